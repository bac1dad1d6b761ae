/* adaptive_pdf.c: phase 1 of the adaptive pipeline on the pilot's cells:
 * the coarse cells and what the pilot left in them, the pilot fields
 * (smoothed luminance and its gradient), the automatic thresholds, the
 * voxel selection and the sampling PDF of each light. The
 * shared math (cells, origin masks, the PDF warp) is kernels/adaptive_filter.h. */
#define _POSIX_C_SOURCE 200809L
#include "adaptive.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "adaptive_internal.h"
#include "base/parallel.h"
#include "base/select.h"

int ad_grid_voxels(const grid_dims_t *d, size_t per_voxel, const char *what, size_t *voxels,
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

/* --- the pilot's coarse cells --------------------------------------------------- */

/* The pilot grid's coarsening: cells of 2^shift voxels a side, the fewest
 * that bring the longest axis to pilot_cells cells. */
int ad_pilot_shift(const grid_dims_t *d, int pilot_cells) {
  int longest = d->nx > d->ny ? d->nx : d->ny;
  if (d->nz > longest) longest = d->nz;
  int s = 0;
  while (s < 10 && pilot_cells > 0 && (longest >> s) > pilot_cells) s++;
  return s;
}

/* The pilot's coarse grid: cells of 2^shift voxels a side over the same
 * corner (the last ones may stick out of the grid). */
grid_dims_t ad_coarse_dims(const grid_dims_t *d, int shift) {
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
  grid_dims_t c = ad_coarse_dims(d, shift);
  for (size_t v = grid_index(&c, 0, 0, (int)lo); v < grid_index(&c, 0, 0, (int)hi); v++)
    j->scat[v] = 0.0f;
  int k1 = (int)hi << shift;
  if (k1 > d->nz) k1 = d->nz;
  for (int k = (int)lo << shift; k < k1; k++)
    for (int jy = 0; jy < d->ny; jy++) {
      size_t row = grid_index(d, 0, jy, k);
      float *crow = j->scat + grid_index(&c, 0, jy >> shift, k >> shift);
      const volume_t *v = j->vol;
      for (int i = 0; i < d->nx; i++) {
        const size_t at = row + (size_t)i;
        float g = (vol_sigma_s(v, at, 0) + vol_sigma_s(v, at, 1) + vol_sigma_s(v, at, 2)) *
                  (1.0f / 3.0f);
        float *o = &crow[i >> shift];
        if (g > *o) *o = g;
      }
    }
}

/* Per coarse cell: the pilot's mean radiance over its voxels in the grid
 * (3 floats) and the largest grey scattering coefficient of those voxels. */
void ad_coarse_fields(const pm_setup_t *p, const uint64_t *acc, const volume_t *vol, int shift,
                      float *rgb, float *scat) {
  const grid_dims_t *d = &vol->dims;
  grid_dims_t c = ad_coarse_dims(d, shift);
  const int ch = p->channels;
  scat_job_t job = {vol, shift, scat};
  bk_parallel((size_t)c.nz, 1, coarse_scattering_range, &job);
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
  int rc = ad_grid_voxels(d, 3 * sizeof(float), "adaptive pilot", &voxels, err);
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
    med_lum = bk_quantile(vals, n, 0.5f);
    n = 0;
    for (size_t v = 0; v < voxels; v++) {
      if (scattering && !(scattering[v] > 0.0f)) continue;
      const float *c = pilot_radiance + 3 * v;
      if (ad_luminance(c[0], c[1], c[2]) > 0.0f) vals[n++] = grad[v];
    }
    med_grad = bk_quantile(vals, n, 0.5f);
    float p = bk_quantile(vals, n, AD_AUTO_GRADIENT_PERCENTILE);
    if (isnan(med_lum) || isnan(med_grad) || isnan(p)) {
      free(vals);
      return bk_fail(err, BK_ERR_RUNTIME, "adaptive thresholds: out of memory");
    }
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

/* --- selection ---------------------------------------------------------------- */

int ad_select_voxels(const grid_dims_t *d, const float *pilot_radiance, const float *scattering,
                     const ad_select_opts_t *opt, uint8_t *selected, ad_select_stats_t *stats,
                     bk_error_t *err) {
  size_t voxels;
  float *lum = NULL, *grad = NULL;
  ad_select_stats_t st;
  memset(&st, 0, sizeof st);
  int rc = ad_grid_voxels(d, 3 * sizeof(float), "adaptive selection", &voxels, err);
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
  float g_auto = 0.0f, l_auto = 0.0f;
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

void ad_cell_costs(const uint64_t *cell_work, double *cost) {
  uint64_t photons = 0, work = 0;
  for (int c = 0; c < LD_CELLS; c++) photons += cell_work[c], work += cell_work[LD_CELLS + c];
  const double mean = photons ? (double)work / (double)photons : 1.0;
  for (int c = 0; c < LD_CELLS; c++) {
    double w = cell_work[c] ? (double)cell_work[LD_CELLS + c] / (double)cell_work[c] : mean;
    cost[c] = w > 1.0 ? w : 1.0;
  }
}

int ad_build_pdf(const uint64_t *origin_masks, const uint8_t *selected, const float *voxel_weight,
                 const double *cost, size_t voxels, float floor_fraction, ad_pdf_t *pdf,
                 bk_error_t *err) {
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
  double w[LD_CELLS];
  for (int c = 0; c < LD_CELLS; c++) w[c] = pdf->importance[c] / (cost ? sqrt(cost[c]) : 1.0);
  return ad_pdf_from_weights(w, LD_CELLS_X, LD_CELLS_Y, floor_fraction, pdf->table, pdf->cell_pdf,
                             err);
}
