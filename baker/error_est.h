/* error_est.h: the error of a bake, estimated while it runs (docs/error.md).
 *
 * Definitions (DESIGN.md §8): truth T is the radiance of the same grid with
 * unlimited photons and RK4 at step 1/8 voxel; lit voxels are those whose
 * luminance (Rec. 709) is at least 2% of the 99.9th percentile; the error ε
 * is sqrt(mean_lit (L − T)²) / mean_lit T. Its two parts, estimated without
 * the truth:
 *
 *  noise  the photons are traced in B independent batches (rotated
 *         Hammersley sets, baker/batches.h), each a whole estimate x_b; the
 *         bake writes their mean, whose variance per voxel is
 *         s² / B with s² = Σ (x_b − x̄)² / (B − 1). ε_noise² =
 *         mean_lit(s²/B) / mean_lit(x̄)².
 *  step   the integrator's bias: T twin batches of photons traced twice from
 *         the same starting points, with the bake's integrator and with the
 *         truth's (RK4, 1/8 voxel); per voxel d_t their difference. The
 *         mean d̄ estimates the bias plus noise of its own, removed with the
 *         spread of d_t: ε_step² = max(0, mean_lit(d̄² − var(d̄))) /
 *         mean_lit(x̄)².
 *  ε̂ = sqrt(ε_noise² + ε_step²).
 *
 * What is kept per voxel: by default only the voxels with even (i, j, k),
 * an eighth of the grid, a systematic sample on which the lit set, the
 * percentile and the means are taken (8 bytes per tracked voxel: 1 byte per
 * voxel, 3 more while the twins run); the error grid has a second tracker
 * over every voxel (8 bytes per voxel, 4 of which become the
 * `radiance_error` grid). */
#ifndef BAKER_ERROR_EST_H
#define BAKER_ERROR_EST_H

#include <stddef.h>
#include <stdint.h>

#include "march.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Luminance weights of linear Rec. 709 RGB. */
#define EE_LUM_R 0.2126
#define EE_LUM_G 0.7152
#define EE_LUM_B 0.0722
/* Lit voxels: luminance >= this fraction of the 99.9th percentile. */
#define EE_LIT_FRACTION 0.02
#define EE_LIT_PERCENTILE 0.999
/* A term that was not measured (one batch: no spread). */
#define EE_UNKNOWN (-1.0)

typedef struct ee_terms {
  double estimate, noise, step; /* ε̂, ε_noise, ε_step; EE_UNKNOWN when not measured */
  /* adaptive mode with its filter: the filter's bias (then noise is the
   * filtered estimate's); 0 without a filter */
  double filter;
  int batches;                  /* B behind the noise term */
  int twin_batches;             /* T behind the step term (0: exact, no twin needed) */
  uint64_t twin_photons;        /* photons per twin batch */
} ee_terms_t;

typedef struct ee_tracker {
  int shift;          /* 1: voxels with even (i, j, k); 0: every voxel */
  int mx, my, mz;     /* tracked lattice */
  size_t count;
  float *prev;        /* per tracked voxel: the luminance sum of the batches so far */
  float *sumsq;       /* ... and the sum of the squares of each batch's luminance */
  int touched;        /* prev and sumsq resident (at the first batch, after the twins) */
  int twins;          /* twin batches recorded */
  float *dsum, *dsumsq; /* twin: sums of d_t and d_t² (NULL until a twin runs) */
  float *twin_tmp;    /* twin: the truth integrator's luminance of the twin in flight */
  double lum[3];      /* luminance per accumulator quantum, per channel (one batch) */
} ee_tracker_t;

/* Entry k of a tracked lattice (every 2^shift-th voxel along each axis,
 * mx per row and mx × my per plane, x fastest): its voxel's coordinates.
 * The one decoding of the layout, for every reader of a tracker's arrays. */
static inline void ee_lattice_ijk(size_t k, size_t mx, size_t my, int shift, int ijk[3]) {
  ijk[0] = (int)(k % mx) << shift;
  ijk[1] = (int)(k / mx % my) << shift;
  ijk[2] = (int)(k / (mx * my)) << shift;
}
/* The even lattice (x, y, z even: ((nx + 1) / 2) × ((ny + 1) / 2) ×
 * ((nz + 1) / 2) voxels, x fastest): its k-th voxel's index in the grid. */
