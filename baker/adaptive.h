/* adaptive.h: the adaptive pipeline (DESIGN.md §3 stage 6): a pilot march,
 * voxel selection and a sampling PDF per light (phase 1), a march of
 * photons drawn from that PDF with weights 1/(N pdf) (phase 2), and the
 * reconstruction filter. The selection and PDFs are adaptive_pdf.c, the
 * filter adaptive_filter.c, and ad_bake (adaptive.c) runs it all; the march
 * is baker/march.c's (modes PM_MODE_ORIGINS and PM_MODE_TABLES of
 * kernels/photon_march.h) on one prepared setup, and the math shared with the
 * kernels is in kernels/adaptive_filter.h (cells, origin masks, the PDF warp, the
 * filter).
 *
 * What ad_bake does, per frame:
 *  1. Pilot march, uniform Hammersley points, `adaptive.pilot` photons (~4000)
 *     through the full-resolution n field, depositing into coarse cells of
 *     2^s voxels a side, s the smallest with the longest axis >> s <=
 *     AD_PILOT_CELLS (4^3 voxels at 128^3): 4000 photon tracks are a few per
 *     cell there, where at full resolution most voxels would see none and
 *     every gradient would be noise. It yields the pilot radiance per cell
 *     and the origin masks: one uint64_t per cell per light, light major
 *     (ld_origin_index), bit c set when a pilot photon from light-domain cell
 *     c = ld_cell_of(a, b) crossed the cell (ld_origin_mark). The march
 *     also counts each light-domain cell's photons and their work
 *     (pm_setup_t.cell_work): what a photon from that cell costs.
 *  2. ad_select_voxels on the pilot cells: those whose luminance gradient
 *     exceeds a threshold (edges, caustics) or whose luminance is below one
 *     (shadows). Thresholds are explicit or automatic (the rule is
 *     documented at ad_select_voxels).
 *  3. ad_build_pdf, per light: a 2D PDF over the light's 8x8 cells
 *     that favours the cells whose photons reached selected cells, each
 *     selected cell weighing by its pilot luminance gradient (by default,
 *     AD_IMPORTANCE_GRADIENT: an edge that is bright matters more to the
 *     error than a faint one; measured on the sphere scene it lowers the
 *     error at equal photons by 10% against 1 per cell), divided by the
 *     square root of the cell's photon cost (ad_cell_costs: fewer photons
 *     where each costs more, docs/bench.md "Pilot tables weighed by march
 *     work"), mixed with the uniform density so that every cell keeps
 *     pdf >= floor_fraction (1/2: the Hammersley points converge about as
 *     1/N, so a region sampled at density p has 1/p times the error; 1/4
 *     cost more in the sparse fog than it gained at the edges).
 *  4. Main march, in the batches of the reference mode (bt_march,
 *     batches.h; each batch a rotated Hammersley set, a whole estimate, so
 *     the error is measured as there): photon k of N takes its Hammersley point u, warps it with
 *     ld_pdf_warp(table, 8, 8, u) -> (x, pdf), generates the photon from x and
 *     multiplies its power (light power / N) by w = 1/pdf. Per voxel it keeps
 *     the photon count and the sum of w over the photons that entered it; the
 *     mean weight w_mean = sum / count (0 where count is 0) is the
 *     `photon_weight` grid and the count the `photon_count` grid. w_mean is 1
 *     for uniform sampling, < 1 where the PDF concentrated photons.
 *     One packed atomic per voxel entry (kernels/photon_march.h) makes this march
 *     about 1.2x the reference's cost per photon (bench_adaptive).
 *     With opts.retable the tables are rebuilt after every batch from the
 *     measured spread (ad_loop_t, adaptive_loop.c).
 *  5. The filter (ad_filter_host / ad_filter_cl) on the radiance with count
 *     and w_mean: radius min(alpha * w_mean, centre-surround radius) in half
 *     voxels, capped at AD_DEFAULT_MAX_RADIUS, see kernels/adaptive_filter.h. A grey
 *     march (one channel) is filtered as one channel and coloured after. The
 *     radius grid is a debug output.
 *  6. The error (docs/error.md "Adaptive mode"): the batches' noise and
 *     step terms, and with the filter its noise and bias from the two
 *     halves of the batches filtered at the filter's radii (ad_filter_fixed_lattice).
 * Timing rows: "octree", "pilot marching", "photon distribution" (selection
 * and PDFs), "photon generation" (light set-up; the photons themselves are
 * made in the kernel), "photon marching" (with the unpacking of the
 * accumulators), "filtering", "error estimate" (twins, batch statistics,
 * the filter's terms).
 *
 * Arrays are dense, x-fastest (grid.h); the caller allocates outputs. */
