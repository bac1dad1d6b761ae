/* batches.h: the reference march in independent batches, with its error
 * measured as it goes (error_est.h) and steered by a target or a time budget.
 *
 * Batch b of a bake is a Hammersley set of n_b photons per the usual light
 * shares, with Cranley–Patterson rotations hashed from (seed, light, b)
 * (ph_prepare_batch); batch 0 is the set an unbatched bake of n_b photons
 * traces, so `photons.batches` 1 reproduces such a bake bit for bit. Each
 * batch carries the lights' whole power, so each is a whole estimate; the
 * fixed-point sums of all batches are exact and order-free, and the result
 * is their sum divided by the number of batches. A contiguous group of whole
 * batches can therefore be traced alone (a photon shard) and its sums added
 * to the others' later; the only shared choice is the fixed-point scale
 * (pm_scale_batches with the same cap).
 *
 * Modes: fixed (photons.count split into photons.batches batches);
 * target (photons.target_error E: a pilot of BT_MIN_BATCHES small batches,
 * then, from its noise, batches of a planned size added until ε̂ <= E, at
 * least BT_MIN_BATCHES; the pilot is dropped when the size changes, so the
 * batches in the result are equal; plan_batches in batches.c); budget (photons.time_budget_s S:
 * batches added while the next one, at the mean time per photon so far, ends
 * within S seconds of the march's start). Target and budget combine: the
 * first to stop wins. Target mode also chooses the integrator and step
 * (choose_integrator in batches.c) from the twins' bias estimates. */
#ifndef BAKER_BATCHES_H
#define BAKER_BATCHES_H

#include "clhost.h"
#include "error_est.h"
#include "march.h"
#include "scene.h"
#include "voxelize.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BT_MIN_BATCHES 2  /* open-ended modes stop no earlier (as few as a fixed bake) */
/* Open-ended modes stop here at the latest: the fixed-point scale is set for
 * this many batches (a deposit of one photon across one voxel is then still
 * about 2^62 / (4096 n_b path bound) quanta, thousands at 128^3). */
#define BT_MAX_OPEN_BATCHES 4096
/* Target mode's pilot: photons.count / photons.batches photons in
 * BT_MIN_BATCHES batches, this many times smaller than a batch. */
#define BT_PILOT_SPLIT 4
/* Target mode's plan: the noise of B rotated Hammersley batches of n photons
 * falls as n^(-rate/2) at fixed B (1: plain Monte Carlo; measured about 1.8
 * on the sphere scene at 128^3), aimed this factor below the target. */
#define BT_QMC_RATE 1.8
#define BT_PLAN_MARGIN 1.05
/* Target mode with bt_options_t.target_terms: a batch's check is made when
 * the last one's ratio predicts the target within this factor. */
#define BT_WRITTEN_SLACK 1.15
/* ... and no sooner than at this many times the last one's batch count. */
#define BT_WRITTEN_SPACING 1.25
#define BT_TWIN_BATCHES 4 /* twin batches behind the step term */
/* Twin photons: this fraction of the bake's photon count over all twin
 * batches (at least BT_TWIN_MIN per batch). */
#define BT_TWIN_FRACTION (1.0 / 64.0)
#define BT_TWIN_MIN 1024u
/* The open modes size their twins as if this many batches were traced: a
 * target's choice of integrator rests on the twins' bias, which fewer
 * twin photons (2 batches' share) made too noisy to choose by. */
#define BT_OPEN_TWIN_BATCHES 4
/* The truth's integrator: RK4 at this step (voxels). */
#define BT_TRUTH_STEP 0.125f

/* Whether a bake returns each voxel's own spread, which needs more batches
 * (scene_batches): --error-grid, except in a shard (which estimates nothing). */
static inline int bt_per_voxel(int error_grid, int shard_count) {
  return error_grid && !shard_count;
}

