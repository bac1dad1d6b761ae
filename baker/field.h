/* field.h: the refractive field the rays read (kernels/ray_core.h), built on
 * the host for the photon march and for the view alike.
 *
 * In: n, one float per voxel (x-fastest), on cubic voxels of size h (m).
 * Out: {∇n (1/voxel), n} per voxel in the ray core's sparse layout (bricks
 * of the padded grid, whose outer layer copies the edge voxels, stored only
 * where n varies: kernels/ray_core.h). ∇n is rc_gradient_at's central difference, taken in 1/m and
 * scaled by h, so that a bake and a view of its file read the same numbers. */
#ifndef BAKER_FIELD_H
#define BAKER_FIELD_H

#include <stddef.h>

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Float4 entries of a padded field of nx x ny x nz voxels (the view's
 * medium fields, fld_pad4). */
size_t fld_padded_count(int nx, int ny, int nz);

/* The {∇n, n} field of `ior` in the ray core's sparse layout
 * (kernels/ray_core.h rc_field_gather; caller frees); NULL and
 * BK_ERR_RUNTIME in err when out of memory. */
float *fld_build(int nx, int ny, int nz, double h, const float *ior, bk_error_t *err);

/* Dispersion: the fields of n_R, n_G, n_B one after the other
 * (rc_field_channel): G's n is ior, R's and B's the planes ior_rb and
 * ior_rb + nx*ny*nz. */
float *fld_build_rgb(int nx, int ny, int nz, double h, const float *ior, const float *ior_rb,
                     bk_error_t *err);

/* Bytes per voxel of one sparse field at most: every brick stored, each
 * with its (RC_BRICK + 1)³ corners (16 B per voxel where n varies; the
 * bundled scenes need under 1). For memory checks made before the field
 * exists. */
#define FLD_WORST_BYTES_PER_VOXEL (16.0 * 729.0 / 512.0)

/* The floats of `fields` sparse fields one after the other at ng. */
size_t fld_floats(int nx, int ny, int nz, const float *ng, int fields);

/* Voxel (i, j, k)'s {∇n, n} as the sparse field ng holds it, read through
 * the sampler; each of i, j, k from -1 (the padding: the edge voxel's
 * value) to its count - 1. */
void fld_voxel(const float *ng, int i, int j, int k, float q[4]);

/* Copies an unpadded float4 field src (nx*ny*nz float4) into the padded
 * layout dst (fld_padded_count float4). */
void fld_pad4(int nx, int ny, int nz, const float *src, float *dst);
/* The outer layer of a padded float4 field whose voxels are filled: each
 * edge voxel's value copied outwards (what fld_pad4 does after the copy). */
void fld_pad4_faces(int nx, int ny, int nz, float *f);
/* The same for w floats per voxel. */
void fld_pad_faces(int nx, int ny, int nz, int w, float *f);

#ifdef __cplusplus
}
#endif
#endif
