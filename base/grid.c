/* grid.c: grid dimensions from scene bounds, and the memory check that runs
 * before any grid is allocated. */
#include "base/grid.h"

#include <math.h>

int grid_dims_from_bounds(const float bmin[3], const float bmax[3], int resolution,
                          const char *where, grid_dims_t *out, bk_error_t *err) {
  float extent[3], longest = 0.0f;
  for (int a = 0; a < 3; a++) {
    if (!isfinite(bmin[a]) || !isfinite(bmax[a]) || !(bmax[a] > bmin[a]))
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: grid.bounds: max must exceed min on every axis, axis %d has [%g, %g]",
                     where, a, bmin[a], bmax[a]);
    extent[a] = bmax[a] - bmin[a];
    if (extent[a] > longest) longest = extent[a];
  }
  /* the upper limit is checked by grid_check_memory, which can say how much
   * memory the grid would have needed */
  if (resolution < 1)
    return bk_fail(err, BK_ERR_INPUT, "%s: grid.resolution: expected a positive voxel count, got %d",
                   where, resolution);
  out->voxel_size = longest / (float)resolution;
  int *n[3] = {&out->nx, &out->ny, &out->nz};
  for (int a = 0; a < 3; a++) {
    int count = (int)lroundf(extent[a] / out->voxel_size);
    if (count < 1) count = 1;
    if (count > resolution) count = resolution;
    *n[a] = count;
    float centre = 0.5f * (bmin[a] + bmax[a]);
    out->origin[a] = centre - 0.5f * (float)count * out->voxel_size;
  }
  return BK_OK;
}

int grid_crop(const grid_dims_t *whole, const float lo[3], const float hi[3], grid_dims_t *out,
              int off[3]) {
  const int n[3] = {whole->nx, whole->ny, whole->nz};
  int a0[3], a1[3], smaller = 0;
  *out = *whole;
  for (int a = 0; a < 3; a++) {
    off[a] = 0;
    /* in double: a box far outside must not wrap the int math */
    double l = floor((double)lo[a]) - GRID_CROP_PAD, h = ceil((double)hi[a]) + GRID_CROP_PAD;
    if (!(h >= 0.0) || !(l <= (double)(n[a] - 1))) return 0;
    a0[a] = l <= 0.0 ? 0 : ((int)l / GRID_CROP_ALIGN) * GRID_CROP_ALIGN;
    a1[a] = h >= (double)(n[a] - 1) ? n[a]
                                     : ((int)h / GRID_CROP_ALIGN + 1) * GRID_CROP_ALIGN;
    if (a1[a] > n[a]) a1[a] = n[a];
    smaller |= a1[a] - a0[a] < n[a];
  }
  if (!smaller) return 0;
  int *dn[3] = {&out->nx, &out->ny, &out->nz};
  for (int a = 0; a < 3; a++) {
    off[a] = a0[a];
    *dn[a] = a1[a] - a0[a];
    out->origin[a] = whole->origin[a] + (float)a0[a] * whole->voxel_size;
  }
  return 1;
}

void grid_voxel_center(const grid_dims_t *d, int i, int j, int k, float out[3]) {
  out[0] = d->origin[0] + ((float)i + 0.5f) * d->voxel_size;
  out[1] = d->origin[1] + ((float)j + 0.5f) * d->voxel_size;
  out[2] = d->origin[2] + ((float)k + 0.5f) * d->voxel_size;
}

int grid_check_memory(const grid_dims_t *d, size_t bytes_per_voxel, const char *where,
                      bk_error_t *err) {
  /* in double: a 100000^3 grid must be reported, not wrapped around */
  double voxels = (double)d->nx * (double)d->ny * (double)d->nz;
  double bytes = voxels * (double)bytes_per_voxel;
  uint64_t physical = bk_physical_memory();
  size_t exact;
  char need[32], have[32];
  if (!bk_mul3_size((size_t)d->nx, (size_t)d->ny, (size_t)d->nz, &exact) ||
      !bk_mul_size(exact, bytes_per_voxel, &exact) || (physical && bytes > (double)physical))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: a %dx%dx%d grid (%.3g voxels) would need %s of memory, more than this "
                   "machine's %s; lower grid.resolution",
                   where, d->nx, d->ny, d->nz, voxels, bk_format_bytes(bytes, need, sizeof need),
                   bk_format_bytes((double)physical, have, sizeof have));
  if (d->nx > GRID_MAX_AXIS || d->ny > GRID_MAX_AXIS || d->nz > GRID_MAX_AXIS)
    return bk_fail(err, BK_ERR_INPUT, "%s: a %dx%dx%d grid exceeds %d voxels per axis (%s)", where,
                   d->nx, d->ny, d->nz, GRID_MAX_AXIS, bk_format_bytes(bytes, need, sizeof need));
  return BK_OK;
}
