/* adaptive.c: voxel selection, automatic thresholds and the sampling PDF of
 * the adaptive pipeline (phase 1), and the reconstruction filter on the host
 * and on the OpenCL device. The shared math is kernels/adaptive_filter.h. */
#define _POSIX_C_SOURCE 200809L
#include "adaptive.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>


/* Host filter threads: the CPU cores, at most this many. */
#define AD_MAX_THREADS 64

/* Voxel count of a grid, refusing empty grids and overflow of `per_voxel`
 * bytes per voxel. */
static int grid_size(const grid_dims_t *d, size_t per_voxel, const char *what, size_t *voxels,
                     bk_error_t *err) {
  size_t bytes;
  if (!d || d->nx < 1 || d->ny < 1 || d->nz < 1 || !(d->voxel_size > 0.0f))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: grid %dx%dx%d with voxel size %g: expected at least one voxel along "
                   "each axis and a positive voxel size",
                   what, d ? d->nx : 0, d ? d->ny : 0, d ? d->nz : 0,
                   d ? (double)d->voxel_size : 0.0);
  if (!bk_mul3_size((size_t)d->nx, (size_t)d->ny, (size_t)d->nz, voxels) ||
      !bk_mul_size(*voxels, per_voxel, &bytes))
    return bk_fail(err, BK_ERR_INPUT, "%s: grid %dx%dx%d overflows the address space", what,
                   d->nx, d->ny, d->nz);
  return BK_OK;
}

/* --- pilot fields -------------------------------------------------------------- */

/* Box mean along one axis with half-width s, clipped to the grid: prefix sums
 * per line, so the cost does not grow with s. Separable, so three passes give
 * the mean over the clipped (2s+1)^3 box. */
static void box_axis(const grid_dims_t *d, int axis, int s, const float *in, float *out,
                     double *prefix) {
  int n = axis == 0 ? d->nx : axis == 1 ? d->ny : d->nz;
  size_t stride = axis == 0 ? 1 : axis == 1 ? (size_t)d->nx : (size_t)d->nx * (size_t)d->ny;
  int na = axis == 0 ? d->ny : d->nx, nb = axis == 2 ? d->ny : d->nz;
  for (int b = 0; b < nb; b++)
    for (int a = 0; a < na; a++) {
      size_t base = axis == 0 ? grid_index(d, 0, a, b)
                    : axis == 1 ? grid_index(d, a, 0, b)
                                : grid_index(d, a, b, 0);
      prefix[0] = 0.0;
      for (int i = 0; i < n; i++) prefix[i + 1] = prefix[i] + in[base + (size_t)i * stride];
      for (int i = 0; i < n; i++) {
        int lo = i - s < 0 ? 0 : i - s, hi = i + s + 1 > n ? n : i + s + 1;
        out[base + (size_t)i * stride] = (float)((prefix[hi] - prefix[lo]) / (double)(hi - lo));
      }
    }
}

/* d Y / d(axis) at index c of a line of `count` voxels, per voxel. */
static float diff_axis(const float *y, size_t v, size_t stride, int c, int count) {
  if (count < 2) return 0.0f;
  if (c == 0) return y[v + stride] - y[v];
  if (c == count - 1) return y[v] - y[v - stride];
  return 0.5f * (y[v + stride] - y[v - stride]);
}

int ad_pilot_fields(const grid_dims_t *d, const float *pilot_radiance, int smooth_radius,
                    float *lum, float *grad, bk_error_t *err) {
  size_t voxels;
  float *tmp = NULL;
  double *prefix = NULL;
  int rc = grid_size(d, 3 * sizeof(float), "adaptive pilot", &voxels, err);
  if (rc != BK_OK) return rc;
  if (!pilot_radiance || !lum || !grad)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive pilot: missing pilot radiance or output array");
  if (smooth_radius < 0 || smooth_radius > GRID_MAX_AXIS)
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive pilot: smoothing radius %d: expected 0..%d voxels", smooth_radius,
                   GRID_MAX_AXIS);
  rc = BK_ERR_RUNTIME;
  for (size_t v = 0; v < voxels; v++) {
    const float *c = pilot_radiance + 3 * v;
    if (!isfinite(c[0]) || !isfinite(c[1]) || !isfinite(c[2]) || c[0] < 0.0f || c[1] < 0.0f ||
        c[2] < 0.0f) {
      int i = (int)(v % (size_t)d->nx), j = (int)(v / (size_t)d->nx % (size_t)d->ny),
          k = (int)(v / ((size_t)d->nx * (size_t)d->ny));
      bk_fail(err, BK_ERR_RUNTIME,
              "adaptive pilot: radiance at voxel (%d,%d,%d) is (%g, %g, %g); expected finite "
              "values >= 0 (a march bug or an overflow)",
              i, j, k, (double)c[0], (double)c[1], (double)c[2]);
      goto error;
    }
    lum[v] = ad_luminance(c[0], c[1], c[2]);
  }
  if (smooth_radius > 0) {
    int longest = d->nx > d->ny ? d->nx : d->ny;
    if (d->nz > longest) longest = d->nz;
    tmp = bk_calloc(voxels, sizeof(float), "adaptive pilot smoothing", err);
    prefix = bk_calloc((size_t)longest + 1, sizeof(double), "adaptive pilot smoothing", err);
    if (!tmp || !prefix) goto error;
    box_axis(d, 0, smooth_radius, lum, tmp, prefix);
    box_axis(d, 1, smooth_radius, tmp, grad, prefix); /* grad as scratch */
    box_axis(d, 2, smooth_radius, grad, lum, prefix);
  }
  float inv_h = 1.0f / d->voxel_size;
  size_t sy = (size_t)d->nx, sz = (size_t)d->nx * (size_t)d->ny;
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        size_t v = grid_index(d, i, j, k);
        float gx = diff_axis(lum, v, 1, i, d->nx), gy = diff_axis(lum, v, sy, j, d->ny),
              gz = diff_axis(lum, v, sz, k, d->nz);
        grad[v] = sqrtf(gx * gx + gy * gy + gz * gz) * inv_h;
      }
  rc = BK_OK;
error:
  free(tmp);
  free(prefix);
  return rc;
}

/* --- automatic thresholds ----------------------------------------------------- */

/* The k-th smallest of a[0..n) (n > 0), reordering a: Hoare quickselect with
 * a median-of-three pivot, O(n) on average. */
