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