#ifndef BAKER_ADAPTIVE_H
#define BAKER_ADAPTIVE_H

#include <stdint.h>

#include "batches.h"
#include "clhost.h"
#include "base/grid.h"
#include "kernels/adaptive_filter.h"
#include "kernels/light_domain.h"
#include "march.h"
#include "scene.h"
#include "voxelize.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Automatic thresholds (ad_select_voxels; reasons in adaptive_pdf.c). */
#define AD_AUTO_GRADIENT_PERCENTILE 0.90f /* at most the top 10% of reached voxels */
#define AD_AUTO_GRADIENT_OUTLIER 4.0f     /* and at least 4 median gradients */
#define AD_AUTO_SHADOW_FRACTION 0.1f      /* shadow: a decade below the median */
#define AD_DEFAULT_SMOOTH_RADIUS 1        /* box pre-smoothing of the pilot, cells */
#define AD_DEFAULT_FLOOR 0.5f             /* pdf >= 1/2: weights <= 2 */
#define AD_DEFAULT_MAX_RADIUS 1.0f        /* voxels (bench_adaptive: 2 gains 2% for twice the cost) */
#define AD_PILOT_CELLS 32                 /* the pilot's coarse grid, cells along the longest axis */
#define AD_DEFAULT_NOISE_K 2.0f           /* filter: first step within 2 lum / count */

/* What each selected pilot cell adds to the PDF (spread over the light
 * cells that reached it). */
#define AD_IMPORTANCE_UNIT 0        /* 1 */
#define AD_IMPORTANCE_GRADIENT 1    /* its luminance gradient */
#define AD_IMPORTANCE_LUMINANCE 2   /* its luminance */
#define AD_IMPORTANCE_GRADIENT_23 3 /* gradient^(2/3) */

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

/* selected[v] = AD_SEL_GRADIENT when |∇Y| > gradient threshold, | AD_SEL_SHADOW
 * when Y < luminance threshold (Y and |∇Y| from ad_pilot_fields), for the
 * voxels that matter (scattering[v] > 0 when scattering is not NULL: radiance
 * where nothing scatters is never seen); 0 elsewhere. A negative threshold in
 * opt is automatic, from the pilot's own statistics over the "reached"
 * voxels (pilot radiance > 0) that matter:
 *   gradient  = max(P90(|∇Y|), 4 * median(|∇Y|))
 *   luminance = 0.1 * median(Y)
 * Both scale with the light, so no scene needs tuning. With no reached voxel
 * both are 0 and nothing is selected by gradient. stats (may be NULL)
 * reports the thresholds used and the counts. */
int ad_select_voxels(const grid_dims_t *d, const float *pilot_radiance, const float *scattering,
                     const ad_select_opts_t *opt, uint8_t *selected, ad_select_stats_t *stats,
                     bk_error_t *err);

/* One light's sampling PDF over the LD_CELLS_X x LD_CELLS_Y cells. */
typedef struct ad_pdf {
  int nx, ny;                 /* LD_CELLS_X, LD_CELLS_Y */
  float floor_fraction;       /* every cell has pdf >= this */
  float cell_pdf[LD_CELLS];   /* density of each cell w.r.t. uniform (mean 1), as the warp reports it */
  float table[LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y)]; /* what ld_pdf_warp reads */
  double importance[LD_CELLS]; /* share of the selected voxels each cell reaches */
  size_t selected_reached;    /* selected voxels with origin data */
} ad_pdf_t;

/* Builds the PDF of one light from its origin masks (`voxels` entries: the
 * light's block, origin + ld_origin_index(0, light, voxels)) and the
 * selection. Each selected voxel with mask m spreads an importance of
 * voxel_weight[v] (voxel_weight NULL: 1) evenly over the popcount(m) cells
 * that reached it, so a voxel every cell reaches favours none; then
 *   pdf(c) = floor + (1 - floor) * LD_CELLS * w(c) / sum(w),
 *   w(c) = importance(c) / sqrt(cost(c))
 * a mixture with the uniform density (defensive sampling): pdf >= floor, so
 * weights stay <= 1/floor. No selected voxel with origin data: uniform.
 * cost (LD_CELLS, ad_cell_costs; NULL: all equal) is a photon's march work
 * from each cell: for a fixed march time the variance is least with photons
 * in proportion to importance / sqrt(cost) (importance read as the spread
 * a cell's photons reduce, Neyman allocation with costs).
 * floor_fraction must be in (0, 1]. */
