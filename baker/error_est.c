/* error_est.c: per-voxel batch statistics and the bake's error terms (see
 * error_est.h). */
#include "error_est.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "base/select.h"

static const double lum_w[3] = {EE_LUM_R, EE_LUM_G, EE_LUM_B};

int ee_tracker_init(ee_tracker_t *t, const pm_setup_t *s, int all, bk_error_t *err) {
  memset(t, 0, sizeof *t);
  t->shift = all ? 0 : 1;
  t->mx = (s->dims.nx + t->shift) >> t->shift;
  t->my = (s->dims.ny + t->shift) >> t->shift;
  t->mz = (s->dims.nz + t->shift) >> t->shift;
  t->count = (size_t)t->mx * t->my * t->mz;
  /* not touched yet: the twins, which come first, keep their own sums */
  t->prev = bk_calloc(t->count, sizeof(float), "error estimate: batch sums", err);
  t->sumsq = bk_calloc(t->count, sizeof(float), "error estimate: batch squares", err);
  if (!t->prev || !t->sumsq) {
    ee_tracker_free(t);
    return BK_ERR_RUNTIME;
  }
  /* one batch's quanta -> luminance; a one-channel march carries the sum of
   * RGB and to_radiance holds its colour */
  for (int c = 0; c < 3; c++) t->lum[c] = lum_w[c] * s->to_radiance[c];
  if (s->channels == 1) t->lum[0] = t->lum[0] + t->lum[1] + t->lum[2], t->lum[1] = t->lum[2] = 0;
  return BK_OK;
}

void ee_tracker_free(ee_tracker_t *t) {
  free(t->prev);
  free(t->sumsq);
  free(t->dsum);
  free(t->dsumsq);
  free(t->twin_tmp);
  memset(t, 0, sizeof *t);
}

size_t ee_lattice_voxel(const grid_dims_t *d, size_t k) {
  int ijk[3];
  ee_lattice_ijk(k, ((size_t)d->nx + 1) / 2, ((size_t)d->ny + 1) / 2, 1, ijk);
  return grid_index(d, ijk[0], ijk[1], ijk[2]);
}

typedef struct gather_ctx {
  const grid_dims_t *d;
  const float *grid;
  int ch;
  float *out;
  size_t mx, my;
} gather_ctx_t;

static void gather_rows(void *arg, size_t lo, size_t hi) {
  const gather_ctx_t *x = arg;
  for (size_t r = lo; r < hi; r++) {
    int ijk[3];
    ee_lattice_ijk(r * x->mx, x->mx, x->my, 1, ijk);
    const float *g = x->grid + (size_t)x->ch * grid_index(x->d, ijk[0], ijk[1], ijk[2]);
    float *o = x->out + r * x->mx;
    for (size_t e = 0; e < x->mx; e++, g += 2 * x->ch)
      o[e] = x->ch == 1 ? g[0]
                        : g[0] * (float)EE_LUM_R + g[1] * (float)EE_LUM_G + g[2] * (float)EE_LUM_B;
  }
}

void ee_lattice_gather(const grid_dims_t *d, const float *grid, int ch, float *out) {
  gather_ctx_t x = {d, grid, ch, out, ((size_t)d->nx + 1) / 2, ((size_t)d->ny + 1) / 2};
  const size_t rows = x.my * (((size_t)d->nz + 1) / 2);
  bk_parallel(rows, BK_GRAIN / x.mx + 1, gather_rows, &x);
}

/* The grid index of the first tracked voxel of tracked row r (rows run
 * along x; the next voxel of a row is 2^shift further). */
static size_t row_start(const ee_tracker_t *t, const pm_setup_t *s, size_t r) {
  int ijk[3];
  ee_lattice_ijk(r * (size_t)t->mx, (size_t)t->mx, (size_t)t->my, t->shift, ijk);
  return grid_index(&s->dims, ijk[0], ijk[1], ijk[2]);
}

static float lum_at(const ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc, size_t v) {
  /* sampling tables add a count/weight counter per voxel */
  const uint64_t *a = acc + (size_t)pm_acc_stride((int)s->params.mode, s->channels) * v;
  if (s->channels == 1) return (float)((double)a[0] * t->lum[0]);
  return (float)((double)a[0] * t->lum[0] + (double)a[1] * t->lum[1] + (double)a[2] * t->lum[2]);
}

/* What a pass over the tracked voxels does with each one's luminance. */
typedef enum { EE_PASS_BATCH, EE_PASS_READ, EE_PASS_TWIN } ee_pass_t;

typedef struct ee_ctx {
  ee_tracker_t *t;
  const pm_setup_t *s;
  const uint64_t *acc;
  const float *fine;
  float *out;
  ee_pass_t pass;
} ee_ctx_t;

