/* iorgrad.h: the gradient grid of the refractive index, ∇n, for the march.
 *
 * In: the grid dimensions and n, one float per voxel (x-fastest). Out: ∇n in
 * 1/m, 3 floats per voxel (x y z), by central differences (one-sided on the
 * faces) — kernels/ior.h, the same function on the host and on the device.
 * The photon march reads it with ior_gradient_sample() from that header to
 * integrate d/ds(n dx/ds) = ∇n. */
#ifndef BAKER_IORGRAD_H
#define BAKER_IORGRAD_H

#include "clhost.h"
#include "grid.h"
#include "shared.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The kernel-side description of a grid (kernels/shared.h). */
bk_grid ig_kernel_grid(const grid_dims_t *d);

/* Plain C loop over kernels/ior.h: the reference the device is tested on.
 * grad holds 3 * grid_count(d) floats. */
int ig_compute_host(const grid_dims_t *d, const float *ior, float *grad, bk_error_t *err);

/* Builds kernels/ior.cl (with the binary cache) and runs it: uploads ior,
 * reads grad back (3 * grid_count(d) floats). */
int ig_compute_cl(clh_context_t *cl, const grid_dims_t *d, const float *ior, float *grad,
                  bk_error_t *err);

/* For stages that keep n and ∇n on the device: enqueues the kernel on
 * existing buffers (ior: grid_count floats, grad: 3 * grid_count floats) and
 * waits for it. `program` is kernels/ior.cl built with clh_build, or NULL to
 * build it here. */
int ig_compute_cl_buffers(clh_context_t *cl, cl_program program, const grid_dims_t *d,
                          cl_mem ior, cl_mem grad, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