static float select_kth(float *a, size_t n, size_t k) {
  ptrdiff_t lo = 0, hi = (ptrdiff_t)n - 1, kk = (ptrdiff_t)k;
  while (lo < hi) {
    float x = a[lo], y = a[lo + (hi - lo) / 2], z = a[hi];
    float pivot = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
    ptrdiff_t i = lo, j = hi;
    while (i <= j) {
      while (a[i] < pivot) i++;
      while (a[j] > pivot) j--;
      if (i <= j) {
        float t = a[i];
        a[i] = a[j];
        a[j] = t;
        i++;
        j--;
      }
    }
    if (kk <= j) hi = j;
    else if (kk >= i) lo = i;
    else return a[kk];
  }
  return a[kk];
}

/* Value at quantile q of a[0..n) (the lower nearest rank), reordering a. */
static float quantile(float *a, size_t n, float q) {
  return select_kth(a, n, (size_t)floor((double)q * (double)(n - 1)));
}

/* Why these rules. The pilot is a few thousand photon tracks, so its
 * gradients are mostly noise and the scene's scale is unknown; both rules are
 * relative to the pilot itself and scale with the light's power.
 * Gradient: an edge is an outlier of |∇Y|. For pure noise |∇Y| follows a
 * Maxwell-like law (three roughly Gaussian differences), for which 4 medians
 * is beyond the 99.999th percentile, so 4 medians keeps noise and smooth
 * falloff out: a pilot without edges selects next to nothing (measured: 3 of
 * 110592 voxels of a flat fog with 10% noise) and the PDF stays near uniform,
 * while a step several times the noise is far above it (99.8% of the edge
 * voxels found at 100% noise per voxel, a scratch run of tests/test_adaptive.c).
 * The 90th percentile bounds the other side: when edges are everywhere, only
 * the strongest tenth steer the PDF, keeping it concentrated.
 * Luminance: a shadow is a decade darker than the typical lit voxel (0.1 of
 * the median of reached voxels); unreached voxels (Y = 0) are selected too but
 * carry no origin data, so they do not move the PDF. */
static int thresholds_from_fields(const grid_dims_t *d, const float *pilot_radiance,
                                  const float *scattering, const float *lum, const float *grad,
                                  float *grad_thr, float *lum_thr, ad_select_stats_t *stats,
                                  bk_error_t *err) {
  size_t voxels = grid_count(d), n = 0, considered = 0;
  float *vals = bk_calloc(voxels, sizeof(float), "adaptive thresholds", err);
  if (!vals) return BK_ERR_RUNTIME;
  for (size_t v = 0; v < voxels; v++) {
    if (scattering && !(scattering[v] > 0.0f)) continue;
    considered++;
    const float *c = pilot_radiance + 3 * v;
    if (ad_luminance(c[0], c[1], c[2]) > 0.0f) vals[n++] = lum[v];
  }
  float med_lum = 0.0f, med_grad = 0.0f, g = 0.0f, l = 0.0f;
  if (n > 0) {
    med_lum = quantile(vals, n, 0.5f);
    n = 0;
    for (size_t v = 0; v < voxels; v++) {
      if (scattering && !(scattering[v] > 0.0f)) continue;
      const float *c = pilot_radiance + 3 * v;
      if (ad_luminance(c[0], c[1], c[2]) > 0.0f) vals[n++] = grad[v];
    }
    med_grad = quantile(vals, n, 0.5f);
    float p = quantile(vals, n, AD_AUTO_GRADIENT_PERCENTILE);
    g = fmaxf(p, AD_AUTO_GRADIENT_OUTLIER * med_grad);
    l = AD_AUTO_SHADOW_FRACTION * med_lum;
  }
  free(vals);
  *grad_thr = g;
  *lum_thr = l;
  if (stats) {
    stats->median_luminance = med_lum;
    stats->median_gradient = med_grad;
    stats->considered = considered;
    stats->reached = n;
  }
  return BK_OK;
}

int ad_auto_thresholds(const grid_dims_t *d, const float *pilot_radiance, const float *scattering,
                       int smooth_radius, float *grad_thr, float *lum_thr,
                       ad_select_stats_t *stats, bk_error_t *err) {
  size_t voxels;
  float *lum = NULL, *grad = NULL;
  int rc = grid_size(d, 3 * sizeof(float), "adaptive thresholds", &voxels, err);
  if (rc != BK_OK) return rc;
  rc = BK_ERR_RUNTIME;
  lum = bk_calloc(voxels, sizeof(float), "adaptive pilot luminance", err);
  grad = bk_calloc(voxels, sizeof(float), "adaptive pilot gradient", err);
  if (!lum || !grad) goto error;
  rc = ad_pilot_fields(d, pilot_radiance, smooth_radius, lum, grad, err);
  if (rc != BK_OK) goto error;
  rc = thresholds_from_fields(d, pilot_radiance, scattering, lum, grad, grad_thr, lum_thr, stats,
                              err);
  if (rc == BK_OK && stats) {
    stats->gradient_threshold = *grad_thr;
    stats->luminance_threshold = *lum_thr;
  }
error:
  free(lum);
  free(grad);
  return rc;
}

/* --- selection ---------------------------------------------------------------- */

int ad_select_voxels(const grid_dims_t *d, const float *pilot_radiance, const float *scattering,
                     const ad_select_opts_t *opt, uint8_t *selected, ad_select_stats_t *stats,
                     bk_error_t *err) {
  size_t voxels;
  float *lum = NULL, *grad = NULL;
  ad_select_stats_t st;
  memset(&st, 0, sizeof st);
  int rc = grid_size(d, 3 * sizeof(float), "adaptive selection", &voxels, err);
  if (rc != BK_OK) return rc;
  if (!opt || !selected)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive selection: missing options or output array");
  if (isnan(opt->gradient_threshold) || isinf(opt->gradient_threshold))
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive.gradient_threshold: expected \"auto\" or a number >= 0, got %g",
                   (double)opt->gradient_threshold);
  if (isnan(opt->luminance_threshold) || isinf(opt->luminance_threshold))
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive.luminance_threshold: expected \"auto\" or a number >= 0, got %g",
                   (double)opt->luminance_threshold);
  rc = BK_ERR_RUNTIME;
  lum = bk_calloc(voxels, sizeof(float), "adaptive pilot luminance", err);
  grad = bk_calloc(voxels, sizeof(float), "adaptive pilot gradient", err);
  if (!lum || !grad) goto error;
  rc = ad_pilot_fields(d, pilot_radiance, opt->smooth_radius, lum, grad, err);
  if (rc != BK_OK) goto error;
  float g_auto, l_auto;
  rc = thresholds_from_fields(d, pilot_radiance, scattering, lum, grad, &g_auto, &l_auto, &st,
                              err);
  if (rc != BK_OK) goto error;
  st.gradient_threshold = opt->gradient_threshold < 0.0f ? g_auto : opt->gradient_threshold;
  st.luminance_threshold = opt->luminance_threshold < 0.0f ? l_auto : opt->luminance_threshold;
  for (size_t v = 0; v < voxels; v++) {
    uint8_t s = 0;
    if (!scattering || scattering[v] > 0.0f) {
      if (grad[v] > st.gradient_threshold) s |= AD_SEL_GRADIENT;
      if (lum[v] < st.luminance_threshold) s |= AD_SEL_SHADOW;
    }
    selected[v] = s;
    st.by_gradient += (s & AD_SEL_GRADIENT) != 0;
    st.by_shadow += (s & AD_SEL_SHADOW) != 0;
    st.selected += s != 0;
  }
  bk_log(2,
         "adaptive selection: %zu of %zu voxels (%zu by gradient > %g /m, %zu by luminance < %g; "
         "%zu reached by the pilot, median luminance %g, median gradient %g /m)",
         st.selected, st.considered, st.by_gradient, (double)st.gradient_threshold, st.by_shadow,
         (double)st.luminance_threshold, st.reached, (double)st.median_luminance,
         (double)st.median_gradient);
  if (stats) *stats = st;
  rc = BK_OK;
