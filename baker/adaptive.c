/* adaptive.c: voxel selection, automatic thresholds and the sampling PDF of
 * the adaptive pipeline (phase 1), and the reconstruction filter on the host
 * and on the OpenCL device. The shared math is kernels/adaptive.h. */
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

static bk_grid kernel_grid(const grid_dims_t *d) {
  bk_grid g;
  g.nx = d->nx;
  g.ny = d->ny;
  g.nz = d->nz;
  g.pad0 = 0;
  g.origin_x = d->origin[0];
  g.origin_y = d->origin[1];
  g.origin_z = d->origin[2];
  g.voxel_size = d->voxel_size;
  return g;
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
            ad_pdf_eval(table, nx, ny, ((float)c + 0.5f) / (float)nx, ((float)r + 0.5f) / (float)ny);
  return BK_OK;
}

int ad_build_pdf(const uint64_t *origin_masks, const uint8_t *selected, size_t voxels,
                 float floor_fraction, ad_pdf_t *pdf, bk_error_t *err) {
  if (!pdf) return bk_fail(err, BK_ERR_RUNTIME, "adaptive pdf: missing output");
  memset(pdf, 0, sizeof *pdf);
  if (voxels > 0 && (!origin_masks || !selected))
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive pdf: missing origin masks or selection");
  pdf->nx = AD_CELLS_X;
  pdf->ny = AD_CELLS_Y;
  pdf->floor_fraction = floor_fraction;
  for (size_t v = 0; v < voxels; v++) {
    uint64_t m = origin_masks[v];
    if (!selected[v] || !m) continue;
    double share = 1.0 / (double)__builtin_popcountll(m);
    while (m) {
      pdf->importance[__builtin_ctzll(m)] += share;
      m &= m - 1;
    }
    pdf->selected_reached++;
  }
  return ad_pdf_from_weights(pdf->importance, AD_CELLS_X, AD_CELLS_Y, floor_fraction, pdf->table,
                             pdf->cell_pdf, err);
}

/* --- the reconstruction filter ------------------------------------------------ */

/* Shell r = 0 for d = 0, else the smallest r with |d|^2 <= r^2. */
static int shell_of(int d2) {
  int r = (int)sqrt((double)d2);
  while (r * r < d2) r++;
  while (r > 0 && (r - 1) * (r - 1) >= d2) r--;
  return r;
}

int ad_sphere_size(int r) {
  if (r < 0) return 0;
  int n = 0;
  for (int z = -r; z <= r; z++)
    for (int y = -r; y <= r; y++)
      for (int x = -r; x <= r; x++) n += x * x + y * y + z * z <= r * r;
  return n;
}

/* The filter's tables (see kernels/adaptive.h): the offsets of the sphere of
 * radius rmax grouped by shell (3 ints each; within a shell in z, y, x order,
 * so host and device sum alike), the shell starts (rmax + 2 entries), and the
 * Gaussian weights, row r (radius) column q (squared length), AD_Q_MAX + 1
 * columns, for r = 0..AD_FILTER_MAX_RADIUS. */
typedef struct filter_tables {
  int *offsets, *start;
  float *weights;
  int n_offsets;
} filter_tables_t;

static void free_tables(filter_tables_t *t) {
  free(t->offsets);
  free(t->start);
  free(t->weights);
  memset(t, 0, sizeof *t);
}

#define AD_WEIGHT_COUNT ((AD_FILTER_MAX_RADIUS + 1) * (AD_Q_MAX + 1))

