/* view_fields.h: what the view kernel reads besides the medium, built on
 * the host from the dense volume (view_volume.h): ∇n with n, the distance to
 * the nearest refraction, the padded layout of 4-float fields and the flags
 * of each 8³ brick (kernels/view.h). */
#ifndef BAKER_VIEW_FIELDS_H
#define BAKER_VIEW_FIELDS_H

#include "common.h"
#include "view_volume.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The refractive field the kernel reads, from n (nx*ny*nz floats, x-fastest):
 * ng holds 4 floats per voxel, ∇n per voxel length (central differences,
 * one-sided on the faces: kernels/ior.h, as the photon march) and n. */
void view_ng_field(int nx, int ny, int nz, const float *ior, float *ng);

/* The layout the kernel reads 4-float fields in: src (nx*ny*nz voxels of 4
 * floats) with one layer of replicated edge voxels around it, into dst of
 * (nx+2)*(ny+2)*(nz+2) voxels. */
void view_pad4(int nx, int ny, int nz, const float *src, float *dst);

/* Where camera rays may walk straight inside refracting bricks: per voxel,
 * the Chebyshev distance in voxels (capped at VIEW_FLAT_MAX) to the nearest
 * voxel whose ∇n (from view_ng_field) is not zero. scratch: nx*ny*nz bytes. */
void view_flat_field(int nx, int ny, int nz, const float *ng, unsigned char *flat,
                     unsigned char *scratch);

/* Per 8³ brick: VIEW_BRICK_N_CONST where n is constant (the curved march
 * walks straight), VIEW_BRICK_MEDIUM_CONST where the medium is; fills
 * v->bricks and v->bx, by, bz. */
int build_bricks(view_volume_t *v, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