error:
  free(lum);
  free(grad);
  return rc;
}

/* --- the sampling PDF --------------------------------------------------------- */

int ad_pdf_from_weights(const double *weights, int nx, int ny, float floor_fraction,
                        float *table, float *cell_pdf, bk_error_t *err) {
  if (nx < 1 || ny < 1 || nx > 4096 || ny > 4096)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive pdf: %dx%d cells: expected 1..4096 per axis",
                   nx, ny);
  if (!(floor_fraction > 0.0f && floor_fraction <= 1.0f))
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive pdf: floor fraction %g: expected a number in (0, 1]",
                   (double)floor_fraction);
  if (!weights || !table)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive pdf: missing weights or table");
  int cells = nx * ny;
  double total = 0.0;
  for (int c = 0; c < cells; c++) {
    if (!(weights[c] >= 0.0) || isinf(weights[c]))
      return bk_fail(err, BK_ERR_RUNTIME,
                     "adaptive pdf: cell %d has weight %g; expected a finite number >= 0", c,
                     weights[c]);
    total += weights[c];
  }
  /* Probabilities p(c) = floor / cells + (1 - floor) w(c) / total, summed in
   * double so the CDFs are monotone and end at 1 before the cast. */
  double f = total > 0.0 ? (double)floor_fraction : 1.0;
  float *marg = table;
  double acc = 0.0;
  marg[0] = 0.0f;
  for (int r = 0; r < ny; r++) {
    double row = 0.0;
    for (int c = 0; c < nx; c++)
      row += f / cells + (total > 0.0 ? (1.0 - f) * weights[c + nx * r] / total : 0.0);
    float *cond = table + (ny + 1) + r * (nx + 1);
    double in_row = 0.0;
    cond[0] = 0.0f;
    for (int c = 0; c < nx; c++) {
      double p = f / cells + (total > 0.0 ? (1.0 - f) * weights[c + nx * r] / total : 0.0);
      in_row += p;
      cond[c + 1] = (float)(in_row / row);
    }
    cond[nx] = 1.0f;
    acc += row;
    marg[r + 1] = (float)acc;
  }
  marg[ny] = 1.0f;
  if (cell_pdf)
    for (int r = 0; r < ny; r++)
      for (int c = 0; c < nx; c++)
        cell_pdf[c + nx * r] =
            ld_pdf_eval(table, nx, ny, ((float)c + 0.5f) / (float)nx, ((float)r + 0.5f) / (float)ny);
  return BK_OK;
}

int ad_build_pdf(const uint64_t *origin_masks, const uint8_t *selected, size_t voxels,
                 float floor_fraction, ad_pdf_t *pdf, bk_error_t *err) {
  return ad_build_pdf_weighted(origin_masks, selected, NULL, voxels, floor_fraction, pdf, err);
}

int ad_build_pdf_weighted(const uint64_t *origin_masks, const uint8_t *selected,
                          const float *voxel_weight, size_t voxels, float floor_fraction,
                          ad_pdf_t *pdf, bk_error_t *err) {
  if (!pdf) return bk_fail(err, BK_ERR_RUNTIME, "adaptive pdf: missing output");
  memset(pdf, 0, sizeof *pdf);
  if (voxels > 0 && (!origin_masks || !selected))
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive pdf: missing origin masks or selection");
  pdf->nx = LD_CELLS_X;
  pdf->ny = LD_CELLS_Y;
  pdf->floor_fraction = floor_fraction;
  for (size_t v = 0; v < voxels; v++) {
    uint64_t m = origin_masks[v];
    if (!selected[v] || !m) continue;
    double share = (voxel_weight ? (double)voxel_weight[v] : 1.0) / (double)__builtin_popcountll(m);
    while (m) {
      pdf->importance[__builtin_ctzll(m)] += share;
      m &= m - 1;
    }
    pdf->selected_reached++;
  }
  return ad_pdf_from_weights(pdf->importance, LD_CELLS_X, LD_CELLS_Y, floor_fraction, pdf->table,
                             pdf->cell_pdf, err);
}

/* --- the reconstruction filter ------------------------------------------------ */

/* The 1D Gaussian weights (kernels/adaptive_filter.h): row q (level), column |d|. */
#define AD_WEIGHT_COUNT (AD_WROW * AD_WROW)
static void filter_weights(float *w) {
  for (int i = 0; i < AD_WEIGHT_COUNT; i++) w[i] = 0.0f;
  for (int q = 1; q <= AD_FILTER_MAX_LEVEL; q++) {
    double sigma = (double)AD_FILTER_SIGMA * q;
    for (int d = 0; d <= q; d++) w[q * AD_WROW + d] = (float)exp(-(double)(d * d) / (2.0 * sigma * sigma));
  }
}

/* The checks both filter entry points make: the grid, the channel count,
 * alpha, and levels in min_levels..AD_FILTER_MAX_LEVEL (half voxels). */