static int filter_tables(int rmax, filter_tables_t *t, bk_error_t *err) {
  memset(t, 0, sizeof *t);
  int total = ad_sphere_size(rmax);
  t->offsets = bk_calloc((size_t)total * 3, sizeof(int), "filter shell table", err);
  t->start = bk_calloc((size_t)rmax + 2, sizeof(int), "filter shell table", err);
  t->weights = bk_calloc(AD_WEIGHT_COUNT, sizeof(float), "filter weights", err);
  if (!t->offsets || !t->start || !t->weights) {
    free_tables(t);
    return BK_ERR_RUNTIME;
  }
  int n = 0;
  for (int s = 0; s <= rmax; s++) {
    t->start[s] = n;
    for (int z = -rmax; z <= rmax; z++)
      for (int y = -rmax; y <= rmax; y++)
        for (int x = -rmax; x <= rmax; x++) {
          int d2 = x * x + y * y + z * z;
          if (d2 > rmax * rmax || shell_of(d2) != s) continue;
          t->offsets[3 * n] = x;
          t->offsets[3 * n + 1] = y;
          t->offsets[3 * n + 2] = z;
          n++;
        }
  }
  t->start[rmax + 1] = n;
  t->n_offsets = n;
  for (int r = 0; r <= AD_FILTER_MAX_RADIUS; r++) {
    double sigma = (double)AD_FILTER_SIGMA * r;
    for (int q = 0; q <= r * r; q++)
      t->weights[r * (AD_Q_MAX + 1) + q] =
          r == 0 ? 1.0f : (float)exp(-(double)q / (2.0 * sigma * sigma));
  }
  return BK_OK;
}

static int check_filter_args(const grid_dims_t *d, const float *radiance, const uint32_t *count,
                             const float *mean_weight, float alpha, int max_radius,
                             const float *out_radiance, size_t *voxels, bk_error_t *err) {
  int rc = grid_size(d, 3 * sizeof(float), "adaptive filter", voxels, err);
  if (rc != BK_OK) return rc;
  if (!(alpha >= 0.0f) || isinf(alpha))
    return bk_fail(err, BK_ERR_INPUT, "adaptive.alpha: expected a finite number >= 0, got %g",
                   (double)alpha);
  if (max_radius < 0 || max_radius > AD_FILTER_MAX_RADIUS)
    return bk_fail(err, BK_ERR_INPUT, "adaptive filter: maximum radius %d: expected 0..%d voxels",
                   max_radius, AD_FILTER_MAX_RADIUS);
  if (!radiance || !count || !mean_weight || !out_radiance)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive filter: missing input or output array");
  if (out_radiance == radiance)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "adaptive filter: the output must not alias the input radiance");
  return BK_OK;
}

typedef struct filter_job {
  const float *rgb;
  const uint32_t *count;
  const float *mean_weight;
  const filter_tables_t *tab;
  bk_grid g;
  float alpha;
  int rmax;
  float *out, *radius;
  int first, step; /* z slices first, first + step, ... */
} filter_job_t;

static void *filter_slices(void *arg) {
  const filter_job_t *job = arg;
  const bk_grid g = job->g;
  for (int k = job->first; k < g.nz; k += job->step)
    for (int j = 0; j < g.ny; j++)
      for (int i = 0; i < g.nx; i++) {
        size_t v = (size_t)i + (size_t)g.nx * ((size_t)j + (size_t)g.ny * (size_t)k);
        float o[3];
        int r = ad_filter_voxel(job->rgb, job->count, job->mean_weight, job->tab->offsets,
                                job->tab->start, job->tab->weights, g, job->alpha, job->rmax, i,
                                j, k, o);
        job->out[3 * v] = o[0];
        job->out[3 * v + 1] = o[1];
        job->out[3 * v + 2] = o[2];
        if (job->radius) job->radius[v] = (float)r;
      }
  return NULL;
}

