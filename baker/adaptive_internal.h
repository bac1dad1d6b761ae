/* adaptive_internal.h: what the files of the adaptive stage share and
 * nobody else needs. */
#ifndef BAKER_ADAPTIVE_INTERNAL_H
#define BAKER_ADAPTIVE_INTERNAL_H

#include "base/grid.h"
#include "march.h"
#include "voxelize.h"

/* Voxel count of a grid, refusing empty grids and overflow of `per_voxel`
 * bytes per voxel; `what` names the caller in the message. (A base-layer
 * grid check when grid.h gets one.) */
int ad_grid_voxels(const grid_dims_t *d, size_t per_voxel, const char *what, size_t *voxels,
                   bk_error_t *err);

/* The pilot's coarse grid (adaptive_pdf.c): cells of 2^shift voxels a side,
 * shift the fewest that bring the longest axis to pilot_cells cells; the
 * grid of those cells over the same corner (the last may stick out); and
 * per cell the pilot's mean radiance over its voxels in the grid (3 floats)
 * and the largest grey scattering coefficient of those voxels. */
int ad_pilot_shift(const grid_dims_t *d, int pilot_cells);
grid_dims_t ad_coarse_dims(const grid_dims_t *d, int shift);
void ad_coarse_fields(const pm_setup_t *p, const uint64_t *acc, const volume_t *vol, int shift,
                      float *rgb, float *scat);

#endif
