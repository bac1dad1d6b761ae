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
 * cost_j the march time of a photon from cell j. The march does not time
 * photons per cell; its proxy is the pilot cells they reach, each weighed
 * by its integrator work: 1 where n is constant in the cell (straight DDA),
 * evals / step where it varies (every voxel stepped: 4 field evaluations
 * per RK4 step, 1 per Euler step). The floor mixture of ad_pdf_from_weights
 * keeps pdf >= floor, so the weights stay <= 1/floor and every batch stays
 * an unbiased estimate given the tables it was drawn with. */
#define _POSIX_C_SOURCE 200809L
#include "adaptive.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "integrators.h"

/* Per pilot cell: the integrator work of a photon crossing it. */
static void cell_costs(ad_loop_t *L, const volume_t *vol, const pm_setup_t *s) {
  const grid_dims_t *d = &vol->dims;
  const int sh = L->shift;
  const double evals = s->params.integrator == integrator_kind(INTEGRATOR_RK4)->device ? 4.0 : 1.0;
  const double stepped = evals / (s->params.step > 0.0f ? s->params.step : 1.0f);
  float *lo = calloc(L->cv, sizeof(float)), *hi = calloc(L->cv, sizeof(float));
  for (size_t c = 0; c < L->cv; c++) L->cost[c] = 1.0f;
  if (!lo || !hi || !vol->has_refraction) {
    free(lo), free(hi);
    return;
  }
  for (size_t c = 0; c < L->cv; c++) lo[c] = 1e30f, hi[c] = 0.0f;
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        float n = vol->ior[grid_index(d, i, j, k)];
        size_t c = grid_index(&L->cd, i >> sh, j >> sh, k >> sh);
        lo[c] = fminf(lo[c], n), hi[c] = fmaxf(hi[c], n);
      }
  for (size_t c = 0; c < L->cv; c++)
    if (hi[c] > lo[c]) L->cost[c] = (float)stepped;
  free(lo), free(hi);
}

int ad_loop_init(ad_loop_t *L, const volume_t *vol, const pm_setup_t *main_setup, int shift,
                 const grid_dims_t *cd, const uint64_t *masks, const int *pilot_of, float *tables,
                 float floor_fraction, bk_error_t *err) {
  memset(L, 0, sizeof *L);
  L->shift = shift, L->cd = *cd, L->cv = grid_count(cd), L->masks = masks;
  L->lights = main_setup->lights.count, L->tables = tables, L->floor = floor_fraction;
  memcpy(L->pilot_of, pilot_of, sizeof(int) * (size_t)L->lights);
  L->cost = bk_calloc(L->cv, sizeof(float), "adaptive loop: cell costs", err);
  L->cellvar = bk_calloc(L->cv, sizeof(double), "adaptive loop: cell variance", err);
  if (!L->cost || !L->cellvar) {
    ad_loop_free(L);
    return BK_ERR_RUNTIME;
  }
  cell_costs(L, vol, main_setup);
  for (int l = 0; l < L->lights; l++)
    for (int c = 0; c < LD_CELLS; c++)
      L->pdf[l][c] = ld_pdf_eval(tables + (size_t)l * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y),
                                 LD_CELLS_X, LD_CELLS_Y, ((c % LD_CELLS_X) + 0.5f) / LD_CELLS_X,
                                 ((c / LD_CELLS_X) + 0.5f) / LD_CELLS_Y);
  return BK_OK;
}

void ad_loop_free(ad_loop_t *L) {
  free(L->cost);
  free(L->cellvar);
  L->cost = NULL, L->cellvar = NULL;
}

/* Light l's new table from the cells' variance (L->cellvar). */
static int retable_light(ad_loop_t *L, int l, bk_error_t *err) {
  const int p = L->pilot_of[l];
  if (p < 0) return BK_OK; /* no origin data: the light keeps its table */
  const uint64_t *m = L->masks + (size_t)p * L->cv;
  double imp[LD_CELLS] = {0}, cost[LD_CELLS] = {0}, w[LD_CELLS];
  for (size_t c = 0; c < L->cv; c++) {
    if (!m[c]) continue;
    double share = L->cellvar[c] / __builtin_popcountll(m[c]);
    for (int j = 0; j < LD_CELLS; j++)
      if (m[c] >> j & 1u) imp[j] += share, cost[j] += L->cost[c];
  }
  for (int j = 0; j < LD_CELLS; j++)
    w[j] = cost[j] > 0.0 ? sqrt(imp[j] * L->pdf[l][j] / cost[j]) : 0.0;
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