int ad_filter_host(const grid_dims_t *d, const float *radiance, const uint32_t *count,
                   const float *mean_weight, float alpha, int max_radius, float *out_radiance,
                   float *out_radius, bk_error_t *err) {
  size_t voxels;
  filter_tables_t tab;
  int rc = check_filter_args(d, radiance, count, mean_weight, alpha, max_radius, out_radiance,
                             &voxels, err);
  if (rc != BK_OK) return rc;
  rc = filter_tables(max_radius, &tab, err);
  if (rc != BK_OK) return rc;

  long cpus = sysconf(_SC_NPROCESSORS_ONLN);
  int threads = cpus < 1 ? 1 : cpus > AD_MAX_THREADS ? AD_MAX_THREADS : (int)cpus;
  if (threads > d->nz) threads = d->nz;
  filter_job_t jobs[AD_MAX_THREADS];
  pthread_t tid[AD_MAX_THREADS];
  int started = 0;
  for (int t = 0; t < threads; t++) {
    filter_job_t *job = &jobs[t];
    job->rgb = radiance;
    job->count = count;
    job->mean_weight = mean_weight;
    job->tab = &tab;
    job->g = kernel_grid(d);
    job->alpha = alpha;
    job->rmax = max_radius;
    job->out = out_radiance;
    job->radius = out_radius;
    job->first = t;
    job->step = threads;
  }
  /* thread 0 is this one; a thread that cannot start leaves its slices to
   * the caller's thread, so the result never depends on the thread count */
  for (int t = 1; t < threads; t++) {
    if (pthread_create(&tid[t], NULL, filter_slices, &jobs[t]) != 0) break;
    started = t;
  }
  filter_slices(&jobs[0]);
  for (int t = 1; t <= started; t++) pthread_join(tid[t], NULL);
  for (int t = started + 1; t < threads; t++) filter_slices(&jobs[t]);
  free_tables(&tab);
  return BK_OK;
}

int ad_filter_cl_buffers(clh_context_t *cl, cl_program program, const grid_dims_t *d, cl_mem rgb,
                         cl_mem count, cl_mem mean_weight, float alpha, int max_radius,
                         cl_mem out_rgb, cl_mem out_radius, bk_error_t *err) {
  cl_program own = NULL;
  cl_kernel kernel = NULL;
  cl_mem off_buf = NULL, start_buf = NULL, w_buf = NULL;
  cl_int cerr = CL_SUCCESS;
  filter_tables_t tab;
  size_t voxels;
  int rc = grid_size(d, 3 * sizeof(float), "adaptive filter", &voxels, err);
  if (rc != BK_OK) return rc;
  if (!(alpha >= 0.0f) || isinf(alpha))
    return bk_fail(err, BK_ERR_INPUT, "adaptive.alpha: expected a finite number >= 0, got %g",
                   (double)alpha);
  if (max_radius < 0 || max_radius > AD_FILTER_MAX_RADIUS)
    return bk_fail(err, BK_ERR_INPUT, "adaptive filter: maximum radius %d: expected 0..%d voxels",
                   max_radius, AD_FILTER_MAX_RADIUS);
  rc = filter_tables(max_radius, &tab, err);
  if (rc != BK_OK) return rc;
  rc = BK_ERR_RUNTIME;
  if (!program) {
    if (clh_build(cl, "filter.cl", "", &own, err) != BK_OK) goto error;
    program = own;
  }
  off_buf = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                           (size_t)tab.n_offsets * 3 * sizeof(int), tab.offsets, &cerr);
  CLH_CHECK(cerr, err, error);
  start_buf = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                             ((size_t)max_radius + 2) * sizeof(int), tab.start, &cerr);
  CLH_CHECK(cerr, err, error);
  w_buf = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                         AD_WEIGHT_COUNT * sizeof(float), tab.weights, &cerr);
  CLH_CHECK(cerr, err, error);
  kernel = clCreateKernel(program, "ad_filter", &cerr);
  CLH_CHECK(cerr, err, error);
  bk_grid g = kernel_grid(d);
  cl_int want = out_radius != NULL;
  CLH_CHECK(clSetKernelArg(kernel, 0, sizeof(cl_mem), &rgb), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 1, sizeof(cl_mem), &count), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 2, sizeof(cl_mem), &mean_weight), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 3, sizeof(cl_mem), &off_buf), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 4, sizeof(cl_mem), &start_buf), err, error);
  cl_int rmax = max_radius;
  CLH_CHECK(clSetKernelArg(kernel, 5, sizeof(cl_mem), &w_buf), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 6, sizeof(bk_grid), &g), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 7, sizeof(float), &alpha), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 8, sizeof(cl_int), &rmax), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 9, sizeof(cl_int), &want), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 10, sizeof(cl_mem), &out_rgb), err, error);
  /* a NULL buffer is a NULL pointer in the kernel, which want = 0 never touches */
  CLH_CHECK(clSetKernelArg(kernel, 11, sizeof(cl_mem), &out_radius), err, error);
  size_t global[3] = {(size_t)d->nx, (size_t)d->ny, (size_t)d->nz};
  CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, kernel, 3, NULL, global, NULL, 0, NULL, NULL), err,
            error);
  CLH_CHECK(clFinish(cl->queue), err, error);
  rc = BK_OK;