static int check_filter_params(const grid_dims_t *d, int channels, float alpha, int levels,
                               int min_levels, size_t *voxels, bk_error_t *err) {
  int rc = grid_size(d, 3 * sizeof(float), "adaptive filter", voxels, err);
  if (rc != BK_OK) return rc;
  if (channels != 1 && channels != 3)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive filter: %d channels: expected 1 or 3", channels);
  if (!(alpha >= 0.0f) || isinf(alpha))
    return bk_fail(err, BK_ERR_INPUT, "adaptive.alpha: expected a finite number >= 0, got %g",
                   (double)alpha);
  if (levels < min_levels || levels > AD_FILTER_MAX_LEVEL)
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive filter: largest radius %g voxels: expected %g..%g in half voxels",
                   0.5 * levels, 0.5 * min_levels, 0.5 * AD_FILTER_MAX_LEVEL);
  return BK_OK;
}

static int check_filter_args(const grid_dims_t *d, int channels, const float *radiance,
                             const float *count, const float *mean_weight, float alpha,
                             int levels, const float *out_radiance, size_t *voxels,
                             bk_error_t *err) {
  int rc = check_filter_params(d, channels, alpha, levels, 0, voxels, err);
  if (rc != BK_OK) return rc;
  if (!radiance || !count || !mean_weight || !out_radiance)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive filter: missing input or output array");
  if (out_radiance == radiance)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "adaptive filter: the output must not alias the input radiance");
  size_t bytes;
  if (!bk_mul3_size(*voxels, (size_t)channels * (levels > 0 ? (size_t)levels : 1),
                    sizeof(float), &bytes))
    return bk_fail(err, BK_ERR_INPUT, "adaptive filter: grid %dx%dx%d overflows the address space",
                   d->nx, d->ny, d->nz);
  return BK_OK;
}

/* The host filter: a pass over z slices first, first + step, ... with its
 * own scratch (AD_SLICE_SCRATCH). */
typedef struct filter_job {
  int pass; /* 0: means into M, 1: differences and the choice */
  const float *f, *count, *mean_weight, *weights;
  float *M, *scratch;
  bk_grid g;
  int C, Q;
  float alpha, noise_k;
  float *out, *radius;
  int first, step;
} filter_job_t;

static void *filter_slices(void *arg) {
  const filter_job_t *job = arg;
  for (int k = job->first; k < job->g.nz; k += job->step) {
    const bk_long dq = (bk_long)job->g.nx * job->g.ny * job->g.nz * job->C * job->Q;
    if (job->pass == 0)
      ad_means_slice(job->f, job->weights, job->scratch, job->M, job->M + dq, job->g, k, job->Q,
                     job->C);
    else
      ad_select_slice(job->f, job->M, job->M + dq, job->count, job->mean_weight, job->scratch,
                      job->g, k, job->alpha, job->noise_k, job->Q, job->C, job->out, job->radius);
  }
  return NULL;
}

int ad_filter_host(const grid_dims_t *d, int channels, const float *radiance, const float *count,
                   const float *mean_weight, float alpha, float noise_k, int levels,
                   float *out_radiance, float *out_radius, bk_error_t *err) {
  size_t voxels;
  float weights[AD_WEIGHT_COUNT];
  filter_job_t jobs[AD_MAX_THREADS];
  pthread_t tid[AD_MAX_THREADS];
  float *scratch = NULL, *M = NULL;
  int rc = check_filter_args(d, channels, radiance, count, mean_weight, alpha, levels,
                             out_radiance, &voxels, err);
  if (rc != BK_OK) return rc;
  if (levels == 0 || alpha == 0.0f) { /* nothing to filter */
    memcpy(out_radiance, radiance, voxels * channels * sizeof(float));
    if (out_radius) memset(out_radius, 0, voxels * sizeof(float));
    return BK_OK;
  }
  filter_weights(weights);
  long cpus = sysconf(_SC_NPROCESSORS_ONLN);
  int threads = cpus < 1 ? 1 : cpus > AD_MAX_THREADS ? AD_MAX_THREADS : (int)cpus;
  if (threads > d->nz) threads = d->nz;
  const size_t per = (size_t)AD_SLICE_SCRATCH(d->nx, d->ny, channels, levels);
  scratch = bk_calloc((size_t)threads, per * sizeof(float), "filter scratch", err);
  M = bk_calloc(voxels, (size_t)AD_MEANS_FLOATS(channels, levels) * sizeof(float), "filter means",
                err);
  if (!scratch || !M) {
    rc = BK_ERR_RUNTIME;
    goto error;
  }
  for (int pass = 0; pass < 2; pass++) {
    for (int t = 0; t < threads; t++) {
      filter_job_t *job = &jobs[t];
      job->pass = pass;
      job->f = radiance;
      job->count = count;
      job->mean_weight = mean_weight;
      job->weights = weights;
      job->M = M;
      job->scratch = scratch + (size_t)t * per;
      job->g = pm_kernel_grid(d);
      job->C = channels;
      job->Q = levels;
      job->alpha = alpha;
      job->noise_k = noise_k;
      job->out = out_radiance;
      job->radius = out_radius;
      job->first = t;
      job->step = threads;
    }
    /* thread 0 is this one; a thread that cannot start leaves its slices to
     * the caller's thread, so the result never depends on the thread count */
    int started = 0;
    for (int t = 1; t < threads; t++) {
      if (pthread_create(&tid[t], NULL, filter_slices, &jobs[t]) != 0) break;
      started = t;
    }
    filter_slices(&jobs[0]);
    for (int t = 1; t <= started; t++) pthread_join(tid[t], NULL);
    for (int t = started + 1; t < threads; t++) filter_slices(&jobs[t]);
  }
  rc = BK_OK;
error:
  free(scratch);
  free(M);
  return rc;
}