typedef struct bt_options {
  int error_grid; /* keep every voxel's statistics and return radiance_error */
  /* A photon shard (baker/shard.h): share shard_index of shard_count of
   * every batch is traced (pm_share_range), no error is estimated (the
   * spread needs every shard's batches), and the raw sums go to *sums
   * instead of radiance. 0: the whole bake. */
  int shard_index, shard_count;
  pm_sums_t *sums;
  /* the march's fields kept from the frame before (march.h); NULL: built */
  pm_field_cache_t *fields;
  /* bt_march on a setup with sampling tables (the adaptive pipeline): */
  int halves;             /* keep half A's luminance sum (res.half_a) */
  double w_max;           /* the largest photon weight (0: 1), for the fixed-point scale */
  uint64_t photon_limit;  /* the most photons of all batches together (0: no limit) */
  double t_start;         /* bk_now_ms() when the bake's time budget began (0: at the march) */
  /* Called after every main batch but the last, before the next is loaded,
   * with the batches so far (`done`) and the lattice tracker: may rewrite
   * the sampling tables the setup points to (the next batch uploads them).
   * NULL: none. */
  int (*retable)(void *ctx, int done, const ee_tracker_t *t, bk_error_t *err);
  void *retable_ctx;
  /* Target mode, when the grid written is not the raw mean (the adaptive
   * filter): called after every main batch from the second with the sums
   * of the `done` batches so far and a copy of half A's luminance sum as
   * the bake would end with it (NULL without halves; the callee may write
   * over it); sets t->noise, t->filter and t->estimate to those of the grid
   * that would be written, which the stop then uses (the plan after the
   * pilot keeps the raw mean's). NULL: the raw mean's. */
  int (*target_terms)(void *ctx, int done, const uint64_t *acc, float *half_a, ee_terms_t *t,
                      bk_error_t *err);
  void *target_ctx;
  /* Not NULL: bt_bake allocates the radiance grid here (its radiance
   * argument unused) after the march, once the march's fields are freed, so
   * the two never take memory together (docs/memory.md), with
   * res.radiance_channels floats per voxel. */
  float **radiance_out;
  /* Optional: called once the march's fields are built, before its sums
   * take memory: the volume's n is read no more by the march then
   * (bake.c packs it into bricks there). */
  void (*fields_built)(void *ctx);
  void *fields_built_ctx;
} bt_options_t;

typedef struct bt_result {
  ee_terms_t terms;
  int batches;         /* batches traced */
  uint64_t batch_photons;
  double ms_twin, ms_track; /* the step twin; the per-batch statistics and error terms */
  float *error_grid;   /* opts.error_grid and >= 2 batches: the caller frees */
  float *flux, *uncollided; /* some g != 0 (not a shard): pm_to_flux's grids; the caller frees */
  int camera;               /* uncollided also holds radiance_camera (pm_uncollided_floats) */
  int budget_short;    /* the time budget ended the bake before 2 batches */
  int target_missed;   /* the target was not reached (batch cap or budget) */
  integrator_t integrator; /* what marched: the scene's, or target mode's choice */
  float step;
  int step_exact;          /* the step needs no twin */
  double ms_march;         /* the batches' tracing and the sums made radiance, not the
                            * twins or the statistics (ms_twin, ms_track) */
  /* bt_march with opts.error_grid: every voxel's statistics (the caller
   * frees them with ee_tracker_free) */
  ee_tracker_t full;
  /* opts.halves: per voxel the luminance sum (one batch's units) of half
   * A (ceil(B/2) of the batches: the first in fixed mode, the
   * even-numbered in the open ones; all of them sum to B times the mean);
   * the caller frees it */
  float *half_a;
  int radiance_channels;   /* floats per voxel of the radiance written: 3, or 1
                            * when bt_bake allocated it for grey light */
} bt_result_t;

/* The march stage in batches (pm_bake's place in the pipeline): radiance as
 * pm_bake writes it, and the error. Timings get "photon marching" and
 * "error estimate" rows. */
int bt_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol, const bt_options_t *o,
            float *radiance, bt_result_t *res, pm_stats_t *stats, bk_timings_t *timings,
            bk_error_t *err);

/* The batches on a setup already prepared (reference mode, or sampling
 * tables: pm_sample_tables with total bt_photons_at_most): sets its
 * fixed-point scale for the batches, marches into acc (pm_acc_count(s)
 * counters, zeroed) and divides s->to_radiance by the batches traced, so
 * that pm_to_radiance and pm_unpack_weights of acc give the mean. No
 * timing rows (bt_report makes bt_bake's). */
int bt_march(clh_context_t *cl, const scene_t *scene, pm_setup_t *s, const bt_options_t *o,
             uint64_t *acc, bt_result_t *res, pm_stats_t *stats, bk_error_t *err);
/* The most photons the batches of a bake may trace, all together. */
uint64_t bt_photons_at_most(const scene_t *scene, const bt_options_t *o);
/* The "photon marching" and "error estimate" rows of a reference bake. */
void bt_report(const bt_result_t *res, const pm_stats_t *st, bk_timings_t *timings);

#ifdef __cplusplus
}
#endif
#endif