int ad_build_pdf(const uint64_t *origin_masks, const uint8_t *selected, const float *voxel_weight,
                 const double *cost, size_t voxels, float floor_fraction, ad_pdf_t *pdf,
                 bk_error_t *err);
/* One light's mean march work per photon in each light-domain cell
 * (cost[LD_CELLS], at least 1), from its block of pm_setup_t.cell_work; a
 * cell without photons gets the light's mean. */
void ad_cell_costs(const uint64_t *cell_work, double *cost);

/* The general form: a table (LD_TABLE_FLOATS(nx, ny) floats) from
 * non-negative cell weights (nx * ny, row major, cell = col + nx * row), with
 * the same floor mixture; cell_pdf (may be NULL) receives the densities the
 * warp will report. All-zero weights give the uniform density. */
int ad_pdf_from_weights(const double *weights, int nx, int ny, float floor_fraction,
                        float *table, float *cell_pdf, bk_error_t *err);

/* Reconstruction filter on the host (z slices on every core), the reference
 * the OpenCL path is tested against. radiance: `channels` (1 or 3) floats
 * per voxel (1: a grey value, its own luminance); count, mean_weight: one
 * float per voxel (mean of w = 1/pdf, see above); alpha >= 0; noise_k: the
 * first step's noise scale (< 0: no test, the slides' rule); levels: the
 * largest level, twice the largest radius in voxels, in
 * [0, AD_FILTER_MAX_LEVEL] (kernels/adaptive_filter.h). out_radiance (channels per
 * voxel, must not alias radiance) gets the filtered radiance; out_radius
 * (NULL: not wanted) the radius used per voxel, in voxels (multiples of
 * 1/2). Needs `levels` grids of `channels` floats of scratch. */
int ad_filter_host(const grid_dims_t *d, int channels, const float *radiance, const float *count,
                   const float *mean_weight, float alpha, float noise_k, int levels,
                   float *out_radiance, float *out_radius, bk_error_t *err);

/* The same on the OpenCL device (kernels/filter.cl): two launches, in place
 * on the host arrays on a CPU device, uploads and read-backs on a GPU. Same
 * arguments, same results up to float rounding. */
int ad_filter_cl(clh_context_t *cl, const grid_dims_t *d, int channels, const float *radiance,
                 const float *count, const float *mean_weight, float alpha, float noise_k,
                 int levels, float *out_radiance, float *out_radius, bk_error_t *err);

/* The filter's means at given radii (radius: voxels per voxel, as the
 * filter's out_radius; level round(2 r), at most `levels`) of `count`
 * one-channel grids in[i], at the even lattice only (ee_lattice_voxel: the
 * voxels the error estimate samples) into out[i]: a linear map, so the error
 * estimate can filter the two halves of the batches exactly as the whole
 * was (ad_bake), each value bit for bit what the whole grid's filter gives
 * there, at about a third of its passes' work. On the host. */
int ad_filter_fixed_lattice(const grid_dims_t *d, const float *const *in, int count,
                            const float *radius, int levels, float *const *out,
                            bk_error_t *err);

/* --- the allocation loop (adaptive_loop.c) --------------------------------- */

/* The sampling tables rebuilt after every batch from the measured noise:
 * density moves toward the light-domain cells whose photons reach the
 * voxels with the most remaining error per unit of march work (the method
 * is at the top of adaptive_loop.c). */
typedef struct ad_loop {
  int shift;              /* pilot cells of 2^shift voxels */
  grid_dims_t cd;         /* the pilot's coarse grid */
  size_t cv;
  const uint64_t *masks;  /* the pilot's origin masks, per pilot light */
  int lights;             /* the main march's */
  int pilot_of[SCENE_MAX_LIGHTS]; /* each light's pilot light (-1: none) */
  float *tables;          /* the march's tables, rewritten in place */
  float floor;
  float pdf[SCENE_MAX_LIGHTS][LD_CELLS]; /* the densities in use */
  const uint64_t *work;   /* the pilot's cell_work, per pilot light (march.h) */
  double *cellvar;        /* per pilot cell: the lit voxels' spread */
  int rebuilt;            /* tables rebuilt so far */
} ad_loop_t;
int ad_loop_init(ad_loop_t *L, int lights, int shift, const grid_dims_t *cd,
                 const uint64_t *masks, const uint64_t *work, const int *pilot_of, float *tables,
                 float floor_fraction, bk_error_t *err);
