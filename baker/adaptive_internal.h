/* adaptive_internal.h: what the files of the adaptive stage share and
 * nobody else needs. */
#ifndef BAKER_ADAPTIVE_INTERNAL_H
#define BAKER_ADAPTIVE_INTERNAL_H

#include "base/grid.h"

/* Voxel count of a grid, refusing empty grids and overflow of `per_voxel`
 * bytes per voxel; `what` names the caller in the message. (A base-layer
 * grid check when grid.h gets one.) */
int ad_grid_voxels(const grid_dims_t *d, size_t per_voxel, const char *what, size_t *voxels,
                   bk_error_t *err);

#endif