size_t ee_lattice_voxel(const grid_dims_t *d, size_t k);
/* out[k] = grid's value at the even lattice's entry k, for every k (the
 * lattice walked row by row, not divided out per entry); grid holds ch = 1
 * float per voxel, or ch = 3 (RGB), whose luminance is taken. */
void ee_lattice_gather(const grid_dims_t *d, const float *grid, int ch, float *out);
/* Tracks every voxel (all = 1, for the error grid) or the even lattice. */
int ee_tracker_init(ee_tracker_t *t, const pm_setup_t *s, int all, bk_error_t *err);
void ee_tracker_free(ee_tracker_t *t);
/* After a batch: acc holds the sums of `done` batches. */
void ee_after_batch(ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc);
/* The luminance of acc (one batch's sums) on the tracked voxels into out. */
void ee_read(const ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc, float *out);
/* Twin: `fine` holds the truth integrator's luminance, acc the bake
 * integrator's sums of the same photons. */
int ee_twin_add(ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc, const float *fine,
                bk_error_t *err);
/* Forget the twins recorded (another integrator is measured next). */
void ee_twin_reset(ee_tracker_t *t);
/* The twins recorded, copied into *keep (allocated on the first call, the
 * caller frees it) and put back: target mode measures several integrators
 * and keeps the chosen one's twins without tracing them again. */
int ee_twin_save(const ee_tracker_t *t, float **keep, bk_error_t *err);
void ee_twin_restore(ee_tracker_t *t, const float *keep, int twins);
/* Forget the batches recorded (target mode drops its pilot batches and
 * starts over with larger ones); the twins are kept. */
void ee_batches_reset(ee_tracker_t *t);
/* Per tracked voxel the spread s² between the `batches` batches where the
 * voxel is lit, 0 elsewhere (the adaptive loop's allocation). */
void ee_lit_spread(const ee_tracker_t *t, int batches, float *out);
/* Adds sign times the luminance of acc (sums of batches, in one batch's
 * units) of every voxel of the grid to out (s->voxels floats). */
void ee_add_lum(const ee_tracker_t *t, const pm_setup_t *s, const uint64_t *acc, float sign,
                float *out);
/* The terms of a filtered estimate (adaptive mode), per voxel of n: all is
 * the luminance sum of the B batches, half_a that of half A (ceil(B/2) of
 * them, nA; half B the rest, nB), f the filtered mean's luminance, wf the
 * filtered grid filtered again at the same radii, fa and fb the halves'
 * means filtered the same way. With x̄ the raw mean and κ =
 * (1/B) / (1/nA + 1/nB): noise² = mean_lit κ (fa − fb)² / mean_lit(x̄)²;
 * bias² = mean_lit (wf − f)² / mean_lit(x̄)², or, with wf NULL (a filter
 * whose radii do not depend on the noise), max(0, mean_lit(d² − var d)) /
 * mean_lit(x̄)² with d = f − x̄, var(d) ≈ κ ((fa − xa) − (fb − xb))²
 * (docs/error.md, "The filter"). */
void ee_filter_terms(size_t n, int batches, const float *all, const float *half_a,
                     const float *f, const float *wf, const float *fa, const float *fb,
                     double *noise, double *bias);
/* The step term of the twins recorded, on the lit set and mean of the
 * midpoint of the truth integrator's luminance `fine` (one array of count
 * per twin) and the bake integrator's: for choosing an integrator before
 * the bake's own batches exist. */
double ee_twin_step(const ee_tracker_t *t, const float *fine);
/* The terms after `batches` batches (noise EE_UNKNOWN below 2; step 0 when
 * step_exact, EE_UNKNOWN without twins). */
void ee_terms(const ee_tracker_t *t, int batches, int step_exact, ee_terms_t *out);
/* Every voxel tracked: the standard error of the luminance of the mean of
 * `batches` batches, written over sumsq (which the grid then owns: the
 * tracker forgets it). NULL when not every voxel is tracked or B < 2. */
float *ee_take_error_grid(ee_tracker_t *t, int batches);

/* ε of a grid against a truth grid (both 3 floats per voxel), by the
 * definitions above on every voxel: for tests and benchmarks. */
double ee_true_error(const float *radiance, const float *truth, size_t voxels);

#ifdef __cplusplus
}
#endif
#endif
