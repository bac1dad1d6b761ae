/* adaptive_loop.c: the sampling tables rebuilt after every batch from the
 * error measured so far (issue 12, item 1; see adaptive.h, ad_loop_t).
 *
 * After batch b the tracker knows each lattice voxel's spread s² between
 * batches (error_est.h); over the lit voxels that is where the remaining
 * error is. It is summed per pilot cell (V_c), and each light-domain cell j
 * gets the share of it that its photons can reach, from the pilot's origin
 * masks: I_j = Σ_c [j reached c] V_c / popcount(mask_c). The variance a
 * cell leaves falls as 1/(its photons), so at density p the cell's
 * contribution is I_j measured at the current p_j; the density that
 * minimises the total variance for a given march time is
 *   p_j ∝ sqrt(I_j p_j / cost_j),
 * cost_j the march time of a photon from cell j: its proxy is the work
 * the pilot's photons from cell j did (pm_work: field evaluations and
 * voxel crossings, counted by the march, ad_cell_costs). The floor mixture
 * of ad_pdf_from_weights keeps pdf >= floor, so the weights stay <= 1/floor
 * and every batch stays an unbiased estimate given the tables it was drawn
 * with. */
#define _POSIX_C_SOURCE 200809L
#include "adaptive.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int ad_loop_init(ad_loop_t *L, int lights, int shift, const grid_dims_t *cd,
                 const uint64_t *masks, const uint64_t *work, const int *pilot_of, float *tables,
                 float floor_fraction, bk_error_t *err) {
  memset(L, 0, sizeof *L);
  L->shift = shift, L->cd = *cd, L->cv = grid_count(cd), L->masks = masks, L->work = work;
  L->lights = lights, L->tables = tables, L->floor = floor_fraction;
  memcpy(L->pilot_of, pilot_of, sizeof(int) * (size_t)L->lights);
  L->cellvar = bk_calloc(L->cv, sizeof(double), "adaptive loop: cell variance", err);
  if (!L->cellvar) return BK_ERR_RUNTIME;
  for (int l = 0; l < L->lights; l++)
    for (int c = 0; c < LD_CELLS; c++)
      L->pdf[l][c] = ld_pdf_eval(tables + (size_t)l * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y),
                                 LD_CELLS_X, LD_CELLS_Y, ((c % LD_CELLS_X) + 0.5f) / LD_CELLS_X,
                                 ((c / LD_CELLS_X) + 0.5f) / LD_CELLS_Y);
  return BK_OK;
}

void ad_loop_free(ad_loop_t *L) {
  free(L->cellvar);
  L->cellvar = NULL;
}

/* Light l's new table from the cells' variance (L->cellvar). */
static int retable_light(ad_loop_t *L, int l, bk_error_t *err) {
  const int p = L->pilot_of[l];
  if (p < 0) return BK_OK; /* no origin data: the light keeps its table */
  const uint64_t *m = L->masks + (size_t)p * L->cv;
  double imp[LD_CELLS] = {0}, cost[LD_CELLS], w[LD_CELLS];
  ad_cell_costs(L->work + (size_t)p * PM_CELL_WORK_PER_LIGHT, cost);
  for (size_t c = 0; c < L->cv; c++) {
    if (!m[c]) continue;
    double share = L->cellvar[c] / __builtin_popcountll(m[c]);
    for (int j = 0; j < LD_CELLS; j++)
      if (m[c] >> j & 1u) imp[j] += share;
  }
  for (int j = 0; j < LD_CELLS; j++) w[j] = sqrt(imp[j] * L->pdf[l][j] / cost[j]);
  float *table = L->tables + (size_t)l * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y);
  return ad_pdf_from_weights(w, LD_CELLS_X, LD_CELLS_Y, L->floor, table, L->pdf[l], err);
}

int ad_loop_retable(void *ctx, int done, const ee_tracker_t *t, bk_error_t *err) {
  ad_loop_t *L = ctx;
  if (done < 2) return BK_OK; /* no spread yet */
  float *var = bk_calloc(t->count, sizeof(float), "adaptive loop: voxel spread", err);
  if (!var) return BK_ERR_RUNTIME;
  ee_lit_spread(t, done, var);
  memset(L->cellvar, 0, L->cv * sizeof(double));
  const int s = L->shift; /* lattice index -> voxel -> pilot cell */
  for (size_t k = 0; k < t->count; k++) {
    if (!(var[k] > 0.0f)) continue;
    int v[3];
    ee_lattice_ijk(k, (size_t)t->mx, (size_t)t->my, t->shift, v);
    L->cellvar[grid_index(&L->cd, v[0] >> s, v[1] >> s, v[2] >> s)] += var[k];
  }
  free(var);
  int rc = BK_OK;
  for (int l = 0; l < L->lights && rc == BK_OK; l++) rc = retable_light(L, l, err);
  L->rebuilt++;
  return rc;
}