static void pass_rows(void *arg, size_t lo, size_t hi) {
  ee_ctx_t *x = arg;
  ee_tracker_t *t = x->t;
  /* a twin's sums hold the tracked lattice alone, packed (pm_deposit_lattice) */
  const int packed = x->s->params.lattice != 0;
  const size_t dv = packed ? 1 : (size_t)1 << t->shift, mx = (size_t)t->mx;
  for (size_t r = lo; r < hi; r++) {
    size_t v = packed ? r * mx : row_start(t, x->s, r);
    for (size_t k = r * mx; k < (r + 1) * mx; k++, v += dv) {
      float cur = lum_at(t, x->s, x->acc, v), d;
      switch (x->pass) {
      case EE_PASS_BATCH: /* this batch's sum: the running sum's growth */
        d = cur - t->prev[k];
        t->sumsq[k] += d * d;
        t->prev[k] = cur;
        break;
      case EE_PASS_READ: x->out[k] = cur; break;
      case EE_PASS_TWIN:
        d = cur - x->fine[k];
        t->dsum[k] += d;
        t->dsumsq[k] += d * d;
        break;
      }
    }
  }
}

static void run_pass(ee_ctx_t *x) {
  size_t rows = (size_t)x->t->my * x->t->mz;
  bk_parallel(rows, BK_GRAIN / (size_t)x->t->mx + 1, pass_rows, x);
}

void ee_after_batch(ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc) {
  ee_ctx_t x = {t, s, acc, NULL, NULL, EE_PASS_BATCH};
  if (!t->touched) { /* their pages, once, before the threads fill them */
    bk_touch_pages(t->prev, t->count * sizeof(float));
    bk_touch_pages(t->sumsq, t->count * sizeof(float));
    t->touched = 1;
  }
  run_pass(&x);
}

typedef struct lum_ctx {
  const ee_tracker_t *t;
  const pm_setup_t *s;
  const uint64_t *acc;
  float sign, *out;
} lum_ctx_t;

static void add_lum_range(void *arg, size_t lo, size_t hi) {
  const lum_ctx_t *x = arg;
  for (size_t v = lo; v < hi; v++) x->out[v] += x->sign * lum_at(x->t, x->s, x->acc, v);
}

void ee_add_lum(const ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc, float sign,
                float *out) {
  lum_ctx_t x = {t, s, acc, sign, out};
  bk_parallel(s->voxels, BK_GRAIN, add_lum_range, &x);
}

void ee_read(const ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc, float *out) {
  ee_ctx_t x = {(ee_tracker_t *)t, s, acc, NULL, out, EE_PASS_READ};
  run_pass(&x);
}

int ee_twin_add(ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc, const float *fine,
                bk_error_t *err) {
  if (!t->dsum) {
    t->dsum = bk_calloc_touched(t->count, sizeof(float), "error estimate: twin sums", err);
    t->dsumsq = bk_calloc_touched(t->count, sizeof(float), "error estimate: twin squares", err);
    if (!t->dsum || !t->dsumsq) return BK_ERR_RUNTIME;
  }
  ee_ctx_t x = {t, s, acc, fine, NULL, EE_PASS_TWIN};
  run_pass(&x);
  t->twins++;
  return BK_OK;
}

/* 2% of the 99.9th percentile of lum (n values); 0 when it cannot be had. */
static double lit_threshold(const float *lum, size_t n) {
  double p = bk_quantile(lum, n, EE_LIT_PERCENTILE);
  return isnan(p) ? 0.0 : EE_LIT_FRACTION * p;
}

/* ee_terms' sums over the lit tracked voxels, in fixed chunks added in
 * order: the same bits on every thread count. */
#define EE_TERM_CHUNKS 16
typedef struct ee_sums {
  double m, var, b2;
  size_t lit;
} ee_sums_t;

typedef struct terms_ctx {
  const ee_tracker_t *t;
  const float *mean;
  double thr, B, T;
  double var_b, inv_t, var_t; /* the divisions, hoisted */
  ee_sums_t part[EE_TERM_CHUNKS];
} terms_ctx_t;

/* The variance of a mean of n is (Σx² − n x̄²) / ((n − 1) n). */
static void terms_chunk(void *arg, size_t c, size_t lo, size_t hi) {
  terms_ctx_t *x = arg;
  const ee_tracker_t *t = x->t;
  ee_sums_t p = {0.0, 0.0, 0.0, 0};
  for (size_t k = lo; k < hi; k++) {
    double m = x->mean[k];
    if (!(x->thr > 0.0) || m < x->thr) continue;
    p.lit++;
    p.m += m;
    if (x->B > 1) p.var += fmax(0.0, t->sumsq[k] - x->B * m * m) * x->var_b;
    if (x->T > 1) {
      double dbar = t->dsum[k] * x->inv_t;
      p.b2 += dbar * dbar - fmax(0.0, t->dsumsq[k] - x->T * dbar * dbar) * x->var_t;
    }
  }
  x->part[c] = p;
}

