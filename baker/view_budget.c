/* view_budget.c: `baker view`'s peak memory (see view_budget.h). */
#include "view_budget.h"

#include <math.h>

#include "budget.h"
#include "field.h"

/* the {∇n, n} field where n varies in few bricks, the pyramids and the
 * readers' buffers: above the slopes measured (docs/memory.md) */
#define VIEW_BUDGET_FIELDS 4.0

double view_budget_bytes(const view_budget_grids_t *g) {
  const double rad = 4.0 * g->radiance, ior = 4.0 * g->ior, ext = 4.0 * g->extinction;
  const double sca = 4.0 * g->scattering, rgbn = 4.0 * g->ior_rgb;
  const double lobes_in = 4.0 * (g->flux + g->phase_g + g->uncollided + g->flux_uncollided +
                                 g->camera);
  const int lobes = g->flux && g->phase_g, rgb_sigma = g->extinction == 3 || g->scattering == 3;
  double held = rad + ior + ext + sca + rgbn + lobes_in, peak = held;
  if (g->ior_rgb) { /* n's G plane (when no `ior`) and its R and B planes, then ior_rgb goes */
    held += (g->ior ? 0.0 : 4.0) + 8.0;
    peak = fmax(peak, held);
    held -= rgbn;
  }
  /* each phase's output takes the pages of its inputs slab by slab: the
   * lobes (32 B) those of theirs, the medium (16 B, 8 under grey light)
   * radiance's, σs's and grey σt's, RGB σt (16 B) the 12 of σt as read */
  const double given = rad + sca + (rgb_sigma ? 0.0 : ext);
  const double medium = g->radiance == 1 && !rgb_sigma ? 8.0 : 16.0; /* grey light: {S, σt} */
  const double made[3] = {lobes ? 32.0 : 0.0, medium, rgb_sigma ? 16.0 : 0.0};
  const double used[3] = {lobes_in, given, rgb_sigma ? ext : 0.0};
  for (int p = 0; p < 3; p++) {
    peak = fmax(peak, held + fmax(0.0, made[p] - used[p]));
    held += made[p] - used[p];
  }
  return peak + VIEW_BUDGET_FIELDS * (g->ior_rgb ? 3 : 1);
}

int view_budget_check(const char *path, const int n[3], const view_budget_grids_t *g,
                      double held, uint64_t max_bytes, bk_error_t *err) {
  const double voxels = (double)n[0] * (double)n[1] * (double)n[2];
  const double per_voxel = view_budget_bytes(g), peak = BUDGET_FIXED_BYTES + per_voxel * voxels;
  /* what this process may use in all: the grids already read count in */
  const uint64_t avail = budget_available(0);
  const double limit = max_bytes ? (double)max_bytes : avail ? (double)avail + held : 0.0;
  char need[32], have[32];
  bk_format_bytes(peak, need, sizeof need);
  bk_format_bytes(limit, have, sizeof have);
  bk_log(2, "view: memory: estimated peak %s for %dx%dx%d voxels (%.0f B per voxel), %s available",
         need, n[0], n[1], n[2], per_voxel, have);
  if (!(limit > 0.0) || peak <= limit) return BK_OK;
  return bk_fail(err, BK_ERR_INPUT,
                 "%s: its grids span %dx%dx%d voxels, which the view would need about %s of "
                 "memory for at its peak (%.0f bytes per voxel and the OpenCL runtime); %s %s",
                 path, n[0], n[1], n[2], need, per_voxel,
                 max_bytes ? "--max-memory allows" : "this machine has", have);
}

double view_budget_least_buffer(const int n[3]) {
  return 2.0 * sizeof(float) * (double)fld_padded_count(n[0], n[1], n[2]);
}

int view_budget_device_check(const char *path, const int n[3], uint64_t max_alloc,
                             const char *device, bk_error_t *err) {
  const double bytes = view_budget_least_buffer(n), mib = 1024.0 * 1024.0;
  if (!max_alloc || bytes <= (double)max_alloc) return BK_OK;
  return bk_fail(err, BK_ERR_INPUT,
                 "%s: its grids span %dx%dx%d voxels, whose medium needs at least %.0f MiB in "
                 "one buffer, and OpenCL device %s allows %.0f MiB per buffer; view it with "
                 "--device host",
                 path, n[0], n[1], n[2], bytes / mib, device, (double)max_alloc / mib);
}