error:
  if (kernel) clReleaseKernel(kernel);
  if (off_buf) clReleaseMemObject(off_buf);
  if (start_buf) clReleaseMemObject(start_buf);
  if (w_buf) clReleaseMemObject(w_buf);
  if (own) clReleaseProgram(own);
  free_tables(&tab);
  return rc;
}

int ad_filter_cl(clh_context_t *cl, const grid_dims_t *d, const float *radiance,
                 const uint32_t *count, const float *mean_weight, float alpha, int max_radius,
                 float *out_radiance, float *out_radius, bk_error_t *err) {
  cl_mem rgb = NULL, cnt = NULL, wm = NULL, out = NULL, rad = NULL;
  cl_int cerr = CL_SUCCESS;
  size_t voxels;
  char b1[32], b2[32];
  int rc = check_filter_args(d, radiance, count, mean_weight, alpha, max_radius, out_radiance,
                             &voxels, err);
  if (rc != BK_OK) return rc;
  rc = BK_ERR_RUNTIME;
  size_t rgb_bytes = voxels * 3 * sizeof(float), one_bytes = voxels * sizeof(float);
  if ((cl_ulong)rgb_bytes > cl->max_alloc) {
    bk_fail(err, BK_ERR_RUNTIME,
            "adaptive filter: the %dx%dx%d radiance grid needs %s in one buffer; %s allows %s",
            d->nx, d->ny, d->nz, bk_format_bytes((double)rgb_bytes, b1, sizeof b1),
            cl->device_name, bk_format_bytes((double)cl->max_alloc, b2, sizeof b2));
    goto error;
  }
  rgb = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, rgb_bytes,
                       (void *)radiance, &cerr);
  CLH_CHECK(cerr, err, error);
  cnt = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                       voxels * sizeof(uint32_t), (void *)count, &cerr);
  CLH_CHECK(cerr, err, error);
  wm = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, one_bytes,
                      (void *)mean_weight, &cerr);
  CLH_CHECK(cerr, err, error);
  out = clCreateBuffer(cl->context, CL_MEM_WRITE_ONLY, rgb_bytes, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  if (out_radius) {
    rad = clCreateBuffer(cl->context, CL_MEM_WRITE_ONLY, one_bytes, NULL, &cerr);
    CLH_CHECK(cerr, err, error);
  }
  if (ad_filter_cl_buffers(cl, NULL, d, rgb, cnt, wm, alpha, max_radius, out, rad, err) != BK_OK)
    goto error;
  CLH_CHECK(clEnqueueReadBuffer(cl->queue, out, CL_TRUE, 0, rgb_bytes, out_radiance, 0, NULL,
                                NULL), err, error);
  if (out_radius)
    CLH_CHECK(clEnqueueReadBuffer(cl->queue, rad, CL_TRUE, 0, one_bytes, out_radius, 0, NULL,
                                  NULL), err, error);
  rc = BK_OK;
error:
  if (rgb) clReleaseMemObject(rgb);
  if (cnt) clReleaseMemObject(cnt);
  if (wm) clReleaseMemObject(wm);
  if (out) clReleaseMemObject(out);
  if (rad) clReleaseMemObject(rad);
  return rc;
}