void ee_terms(const ee_tracker_t *t, int batches, int step_exact, ee_terms_t *out) {
  const double B = batches, T = t->twins;
  out->batches = batches;
  out->twin_batches = step_exact ? 0 : t->twins;
  out->noise = out->step = out->estimate = EE_UNKNOWN;
  out->filter = 0.0;
  if (batches < 2 && (step_exact || T < 2)) { /* no spread and no twins: nothing to sum */
    if (step_exact && batches == 1) out->step = 0.0;
    return;
  }
  float *mean = calloc(t->count ? t->count : 1, sizeof *mean);
  if (!mean || batches < 1) {
    free(mean);
    return;
  }
  for (size_t k = 0; k < t->count; k++) mean[k] = (float)(t->prev[k] / B);
  terms_ctx_t x = {.t = t, .mean = mean, .thr = lit_threshold(mean, t->count), .B = B, .T = T,
                   .var_b = batches > 1 ? 1.0 / ((B - 1.0) * B) : 0.0,
                   .inv_t = T > 1 ? 1.0 / T : 0.0, .var_t = T > 1 ? 1.0 / ((T - 1.0) * T) : 0.0};
  bk_parallel_chunks(t->count, EE_TERM_CHUNKS, terms_chunk, &x);
  double sum_m = 0.0, sum_var = 0.0, sum_b2 = 0.0;
  size_t lit = 0;
  for (int c = 0; c < EE_TERM_CHUNKS; c++)
    sum_m += x.part[c].m, sum_var += x.part[c].var, sum_b2 += x.part[c].b2, lit += x.part[c].lit;
  free(mean);
  if (!lit || !(sum_m > 0.0)) { /* nothing lit: nothing to be wrong about */
    out->noise = batches > 1 ? 0.0 : EE_UNKNOWN;
    out->step = step_exact || T > 1 ? 0.0 : EE_UNKNOWN;
  } else {
    double mm = sum_m / (double)lit;
    if (batches > 1) out->noise = sqrt(sum_var / (double)lit) / mm;
    if (step_exact) out->step = 0.0;
    else if (T > 1) out->step = sqrt(fmax(0.0, sum_b2 / (double)lit)) / mm;
  }
  if (out->noise >= 0.0 && out->step >= 0.0)
    out->estimate = sqrt(out->noise * out->noise + out->step * out->step);
}

float *ee_take_error_grid(ee_tracker_t *t, int batches) {
  if (t->shift != 0 || batches < 2) return NULL;
  const double B = batches;
  float *g = t->sumsq;
  for (size_t k = 0; k < t->count; k++) {
    double m = t->prev[k] / B;
    g[k] = (float)sqrt(fmax(0.0, (g[k] - B * m * m) / (B - 1.0)) / B);
  }
  t->sumsq = NULL;
  return g;
}

double ee_true_error(const float *radiance, const float *truth, size_t voxels) {
  float *lt = calloc(voxels ? voxels : 1, sizeof *lt);
  if (!lt) return NAN;
  for (size_t i = 0; i < voxels; i++)
    lt[i] = (float)(lum_w[0] * truth[3 * i] + lum_w[1] * truth[3 * i + 1] +
                    lum_w[2] * truth[3 * i + 2]);
  double thr = lit_threshold(lt, voxels);
  double se = 0.0, st = 0.0;
  size_t lit = 0;
  for (size_t i = 0; i < voxels; i++) {
    if (!(thr > 0.0) || lt[i] < thr) continue;
    double l = lum_w[0] * radiance[3 * i] + lum_w[1] * radiance[3 * i + 1] +
               lum_w[2] * radiance[3 * i + 2];
    se += (l - lt[i]) * (l - lt[i]);
    st += lt[i];
    lit++;
  }
  free(lt);
  return lit && st > 0.0 ? sqrt(se / (double)lit) / (st / (double)lit) : 0.0;
}

void ee_twin_reset(ee_tracker_t *t) {
  if (t->dsum) memset(t->dsum, 0, t->count * sizeof(float));
  if (t->dsumsq) memset(t->dsumsq, 0, t->count * sizeof(float));
  t->twins = 0;
}