int ad_filter_cl_buffers(clh_context_t *cl, cl_program program, const grid_dims_t *d,
                         int channels, cl_mem rgb, cl_mem count, cl_mem mean_weight, float alpha,
                         float noise_k, int levels, cl_mem out_rgb, cl_mem out_radius,
                         bk_error_t *err) {
  cl_program own = NULL;
  cl_kernel km = NULL, ks = NULL;
  cl_mem w_buf = NULL, s_buf = NULL, m_buf = NULL;
  cl_int cerr = CL_SUCCESS;
  float weights[AD_WEIGHT_COUNT];
  char opts[64], b1[32], b2[32];
  size_t voxels;
  int rc = check_filter_params(d, channels, alpha, levels, 1, &voxels, err);
  if (rc != BK_OK) return rc;
  rc = BK_ERR_RUNTIME;
  /* work-items, each with a slice of scratch: a few per core on a CPU, one
   * per slice elsewhere */
  size_t items = cl->is_cpu ? (size_t)4 * (cl->compute_units ? cl->compute_units : 1) : (size_t)d->nz;
  if (items > (size_t)d->nz) items = (size_t)d->nz;
  const size_t scratch_bytes =
      (size_t)AD_SLICE_SCRATCH(d->nx, d->ny, channels, levels) * items * sizeof(float);
  const size_t m_bytes = voxels * (size_t)AD_MEANS_FLOATS(channels, levels) * sizeof(float);
  if ((cl_ulong)m_bytes > cl->max_alloc || (cl_ulong)scratch_bytes > cl->max_alloc) {
    bk_fail(err, BK_ERR_RUNTIME,
            "adaptive filter: the %dx%dx%d grid needs %s in one buffer for radii up to %g "
            "voxels; %s allows %s (lower the resolution)",
            d->nx, d->ny, d->nz,
            bk_format_bytes((double)(m_bytes > scratch_bytes ? m_bytes : scratch_bytes), b1,
                            sizeof b1),
            0.5 * levels, cl->device_name, bk_format_bytes((double)cl->max_alloc, b2, sizeof b2));
    goto error;
  }
  if (!program) {
    snprintf(opts, sizeof opts, "-DAD_CH=%d -DAD_QMAX=%d", channels, levels);
    if (clh_build(cl, "filter.cl", opts, &own, err) != BK_OK) goto error;
    program = own;
  }
  filter_weights(weights);
  w_buf = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof weights,
                         weights, &cerr);
  CLH_CHECK(cerr, err, error);
  s_buf = clCreateBuffer(cl->context, CL_MEM_READ_WRITE, scratch_bytes, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  m_buf = clCreateBuffer(cl->context, CL_MEM_READ_WRITE, m_bytes, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  km = clCreateKernel(program, "ad_means", &cerr);
  CLH_CHECK(cerr, err, error);
  ks = clCreateKernel(program, "ad_select", &cerr);
  CLH_CHECK(cerr, err, error);
  bk_grid g = pm_kernel_grid(d);
  cl_int want = out_radius != NULL;
  CLH_CHECK(clSetKernelArg(km, 0, sizeof(cl_mem), &rgb), err, error);
  CLH_CHECK(clSetKernelArg(km, 1, sizeof(cl_mem), &w_buf), err, error);
  CLH_CHECK(clSetKernelArg(km, 2, sizeof(cl_mem), &s_buf), err, error);
  CLH_CHECK(clSetKernelArg(km, 3, sizeof(cl_mem), &m_buf), err, error);
  CLH_CHECK(clSetKernelArg(km, 4, sizeof(bk_grid), &g), err, error);
  cl_mem sargs[5] = {rgb, m_buf, count, mean_weight, s_buf};
  for (cl_uint a = 0; a < 5; a++)
    CLH_CHECK(clSetKernelArg(ks, a, sizeof(cl_mem), &sargs[a]), err, error);
  CLH_CHECK(clSetKernelArg(ks, 5, sizeof(bk_grid), &g), err, error);
  CLH_CHECK(clSetKernelArg(ks, 6, sizeof(float), &alpha), err, error);
  CLH_CHECK(clSetKernelArg(ks, 7, sizeof(float), &noise_k), err, error);
  CLH_CHECK(clSetKernelArg(ks, 8, sizeof(cl_int), &want), err, error);
  CLH_CHECK(clSetKernelArg(ks, 9, sizeof(cl_mem), &out_rgb), err, error);
  /* a NULL buffer is a NULL pointer in the kernel, which want = 0 never touches */
  CLH_CHECK(clSetKernelArg(ks, 10, sizeof(cl_mem), &out_radius), err, error);
  /* work-groups of one: the work-items spread over the compute units */
  size_t local = 1;
  CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, km, 1, NULL, &items, &local, 0, NULL, NULL), err,
            error);
  CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, ks, 1, NULL, &items, &local, 0, NULL, NULL), err,
            error);
  CLH_CHECK(clFinish(cl->queue), err, error);
  rc = BK_OK;
error:
  if (km) clReleaseKernel(km);
  if (ks) clReleaseKernel(ks);
  if (w_buf) clReleaseMemObject(w_buf);
  if (s_buf) clReleaseMemObject(s_buf);
  if (m_buf) clReleaseMemObject(m_buf);
  if (own) clReleaseProgram(own);
  return rc;
}

