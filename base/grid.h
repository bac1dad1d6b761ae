/* grid.h: the voxel grid every stage shares.
 *
 * `resolution` voxels span the longest side of the scene bounds; voxels are
 * cubes, so the other sides get round(extent / voxel_size) voxels (at least 1)
 * and the grid is centred on the bounds. Voxel (i,j,k) is the cube whose
 * centre is origin + (i+0.5, j+0.5, k+0.5) * voxel_size: cell-centred, the
 * same convention as OpenVDB's indexToWorld for the transform we write.
 * Dense arrays are x-fastest: index = i + nx*(j + ny*k). */
#ifndef BAKER_GRID_H
#define BAKER_GRID_H

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Largest voxels along one axis. Beyond it the int index math and the
 * OpenCL 32-bit global sizes stop being safe. */
#define GRID_MAX_AXIS 16384

typedef struct grid_dims {
  int nx, ny, nz;
  float voxel_size; /* world units (metres) */
  float origin[3];  /* world position of the corner of voxel (0,0,0) */
} grid_dims_t;

/* Fails with BK_ERR_INPUT when bounds are empty/inverted or resolution is out
 * of range (1..GRID_MAX_AXIS); `where` names the scene key for the message. */
int grid_dims_from_bounds(const float bmin[3], const float bmax[3], int resolution,
                          const char *where, grid_dims_t *out, bk_error_t *err);

static inline size_t grid_count(const grid_dims_t *d) {
  return (size_t)d->nx * (size_t)d->ny * (size_t)d->nz;
}
static inline size_t grid_index(const grid_dims_t *d, int i, int j, int k) {
  return (size_t)i + (size_t)d->nx * ((size_t)j + (size_t)d->ny * (size_t)k);
}
/* Voxels a crop adds around the box it must hold, and the multiple its
 * corner and size are rounded out to (OpenVDB's leaves, the pyramid's 8^3
 * bricks). */
#define GRID_CROP_PAD 2
#define GRID_CROP_ALIGN 8

/* The part of `whole` that holds the index-space box [lo, hi] (voxel centres
 * at integers, as the voxelizer's meshes; any floats), padded by
 * GRID_CROP_PAD, rounded out to GRID_CROP_ALIGN and clipped to `whole`: a
 * grid of its own, same voxel size, its origin on whole's voxel corners
 * (*out; off[3], its first voxel's index in whole). Returns 0, *out = whole,
 * when that is all of it or the box misses it. */
int grid_crop(const grid_dims_t *whole, const float lo[3], const float hi[3], grid_dims_t *out,
              int off[3]);

void grid_voxel_center(const grid_dims_t *d, int i, int j, int k, float out[3]);

/* Refuses (BK_ERR_INPUT) a grid whose `bytes_per_voxel` arrays would exceed
 * the machine's physical memory, or overflow, before anything is allocated;
 * the message says how much memory it would need. */
int grid_check_memory(const grid_dims_t *d, size_t bytes_per_voxel, const char *where,
                      bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
