/* adaptive.h: the adaptive pipeline (DESIGN.md §3 stage 6) around the photon
 * march: voxel selection and the sampling PDF (phase 1), and the
 * reconstruction filter (after phase 2). The march itself (pilot and main
 * photons) lives in baker/march.c; the math both sides share is in
 * kernels/adaptive.h (cells, origin masks, the PDF warp, the filter).
 *
 * How a bake uses it, per frame:
 *  1. Pilot march, uniform Hammersley points, `adaptive.pilot` photons (~4000).
 *     It writes the pilot radiance (3 floats per voxel) and the origin masks:
 *     one uint64_t per voxel per light, light major (ad_origin_index), bit c
 *     set when a pilot photon from light-domain cell c = ad_cell_of(a, b)
 *     crossed the voxel (ad_origin_mark).
 *  2. ad_select_voxels on the pilot radiance: voxels whose luminance gradient
 *     exceeds a threshold (edges, caustics) or whose luminance is below one
 *     (shadows). Thresholds are explicit or automatic (ad_auto_thresholds,
 *     the rule is documented there).
 *  3. ad_build_pdf, per light: a 2D PDF over the light's 8x8 cells that
 *     favours the cells whose photons reached selected voxels, mixed with the
 *     uniform density so that every cell keeps pdf >= floor_fraction.
 *     Upload pdf.table (AD_TABLE_FLOATS(8, 8) floats per light).
 *  4. Main march: photon k of N takes its Hammersley point u, warps it with
 *     ad_pdf_warp(table, 8, 8, u) -> (x, pdf), generates the photon from x and
 *     multiplies its power (light power / N) by w = 1/pdf. Per voxel it keeps
 *     the photon count and the sum of w over the photons that crossed it; the
 *     mean weight w_mean = sum / count (0 where count is 0) is the
 *     `photon_weight` grid and the count the `photon_count` grid. w_mean is 1
 *     for uniform sampling, < 1 where the PDF concentrated photons.
 *  5. ad_filter_host / ad_filter_cl on the radiance with count and w_mean:
 *     radius min(round(alpha * w_mean), centre-surround radius), see
 *     kernels/adaptive.h. The radius grid is a debug output.
 *
 * Arrays are dense, x-fastest (grid.h); the caller allocates outputs. */
#ifndef BAKER_ADAPTIVE_H
#define BAKER_ADAPTIVE_H

#include <stdint.h>

#include "clhost.h"
#include "grid.h"
#include "kernels/adaptive.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Automatic thresholds (ad_auto_thresholds; reasons in adaptive.c). */
#define AD_AUTO_GRADIENT_PERCENTILE 0.90f /* at most the top 10% of reached voxels */
#define AD_AUTO_GRADIENT_OUTLIER 4.0f     /* and at least 4 median gradients */
#define AD_AUTO_SHADOW_FRACTION 0.1f      /* shadow: a decade below the median */
#define AD_DEFAULT_SMOOTH_RADIUS 1        /* box pre-smoothing of the pilot, voxels */
#define AD_DEFAULT_FLOOR 0.25f            /* pdf >= 1/4: weights <= 4 */

/* Selection flags, per voxel. */
#define AD_SEL_GRADIENT 1u
#define AD_SEL_SHADOW 2u

typedef struct ad_select_opts {
  float gradient_threshold;  /* < 0 (SCENE_AUTO): automatic; else luminance per metre */
  float luminance_threshold; /* < 0: automatic; else W m^-2 sr^-1 (luminance of L̄) */
  int smooth_radius;         /* box half-width in voxels applied to the pilot
                                luminance before both tests (0 = none); the
                                pilot is a few thousand photon tracks, and one
                                track next to empty voxels is not an edge */
} ad_select_opts_t;

typedef struct ad_select_stats {
  float gradient_threshold;  /* the thresholds used (auto or given) */
  float luminance_threshold;
  float median_luminance;    /* over reached voxels (smoothed pilot) */
  float median_gradient;
  size_t considered;         /* voxels that matter (sigma_s > 0, or all) */
  size_t reached;            /* ... that a pilot photon crossed */
  size_t by_gradient, by_shadow, selected; /* selected = either */
} ad_select_stats_t;

/* The pilot fields the tests run on: per voxel, the luminance of the pilot
 * radiance box-smoothed over (2s+1)^3 voxels (clipped to the grid), and the
 * magnitude of its gradient in luminance per metre (central differences,
 * one-sided on the faces). lum and grad hold grid_count(d) floats. */
int ad_pilot_fields(const grid_dims_t *d, const float *pilot_radiance, int smooth_radius,
                    float *lum, float *grad, bk_error_t *err);