int ad_filter_cl(clh_context_t *cl, const grid_dims_t *d, int channels, const float *radiance,
                 const float *count, const float *mean_weight, float alpha, float noise_k,
                 int levels, float *out_radiance, float *out_radius, bk_error_t *err) {
  cl_mem rgb = NULL, cnt = NULL, wm = NULL, out = NULL, rad = NULL;
  cl_int cerr = CL_SUCCESS;
  size_t voxels;
  int rc = check_filter_args(d, channels, radiance, count, mean_weight, alpha, levels,
                             out_radiance, &voxels, err);
  if (rc != BK_OK) return rc;
  if (levels == 0 || alpha == 0.0f) /* nothing to filter: the host copies */
    return ad_filter_host(d, channels, radiance, count, mean_weight, alpha, noise_k, levels,
                          out_radiance, out_radius, err);
  rc = BK_ERR_RUNTIME;
  size_t rgb_bytes = voxels * channels * sizeof(float), one_bytes = voxels * sizeof(float);
  /* a CPU device works in place on the host arrays; a GPU copies */
  const cl_mem_flags in = CL_MEM_READ_ONLY | (cl->is_cpu ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR);
  const cl_mem_flags outf = CL_MEM_WRITE_ONLY | (cl->is_cpu ? CL_MEM_USE_HOST_PTR : 0);
  rgb = clCreateBuffer(cl->context, in, rgb_bytes, (void *)radiance, &cerr);
  CLH_CHECK(cerr, err, error);
  cnt = clCreateBuffer(cl->context, in, one_bytes, (void *)count, &cerr);
  CLH_CHECK(cerr, err, error);
  wm = clCreateBuffer(cl->context, in, one_bytes, (void *)mean_weight, &cerr);
  CLH_CHECK(cerr, err, error);
  out = clCreateBuffer(cl->context, outf, rgb_bytes, cl->is_cpu ? out_radiance : NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  if (out_radius) {
    rad = clCreateBuffer(cl->context, outf, one_bytes, cl->is_cpu ? out_radius : NULL, &cerr);
    CLH_CHECK(cerr, err, error);
  }
  if (ad_filter_cl_buffers(cl, NULL, d, channels, rgb, cnt, wm, alpha, noise_k, levels, out, rad,
                           err) != BK_OK)
    goto error;
  if (cl->is_cpu) {
    /* make the host arrays current (no copy on PoCL) */
    cl_mem both[2] = {out, rad};
    size_t sizes[2] = {rgb_bytes, one_bytes};
    for (int b = 0; b < 2; b++) {
      if (!both[b]) continue;
      void *p = clEnqueueMapBuffer(cl->queue, both[b], CL_TRUE, CL_MAP_READ, 0, sizes[b], 0, NULL,
                                   NULL, &cerr);
      CLH_CHECK(cerr, err, error);
      CLH_CHECK(clEnqueueUnmapMemObject(cl->queue, both[b], p, 0, NULL, NULL), err, error);
    }
    CLH_CHECK(clFinish(cl->queue), err, error);
  } else {
    CLH_CHECK(clEnqueueReadBuffer(cl->queue, out, CL_TRUE, 0, rgb_bytes, out_radiance, 0, NULL,
                                  NULL), err, error);
    if (out_radius)
      CLH_CHECK(clEnqueueReadBuffer(cl->queue, rad, CL_TRUE, 0, one_bytes, out_radius, 0, NULL,
                                    NULL), err, error);
  }
  rc = BK_OK;
error:
  if (rgb) clReleaseMemObject(rgb);
  if (cnt) clReleaseMemObject(cnt);
  if (wm) clReleaseMemObject(wm);
  if (out) clReleaseMemObject(out);
  if (rad) clReleaseMemObject(rad);
  return rc;
}

/* --- the adaptive bake ----------------------------------------------------------- */

void ad_bake_defaults(ad_bake_opts_t *o) {
  memset(o, 0, sizeof *o);
  o->filter = 1;
  o->max_radius = AD_DEFAULT_MAX_RADIUS;
  o->smooth_radius = AD_DEFAULT_SMOOTH_RADIUS;
  o->floor_fraction = AD_DEFAULT_FLOOR;
  o->pilot_cells = AD_PILOT_CELLS;
  o->noise_k = AD_DEFAULT_NOISE_K;
  o->importance = AD_IMPORTANCE_GRADIENT;
}

int ad_pilot_shift(const grid_dims_t *d, int pilot_cells) {
  int longest = d->nx > d->ny ? d->nx : d->ny;
  if (d->nz > longest) longest = d->nz;
  int s = 0;
  while (s < 10 && pilot_cells > 0 && (longest >> s) > pilot_cells) s++;
  return s;
}

/* The pilot's coarse grid: cells of 2^shift voxels a side over the same
 * corner (the last ones may stick out of the grid). */
static grid_dims_t coarse_dims(const grid_dims_t *d, int shift) {
  grid_dims_t c = *d;
  int m = (1 << shift) - 1;
  c.nx = (d->nx + m) >> shift;
  c.ny = (d->ny + m) >> shift;
  c.nz = (d->nz + m) >> shift;
  c.voxel_size = d->voxel_size * (float)(1 << shift);
  return c;
}

/* The largest grey scattering coefficient of the voxels of each coarse
 * cell, layers [lo, hi) of cells along z (one range per core: the layers
 * own disjoint cells). */
typedef struct scat_job {
  const volume_t *vol;
  int shift;
  float *scat;
} scat_job_t;

static void coarse_scattering_range(void *arg, size_t lo, size_t hi) {
  const scat_job_t *j = arg;
  const grid_dims_t *d = &j->vol->dims;
  const int shift = j->shift;
  grid_dims_t c = coarse_dims(d, shift);
  for (size_t v = grid_index(&c, 0, 0, (int)lo); v < grid_index(&c, 0, 0, (int)hi); v++)
    j->scat[v] = 0.0f;
  int k1 = (int)hi << shift;
  if (k1 > d->nz) k1 = d->nz;
  for (int k = (int)lo << shift; k < k1; k++)
    for (int jy = 0; jy < d->ny; jy++) {
      size_t row = grid_index(d, 0, jy, k);
      float *crow = j->scat + grid_index(&c, 0, jy >> shift, k >> shift);
      const float *s = j->vol->sigma_s + 3 * row;
      for (int i = 0; i < d->nx; i++) {
        float g = (s[3 * i] + s[3 * i + 1] + s[3 * i + 2]) * (1.0f / 3.0f);
        float *o = &crow[i >> shift];
        if (g > *o) *o = g;
      }
    }
}

/* Per coarse cell: the pilot's mean radiance over its voxels in the grid
 * (3 floats) and the largest grey scattering coefficient of those voxels. */
static void coarse_fields(const pm_setup_t *p, const uint64_t *acc, const volume_t *vol, int shift,
                          float *rgb, float *scat) {
  const grid_dims_t *d = &vol->dims;
  grid_dims_t c = coarse_dims(d, shift);
  const int ch = p->channels;
  scat_job_t job = {vol, shift, scat};
  pm_parallel((size_t)c.nz, 1, coarse_scattering_range, &job);
  for (int k = 0; k < c.nz; k++)
    for (int j = 0; j < c.ny; j++)
      for (int i = 0; i < c.nx; i++) {
        size_t v = grid_index(&c, i, j, k);
        /* voxels of this cell inside the grid */
        int ex = (i + 1) << shift > d->nx ? d->nx - (i << shift) : 1 << shift;
        int ey = (j + 1) << shift > d->ny ? d->ny - (j << shift) : 1 << shift;
        int ez = (k + 1) << shift > d->nz ? d->nz - (k << shift) : 1 << shift;
        double inv = 1.0 / ((double)ex * ey * ez);
        for (int q = 0; q < 3; q++)
          rgb[3 * v + q] = (float)((double)acc[ch * v + (ch == 1 ? 0 : q)] * p->to_radiance[q] * inv);
      }
}

/* The grey march's counters to one float per voxel (grey_range), and one
 * float per voxel to RGB (colour_range), on every core. */
typedef struct scale_job {
  const uint64_t *acc; /* grey_range: 2 counters per voxel, radiance first */
  const float *in;     /* colour_range */
  float *out;
  float k[3];
} scale_job_t;

static void grey_range(void *arg, size_t lo, size_t hi) {
  const scale_job_t *j = arg;
  for (size_t v = lo; v < hi; v++) j->out[v] = (float)j->acc[2 * v] * j->k[0];
}

static void colour_range(void *arg, size_t lo, size_t hi) {
  const scale_job_t *j = arg;
  for (size_t v = lo; v < hi; v++) {
    j->out[3 * v] = j->in[v] * j->k[0];
    j->out[3 * v + 1] = j->in[v] * j->k[1];
    j->out[3 * v + 2] = j->in[v] * j->k[2];
  }
}

static int run_march(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *st,
                     bk_error_t *err) {
  return cl ? pm_run_cl(cl, s, acc, st, err) : pm_run_host(s, acc, st, err);
}

int ad_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol,
            const ad_bake_opts_t *opt, float *radiance, float *photon_count, float *photon_weight,
            float *filter_radius, ad_stats_t *stats, bk_timings_t *timings, bk_error_t *err) {
  pm_setup_t base, pilot, main;
  ad_stats_t local;
  ad_bake_opts_t defaults;
  uint64_t *pacc = NULL, *masks = NULL, *acc = NULL;
  float *prgb = NULL, *pscat = NULL, *tables = NULL, *count = NULL, *weight = NULL;
  float *raw = NULL, *filtered = NULL, *vw = NULL;
  uint8_t *sel = NULL;
  double t0;
  memset(&base, 0, sizeof base);
  if (!stats) stats = &local;
  memset(stats, 0, sizeof *stats);
  if (!opt) {
    ad_bake_defaults(&defaults);
    opt = &defaults;
  }
  if (scene->pilot < 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: adaptive.pilot: expected a photon count >= 0, got %d",
                   scene->path, scene->pilot);
  if (!(scene->alpha >= 0.0f) || isinf(scene->alpha))
    return bk_fail(err, BK_ERR_INPUT, "%s: adaptive.alpha: expected a finite number >= 0, got %g",
                   scene->path, (double)scene->alpha);
  if (!(opt->max_radius >= 0.0f && opt->max_radius <= 0.5f * AD_FILTER_MAX_LEVEL))
    return bk_fail(err, BK_ERR_INPUT, "adaptive filter: largest radius %g: expected 0..%g voxels",
                   (double)opt->max_radius, 0.5 * AD_FILTER_MAX_LEVEL);
  const int levels = (int)(2.0f * opt->max_radius + 0.5f);

  int rc = pm_prepare(scene, vol, &base, NULL, &stats->march, err);
  if (rc != BK_OK) return rc;
  stats->ms_octree = stats->march.ms_octree;
  stats->ms_generate = stats->march.ms_generate;
  const grid_dims_t *d = &base.dims;
  const size_t V = base.voxels;
  const int nl = base.lights.count > 0 ? base.lights.count : 1;
  const int TF = LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y);
  rc = BK_ERR_RUNTIME;
  tables = bk_calloc((size_t)nl, TF * sizeof(float), "adaptive PDF tables", err);
  if (!tables) goto error;

  /* phase 1: the pilot, on coarse cells over the full-resolution field */
  const int shift = ad_pilot_shift(d, opt->pilot_cells);
  const grid_dims_t cd = coarse_dims(d, shift);
  const size_t CV = grid_count(&cd);
  stats->coarse_shift = shift;
  stats->pilot_photons = scene->pilot;
  t0 = bk_now_ms();
  int have_pilot = scene->pilot > 0 && base.lights.count > 0;
  if (have_pilot) {
    rc = pm_derive(&base, scene, (uint64_t)scene->pilot, &pilot, err);
    if (rc != BK_OK) goto error;
    pm_record_origins(&pilot, shift, NULL);
    rc = BK_ERR_RUNTIME;
    masks = bk_calloc(pm_mask_count(&pilot), sizeof(uint64_t), "adaptive origin masks", err);
    pacc = bk_calloc(pm_acc_count(&pilot), sizeof(uint64_t), "adaptive pilot accumulator", err);
    if (!masks || !pacc) goto error;
    pilot.masks = masks;
    rc = run_march(cl, &pilot, pacc, &stats->pilot, err);
    if (rc != BK_OK) goto error;
  }
  stats->ms_pilot = bk_now_ms() - t0;

  /* the distribution: selection on the pilot, one PDF per light */
  t0 = bk_now_ms();
  double pdf_min = 1.0, pdf_max = 1.0;
  if (have_pilot) {
    rc = BK_ERR_RUNTIME;
    prgb = bk_calloc(CV, 3 * sizeof(float), "adaptive pilot radiance", err);
    pscat = bk_calloc(CV, sizeof(float), "adaptive pilot scattering", err);
    sel = bk_calloc(CV, 1, "adaptive selection", err);
    if (!prgb || !pscat || !sel) goto error;
    coarse_fields(&pilot, pacc, vol, shift, prgb, pscat);
    ad_select_opts_t so = {scene->gradient_threshold, scene->luminance_threshold,
                           opt->smooth_radius};
    rc = ad_select_voxels(&cd, prgb, pscat, &so, sel, &stats->select, err);
    if (rc != BK_OK) goto error;
    if (opt->importance != AD_IMPORTANCE_UNIT) {
      rc = BK_ERR_RUNTIME;
      vw = bk_calloc(CV, 2 * sizeof(float), "adaptive importance", err);
      if (!vw) goto error;
      rc = ad_pilot_fields(&cd, prgb, opt->smooth_radius, vw + CV, vw, err);
      if (rc != BK_OK) goto error;
      for (size_t v = 0; v < CV; v++) {
        double x = opt->importance == AD_IMPORTANCE_LUMINANCE ? vw[CV + v] : vw[v];
        vw[v] = (float)(opt->importance == AD_IMPORTANCE_GRADIENT_23 ? pow(x, 2.0 / 3.0) : x);
      }
    }
    pdf_min = 1e30;
    pdf_max = 0.0;
    /* tables follow the main march's lights (base's: the same photon count);
     * the pilot's may lack a faint light that got no pilot photon, which
     * then keeps the uniform PDF */
    for (int l = 0; l < base.lights.count; l++) {
      ad_pdf_t pdf;
      int p = -1;
      for (int q = 0; q < pilot.lights.count; q++)
        if (pilot.lights.scene_index[q] == base.lights.scene_index[l]) p = q;
      if (p >= 0) {
        rc = ad_build_pdf_weighted(masks + (size_t)p * CV, sel, vw, CV, opt->floor_fraction,
                                   &pdf, err);
      } else {
        memset(&pdf, 0, sizeof pdf);
        double zero[LD_CELLS] = {0};
        rc = ad_pdf_from_weights(zero, LD_CELLS_X, LD_CELLS_Y, 1.0f, pdf.table, pdf.cell_pdf, err);
      }
      if (rc != BK_OK) goto error;
      memcpy(tables + (size_t)l * TF, pdf.table, TF * sizeof(float));
      if (bk_verbosity >= 2) {
        char line[LD_CELLS_X * 8 + 1];
        bk_log(2, "adaptive: light %d: pdf per cell (rows b, columns a), %zu selected cells "
                  "with origin data", l, pdf.selected_reached);
        for (int y = 0; y < LD_CELLS_Y; y++) {
          int at = 0;
          for (int x = 0; x < LD_CELLS_X; x++)
            at += snprintf(line + at, sizeof line - at, " %6.2f", (double)pdf.cell_pdf[x + LD_CELLS_X * y]);
          bk_log(2, "  %s", line);
        }
      }
      for (int c = 0; c < LD_CELLS; c++) {
        pdf_min = fmin(pdf_min, pdf.cell_pdf[c]);
        pdf_max = fmax(pdf_max, pdf.cell_pdf[c]);
      }
    }
  } else {
    double zero[LD_CELLS] = {0};
    for (int l = 0; l < nl; l++) {
      rc = ad_pdf_from_weights(zero, LD_CELLS_X, LD_CELLS_Y, 1.0f, tables + (size_t)l * TF, NULL,
                               err);
      if (rc != BK_OK) goto error;
    }
  }
  stats->pdf_min = (float)pdf_min;
  stats->pdf_max = (float)pdf_max;
  stats->ms_distribution = bk_now_ms() - t0;

  /* phase 2: warped Hammersley photons of weight 1/pdf */
  t0 = bk_now_ms();
  rc = pm_derive(&base, scene, (uint64_t)scene->photon_count, &main, err);
  if (rc != BK_OK) goto error;
  rc = pm_sample_tables(&main, tables, 1.0 / pdf_min, err);
  if (rc != BK_OK) goto error;
  stats->ms_generate += bk_now_ms() - t0;
  t0 = bk_now_ms();
  rc = BK_ERR_RUNTIME;
  acc = bk_calloc(pm_acc_count(&main), sizeof(uint64_t), "adaptive accumulator", err);
  count = photon_count ? photon_count : bk_calloc(V, sizeof(float), "photon count grid", err);
  weight = photon_weight ? photon_weight : bk_calloc(V, sizeof(float), "photon weight grid", err);
  if (!acc || !count || !weight) goto error;
  if (main.lights.count > 0) {
    rc = run_march(cl, &main, acc, &stats->march, err);
    if (rc != BK_OK) goto error;
  }
  const int C = main.channels;
  const int filter_on = opt->filter && scene->alpha > 0.0f && levels > 0;
  /* grey: the filter works on the one channel the march carried (its
   * luminance is proportional), and colours the result after */
  double grey_k = main.to_radiance[0] + main.to_radiance[1] + main.to_radiance[2];
  if (filter_on) {
    raw = bk_calloc(V, (size_t)C * sizeof(float), "adaptive raw radiance", err);
    if (!raw) goto error;
    if (C == 1) {
      scale_job_t job = {acc, NULL, raw, {(float)grey_k, 0.0f, 0.0f}};
      pm_parallel(V, PM_GRAIN, grey_range, &job);
    } else
      pm_to_radiance(&main, acc, raw);
  } else {
    pm_to_radiance(&main, acc, radiance);
  }
  pm_unpack_weights(&main, acc, count, weight);
  free(acc);
  acc = NULL;
  stats->ms_march = bk_now_ms() - t0;

  /* reconstruction */
  t0 = bk_now_ms();
  stats->filtered = filter_on;
  stats->max_radius = filter_on ? 0.5f * levels : 0.0f;
  if (filter_on) {
    filtered = C == 1 ? bk_calloc(V, sizeof(float), "adaptive filtered radiance", err) : radiance;
    if (!filtered) goto error;
    rc = cl ? ad_filter_cl(cl, d, C, raw, count, weight, scene->alpha, opt->noise_k, levels,
                           filtered, filter_radius, err)
            : ad_filter_host(d, C, raw, count, weight, scene->alpha, opt->noise_k, levels,
                             filtered, filter_radius, err);
    if (rc != BK_OK) goto error;
    if (C == 1) {
      scale_job_t job = {NULL, filtered, radiance,
                         {(float)(main.to_radiance[0] / grey_k),
                          (float)(main.to_radiance[1] / grey_k),
                          (float)(main.to_radiance[2] / grey_k)}};
      pm_parallel(V, PM_GRAIN, colour_range, &job);
    }
  } else if (filter_radius) {
    memset(filter_radius, 0, V * sizeof(float));
  }
  stats->ms_filter = bk_now_ms() - t0;

  if (timings) {
    bk_timings_add(timings, "octree", stats->ms_octree, "%s",
                   base.has_refraction ? "constant-block pyramid of n, n/grad n field"
                                       : "n constant: one straight DDA per photon");
    bk_timings_add(timings, "pilot marching", stats->ms_pilot,
                   "%d pilot photons, origin data on %dx%dx%d cells of %d^3 voxels",
                   have_pilot ? scene->pilot : 0, cd.nx, cd.ny, cd.nz, 1 << shift);
    bk_timings_add(timings, "photon distribution", stats->ms_distribution,
                   "%zu cells selected, pdf %.2f..%.2f", stats->select.selected, pdf_min, pdf_max);
    bk_timings_add(timings, "photon generation", stats->ms_generate,
                   "%d light(s), in-kernel Hammersley warped by the PDF", base.lights.count);
    double sec = stats->ms_march > 0.0 ? stats->ms_march / 1000.0 : 1e-9;
    bk_timings_add(timings, "photon marching", stats->ms_march,
                   "%llu photons, %.0f M voxels/s%s", (unsigned long long)stats->march.photons,
                   stats->march.voxels / sec * 1e-6, cl ? "" : ", host C");
    if (filter_on)
      bk_timings_add(timings, "filtering", stats->ms_filter, "alpha %g, radius <= %g voxels%s",
                     (double)scene->alpha, 0.5 * levels, cl ? "" : ", host C");
    else
      bk_timings_add(timings, "filtering", stats->ms_filter, "off");
  }
  bk_log(2,
         "adaptive: pilot %d photons on %dx%dx%d cells, thresholds gradient %g /m, luminance %g; "
         "%zu of %zu cells selected; pdf %.3f..%.3f; %llu photons marched",
         have_pilot ? scene->pilot : 0, cd.nx, cd.ny, cd.nz,
         (double)stats->select.gradient_threshold, (double)stats->select.luminance_threshold,
         stats->select.selected, stats->select.considered, pdf_min, pdf_max,
         (unsigned long long)stats->march.photons);
  rc = BK_OK;
error:
  free(pacc);
  free(masks);
  free(acc);
  free(prgb);
  free(pscat);
  free(sel);
  free(vw);
  free(tables);
  free(raw);
  if (filtered != radiance) free(filtered);
  if (count != photon_count) free(count);
  if (weight != photon_weight) free(weight);
  pm_setup_free(&base);
  return rc;
}
