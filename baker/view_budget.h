/* view_budget.h: `baker view`'s peak memory, estimated from which grids a
 * file holds and the box they span, and checked before the grids are read
 * against the memory this machine has available (or --max-memory).
 *
 * Model (docs/memory.md, "baker view's memory"): per voxel of the box, the
 * grids as read (4 bytes per channel), then each phase of the load as
 * baker/view_volume.c runs it: the phase lobes (32 B), the packed medium
 * (16 B; 8 under grey light) and RGB σt (16 B) take the pages of the
 * grids they are made from slab by slab; dispersion's planes of n (8-12 B)
 * come beside `ior_rgb`; the {∇n, n} field and the pyramids last (a few B
 * where n varies in few bricks, up to 23 B per field where it varies
 * everywhere: not counted). The peak is the largest phase; checked against
 * GNU time's peak of real views (tests/budget.sh, case view_honest). */
#ifndef BAKER_VIEW_BUDGET_H
#define BAKER_VIEW_BUDGET_H

#include <stdint.h>

#include "base/common.h"

/* Channels of each grid as the view reads it; 0: the file has none. */
typedef struct view_budget_grids {
  int radiance, ior, extinction, scattering, ior_rgb;
  int flux, phase_g, uncollided, flux_uncollided, camera;
} view_budget_grids_t;

/* Bytes per voxel at the load's peak. */
double view_budget_bytes(const view_budget_grids_t *g);

/* Refuses (BK_ERR_INPUT) a view of path whose grids span n[0] x n[1] x n[2]
 * voxels when its estimated peak exceeds what this process may use: the
 * memory available now plus `held` bytes it holds already (the grids read),
 * or max_bytes when > 0. Names the estimate and the limit. */
int view_budget_check(const char *path, const int n[3], const view_budget_grids_t *g,
                      double held, uint64_t max_bytes, bk_error_t *err);

/* Bytes of the largest buffer a device is asked for, at least, by a view
 * of grids spanning n[0] x n[1] x n[2] voxels: the packed medium, {S, σt}
 * under grey light (8 B per voxel of the padded box) and twice that
 * otherwise; RGB σt, the phase lobes and the {∇n, n} field not counted. */
double view_budget_least_buffer(const int n[3]);

/* Refuses (BK_ERR_INPUT) a view of path whose least buffer exceeds
 * max_alloc, the largest `device` allows, pointing to --device host. */
int view_budget_device_check(const char *path, const int n[3], uint64_t max_alloc,
                             const char *device, bk_error_t *err);

#endif