/* The automatic thresholds from the pilot's own statistics, over the
 * "reached" voxels (pilot radiance > 0) that matter (scattering[v] > 0 when
 * scattering is not NULL: radiance where nothing scatters is never seen):
 *   gradient  = max(P90(|∇Y|), 4 * median(|∇Y|))
 *   luminance = 0.1 * median(Y)
 * (Y the smoothed pilot luminance). Both scale with the light, so no scene
 * needs tuning. With no reached voxel both are 0 and nothing is selected by
 * gradient. stats may be NULL. */
int ad_auto_thresholds(const grid_dims_t *d, const float *pilot_radiance, const float *scattering,
                       int smooth_radius, float *grad_thr, float *lum_thr,
                       ad_select_stats_t *stats, bk_error_t *err);

/* selected[v] = AD_SEL_GRADIENT when |∇Y| > gradient threshold, | AD_SEL_SHADOW
 * when Y < luminance threshold, for voxels that matter (scattering as above);
 * 0 elsewhere. Negative thresholds in opt are computed by ad_auto_thresholds.
 * stats (may be NULL) reports the thresholds used and the counts. */
int ad_select_voxels(const grid_dims_t *d, const float *pilot_radiance, const float *scattering,
                     const ad_select_opts_t *opt, uint8_t *selected, ad_select_stats_t *stats,
                     bk_error_t *err);

/* One light's sampling PDF over the AD_CELLS_X x AD_CELLS_Y cells. */
typedef struct ad_pdf {
  int nx, ny;                 /* AD_CELLS_X, AD_CELLS_Y */
  float floor_fraction;       /* every cell has pdf >= this */
  float cell_pdf[AD_CELLS];   /* density of each cell w.r.t. uniform (mean 1), as the warp reports it */
  float table[AD_TABLE_FLOATS(AD_CELLS_X, AD_CELLS_Y)]; /* what ad_pdf_warp reads */
  double importance[AD_CELLS]; /* share of the selected voxels each cell reaches */
  size_t selected_reached;    /* selected voxels with origin data */
} ad_pdf_t;

/* Builds the PDF of one light from its origin masks (`voxels` entries: the
 * light's block, origin + ad_origin_index(0, light, voxels)) and the
 * selection. Each selected voxel with mask m spreads an importance of 1 evenly
 * over the popcount(m) cells that reached it, so a voxel every cell reaches
 * favours none; then
 *   pdf(c) = floor + (1 - floor) * AD_CELLS * importance(c) / sum(importance)
 * a mixture with the uniform density (defensive sampling): pdf >= floor, so
 * weights stay <= 1/floor. No selected voxel with origin data: uniform.
 * floor_fraction must be in (0, 1]. */
int ad_build_pdf(const uint64_t *origin_masks, const uint8_t *selected, size_t voxels,
                 float floor_fraction, ad_pdf_t *pdf, bk_error_t *err);

/* The general form: a table (AD_TABLE_FLOATS(nx, ny) floats) from
 * non-negative cell weights (nx * ny, row major, cell = col + nx * row), with
 * the same floor mixture; cell_pdf (may be NULL) receives the densities the
 * warp will report. All-zero weights give the uniform density. */
int ad_pdf_from_weights(const double *weights, int nx, int ny, float floor_fraction,
                        float *table, float *cell_pdf, bk_error_t *err);

/* Number of voxels in the integer sphere |d|^2 <= r^2 (1, 7, 33, 123, ...). */
int ad_sphere_size(int r);

/* Reconstruction filter on the host (threads over z slices), the reference
 * the OpenCL path is tested against. radiance: 3 floats per voxel; count,
 * mean_weight: one per voxel (mean of w = 1/pdf, see above); alpha >= 0;
 * max_radius in [0, AD_FILTER_MAX_RADIUS]. out_radiance (3 per voxel, must
 * not alias radiance) gets the filtered radiance; out_radius (NULL: not
 * wanted) the radius used per voxel, in voxels. */
int ad_filter_host(const grid_dims_t *d, const float *radiance, const uint32_t *count,
                   const float *mean_weight, float alpha, int max_radius, float *out_radiance,
                   float *out_radius, bk_error_t *err);

/* The same on the OpenCL device (kernels/filter.cl): uploads, runs, reads
 * back. Same arguments, same results up to float rounding. */
int ad_filter_cl(clh_context_t *cl, const grid_dims_t *d, const float *radiance,
                 const uint32_t *count, const float *mean_weight, float alpha, int max_radius,
                 float *out_radiance, float *out_radius, bk_error_t *err);

/* For a pipeline that keeps the grids on the device: enqueues the filter on
 * existing buffers (rgb, out_rgb: 3 floats per voxel; count: uint per voxel;
 * mean_weight, out_radius: float per voxel; out_radius may be NULL) and waits.
 * `program` is kernels/filter.cl from clh_build, or NULL to build it here. */
int ad_filter_cl_buffers(clh_context_t *cl, cl_program program, const grid_dims_t *d, cl_mem rgb,
                         cl_mem count, cl_mem mean_weight, float alpha, int max_radius,
                         cl_mem out_rgb, cl_mem out_radius, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