/* bt_options_t.retable: after `done` batches, from the tracker t. */
int ad_loop_retable(void *ctx, int done, const ee_tracker_t *t, bk_error_t *err);
void ad_loop_free(ad_loop_t *L);

/* --- the whole stage --------------------------------------------------------- */

typedef struct ad_bake_opts {
  int filter;           /* 0: no reconstruction (--no-filter: the raw, unbiased estimate) */
  float max_radius;     /* filter radius cap, voxels, 0..AD_FILTER_MAX_LEVEL / 2 */
  int smooth_radius;    /* pilot pre-smoothing, cells (ad_select_opts_t) */
  float floor_fraction; /* PDF floor, (0, 1] */
  int pilot_cells;      /* the pilot grid's cells along the longest axis */
  float noise_k;        /* filter: the first step's noise allowance (kernels/adaptive_filter.h) */
  int importance;       /* AD_IMPORTANCE_*: what a selected cell spreads over its origins */
  /* A photon shard (baker/shard.h): when sums is not NULL the pilot and the
   * PDF are made as always (they are deterministic, so every shard gets the
   * same tables), the weighted march traces share shard_index of
   * shard_count of every batch (batches.h), and its raw sums go to *sums
   * instead of becoming radiance: ad_finish does that after the shards are
   * added up. */
  pm_sums_t *sums;
  int shard_index, shard_count; /* the shard's share of every batch (batches.h) */
  int error_grid;       /* --error-grid: stats.error.error_grid, the raw estimate's standard error */
  double t_start;       /* bk_now_ms() when the bake began, for photons.time_budget_s (0: ad_bake's start) */
  int retable;          /* rebuild the tables after every batch (ad_loop_t); not with shards */
  /* the march's fields kept from the frame before (march.h); NULL: built */
  pm_field_cache_t *fields;
} ad_bake_opts_t;
void ad_bake_defaults(ad_bake_opts_t *o);

typedef struct ad_stats {
  pm_stats_t pilot, march;   /* phase 1 and phase 2 photons */
  int pilot_photons;         /* adaptive.pilot */
  int coarse_shift;          /* pilot cells of 2^shift voxels */
  ad_select_stats_t select;  /* thresholds used and selected cells */
  float pdf_min, pdf_max;    /* over every light's cells */
  int filtered;
  float max_radius;          /* voxels, 0 when not filtered */
  double ms_octree, ms_pilot, ms_distribution, ms_generate, ms_march, ms_filter;
  /* the weighted march's batches and the error (error_est.h): with the
   * filter, terms.noise is the filtered estimate's and terms.filter its
   * bias; error.error_grid (opts.error_grid) belongs to the caller; its
   * `full` tracker is freed */
  bt_result_t error;
  double ms_error;           /* the filter's error terms (two more filters) */
  int retabled;              /* opts.retable: tables rebuilt between batches */
} ad_stats_t;

/* The adaptive pipeline in place of pm_bake: scene (photons.count phase-2
 * photons, adaptive.pilot, thresholds, alpha), the voxelized volume; cl NULL
 * runs on the host. Out: radiance (3 floats per voxel), and when not NULL
 * photon_count and photon_weight (1 float per voxel: photons that entered
 * the voxel, their mean weight 1/pdf) and filter_radius (voxels; 0 where the
 * filter is off). opt NULL: ad_bake_defaults. Adds the timing rows "octree",
 * "pilot marching", "photon distribution", "photon generation", "photon
 * marching", "filtering". */
int ad_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol,
            const ad_bake_opts_t *opt, float *radiance, float *photon_count, float *photon_weight,
            float *filter_radius, ad_stats_t *stats, bk_timings_t *timings, bk_error_t *err);

/* What ad_bake does after the weighted march, on sums of it (a merge of
 * photon shards): the photon count and mean weight per voxel, the radiance,
 * and the filter with alpha (the scene's adaptive.alpha) as opt asks. On the
 * host when cl is NULL. stats gets the filter's fields. */
int ad_finish(clh_context_t *cl, const grid_dims_t *dims, const pm_sums_t *sums,
              const ad_bake_opts_t *opt, float alpha, float *radiance, float *photon_count,
              float *photon_weight, float *filter_radius, ad_stats_t *stats, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