int ee_twin_save(const ee_tracker_t *t, float **keep, bk_error_t *err) {
  if (!t->dsum) return BK_OK; /* nothing recorded */
  if (!*keep && !(*keep = bk_calloc(2 * t->count, sizeof(float), "error estimate: twin copy", err)))
    return BK_ERR_RUNTIME;
  memcpy(*keep, t->dsum, t->count * sizeof(float));
  memcpy(*keep + t->count, t->dsumsq, t->count * sizeof(float));
  return BK_OK;
}

void ee_twin_restore(ee_tracker_t *t, const float *keep, int twins) {
  memcpy(t->dsum, keep, t->count * sizeof(float));
  memcpy(t->dsumsq, keep + t->count, t->count * sizeof(float));
  t->twins = twins;
}

void ee_batches_reset(ee_tracker_t *t) {
  memset(t->prev, 0, t->count * sizeof(float));
  memset(t->sumsq, 0, t->count * sizeof(float));
}

void ee_filter_terms(size_t n, int batches, const float *all, const float *half_a,
                     const float *f, const float *wf, const float *fa, const float *fb,
                     double *noise, double *bias) {
  const double B = batches, na = (batches + 1) / 2, nb = batches / 2;
  /* var(mean of B) / var(difference of the halves' means) */
  const double kappa = (1.0 / B) / (1.0 / na + 1.0 / nb);
  *noise = *bias = EE_UNKNOWN;
  float *mean = calloc(n ? n : 1, sizeof *mean);
  if (!mean || batches < 2) {
    free(mean);
    return;
  }
  for (size_t k = 0; k < n; k++) mean[k] = (float)(all[k] / B);
  double thr = lit_threshold(mean, n), sum_m = 0.0, sum_n = 0.0, sum_b = 0.0;
  size_t lit = 0;
  for (size_t k = 0; k < n; k++) {
    double m = mean[k];
    if (!(thr > 0.0) || m < thr) continue;
    double df = (double)fa[k] - fb[k];
    sum_n += kappa * df * df;
    if (wf) { /* the filter's move on its own output: its bias at second order */
      double b = (double)wf[k] - f[k];
      sum_b += b * b;
    } else { /* filtered minus raw, less its noise */
      double dx = half_a[k] / na - (all[k] - half_a[k]) / nb, d = f[k] - m;
      sum_b += d * d - kappa * (df - dx) * (df - dx);
    }
    sum_m += m;
    lit++;
  }
  free(mean);
  if (!lit || !(sum_m > 0.0)) {
    *noise = *bias = 0.0;
    return;
  }
  double mm = sum_m / (double)lit;
  *noise = sqrt(sum_n / (double)lit) / mm;
  *bias = sqrt(fmax(0.0, sum_b / (double)lit)) / mm;
}

double ee_twin_step(const ee_tracker_t *t, const float *fine) {
  const double T = t->twins;
  float *mean = calloc(t->count ? t->count : 1, sizeof *mean);
  if (!mean || T < 2) {
    free(mean);
    return EE_UNKNOWN;
  }
  for (size_t k = 0; k < t->count; k++) {
    double m = 0.0;
    for (int b = 0; b < t->twins; b++) m += fine[(size_t)b * t->count + k];
    /* lit by the midpoint of the two integrators' twins: a lit set chosen
     * by the truth's twins alone keeps the voxels where they came out high,
     * whose differences d then lean low (the armadillo at 128³ read Euler
     * at 1/4 voxel as unbiased, 0.0000, against 0.13 on the bake's own lit
     * set); the midpoint is independent of d to first order */
    mean[k] = (float)(m / T + 0.5 * t->dsum[k] / T);
  }
  double thr = lit_threshold(mean, t->count), sum_m = 0.0, sum_b2 = 0.0;
  size_t lit = 0;
  for (size_t k = 0; k < t->count; k++) {
    if (!(thr > 0.0) || mean[k] < thr) continue;
    double dbar = t->dsum[k] / T;
    double var_d = fmax(0.0, (t->dsumsq[k] - T * dbar * dbar) / (T - 1.0)) / T;
    sum_b2 += dbar * dbar - var_d;
    sum_m += mean[k];
    lit++;
  }
  free(mean);
  return lit && sum_m > 0.0 ? sqrt(fmax(0.0, sum_b2 / (double)lit)) / (sum_m / (double)lit) : 0.0;
}

void ee_lit_spread(const ee_tracker_t *t, int batches, float *out) {
  const double B = batches;
  for (size_t k = 0; k < t->count; k++) out[k] = (float)(t->prev[k] / B);
  double thr = lit_threshold(out, t->count);
  for (size_t k = 0; k < t->count; k++) {
    double m = t->prev[k] / B;
    out[k] = thr > 0.0 && m >= thr && batches > 1
                 ? (float)fmax(0.0, (t->sumsq[k] - B * m * m) / (B - 1.0))
                 : 0.0f;
  }
}
