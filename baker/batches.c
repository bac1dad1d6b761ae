/* batches.c: the reference march in batches, its error and when to stop
 * (see batches.h). */
#include "batches.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "integrators.h"

/* The state the batch callbacks share. */
typedef struct bt_run {
  const scene_t *scene;
  const bt_options_t *o;
  pm_setup_t *s;
  ee_tracker_t *tr;        /* the estimate: the even lattice */
  ee_tracker_t *grid;      /* --error-grid: every voxel (NULL otherwise) */
  uint64_t photons;       /* fixed mode: the total; open modes: per batch */
  int batches;            /* fixed mode: B; open modes: 0 */
  int cap;                /* most batches the fixed-point scale allows */
  int first_id;           /* batch ids start here (twins have their own) */
  double t0, t_main, ms_track;
  double target, budget_ms;
  int step_exact;
  ee_terms_t terms;
  float *fine;            /* twin: the truth integrator's luminance per twin batch */
  int twin_phase;         /* 1 truth integrator, 2 bake integrator */
  bk_progress_t prog;
  char label[96];
  int stop_reason;        /* 0 done, 1 target met, 2 budget, 3 cap, 4 the step alone above it */
  int done;               /* main batches traced (those in the result) */
  int pilot;              /* target mode: pilot batches traced, then dropped */
  int pilot_split;        /* target mode without a budget: a pilot, then a plan */
  int planned;            /* target mode: the batch size was planned */
  uint64_t traced;        /* main photons traced, pilot included */
  uint64_t photon_cap;    /* open modes: photons traced at most */
  double cost;            /* twin_cost of the last twin run */
  float *half;            /* opts.halves: half A's luminance sum per voxel */
  double written_ratio;   /* o->target_terms: its error over the raw noise, last time */
  int written_next;       /* o->target_terms: the batch count of the next call, at least */
} bt_run_t;

/* Batch `id`'s lights into run. */
static int load_batch(bt_run_t *x, int id, uint64_t photons, pm_setup_t *run, bk_error_t *err) {
  int rc = ph_prepare_batch(x->scene, &x->s->dims, photons, x->scene->seed, id, &run->lights, err);
  if (rc != BK_OK) return -1;
  if (run->channels == 1) ph_make_grey(&run->lights);
  run->params.photon_total = (bk_uint)run->lights.photons;
  run->params.light_count = (bk_uint)run->lights.count;
  uint64_t first = 0, last = UINT64_MAX; /* a shard: its share of every batch */
  if (x->o->shard_count && id < 0x40000000)
    pm_share_range(run->lights.photons, x->o->shard_index, x->o->shard_count, &first, &last);
  pm_set_range(run, first, last);
  return PM_BATCH_GO;
}

/* Twin batches: traced once with each integrator, each into zeroed sums;
 * acc is zero again at the end. */
static int twin_next(void *ctx, int done, uint64_t *acc, pm_setup_t *run, bk_error_t *err) {
  bt_run_t *x = ctx;
  if (done > 0) {
    float *fine = x->fine + (size_t)(done - 1) * x->tr->count;
    if (x->twin_phase == 1) ee_read(x->tr, run, acc, fine);
    else if (ee_twin_add(x->tr, run, acc, fine, err)) return -1;
  }
  if (done == BT_TWIN_BATCHES) {
    memset(acc, 0, pm_acc_count(run) * sizeof *acc); /* the twins' part of it */
    return 0;
  }
  int rc = load_batch(x, 0x40000000 + done, x->photons, run, err);
  return rc > 0 && done > 0 ? PM_BATCH_GO_ZERO : rc;
}

/* A deterministic price of a twin run (measured time would make target
 * mode's choice, and so its bits, depend on the machine's load): field
 * evaluations (1 per Euler step, 4 per RK4 step) plus voxel deposits. */
static double twin_cost(const pm_stats_t *st, unsigned integ) {
  return (double)pm_work(integ, st->steps, st->voxels);
}

/* The bake's setup for a twin run: uniform photons where the bake draws
 * them from sampling tables. The step bias per voxel is the same whichever
 * unbiased photons measure it, and the adaptive photons, sent through the
 * refracting objects, cost about 1.5x a uniform one (docs/error.md). */
static pm_setup_t twin_setup(const bt_run_t *x) {
  pm_setup_t run = *x->s;
  if (run.params.mode == PM_MODE_TABLES) run.params.mode = PM_MODE_REFERENCE, run.tables = NULL;
  /* the even lattice the tracker reads, packed: 1/8 of the sums to clear,
   * read and (on a GPU) move between batches */
  if (x->tr->shift == 1) pm_deposit_lattice(&run);
  return run;
}

/* The truth integrator's twins, kept in x->fine. acc is zero before and after. */
static int twin_truth(clh_context_t *cl, bt_run_t *x, uint64_t *acc, double *ms, bk_error_t *err) {
  pm_stats_t st;
  memset(&st, 0, sizeof st);
  pm_setup_t truth = twin_setup(x);
  truth.params.integrator = integrator_kind(INTEGRATOR_RK4)->device;
  truth.params.step = BT_TRUTH_STEP;
  x->twin_phase = 1;
  double t0 = bk_now_ms();
  int rc = pm_run_batches(cl, &truth, acc, &st, twin_next, x, err);
  *ms = bk_now_ms() - t0;
  x->cost = twin_cost(&st, truth.params.integrator);
  return rc;
}

/* The same twins with integrator `integ` at `step` into the tracker's step
 * sums (reset first); *ms their time. */
static int twin_with(clh_context_t *cl, bt_run_t *x, uint64_t *acc, unsigned integ, float step,
                     double *ms, bk_error_t *err) {
  pm_stats_t st;
  memset(&st, 0, sizeof st);
  pm_setup_t run = twin_setup(x);
  run.params.integrator = integ;
  run.params.step = step;
  ee_twin_reset(x->tr);
  x->twin_phase = 2;
  double t0 = bk_now_ms();
  int rc = pm_run_batches(cl, &run, acc, &st, twin_next, x, err);
  *ms = bk_now_ms() - t0;
  x->cost = twin_cost(&st, integ);
  return rc;
}

/* Target mode: the integrator and step whose bias leaves room for the noise
 * at the least predicted cost, twin_cost per photon / (E² − ε_step²), among
 * Euler and RK4 at 1/2 and 1/4 voxel and the truth's RK4 1/8 (bias 0).
 * A bias above 0.8 E leaves too little room. A finer step of an integrator
 * costs at least what its coarser step did per photon, so once the best
 * cost is below that, the finer step is not traced. Sets x->s's integrator
 * and step; the tracker keeps the chosen one's twins (copied aside). */
static int choose_integrator(clh_context_t *cl, bt_run_t *x, uint64_t *acc, bk_error_t *err) {
  static const struct { integrator_t i; float step; } cand[] = {
      {INTEGRATOR_EULER, 0.5f}, {INTEGRATOR_EULER, 0.25f}, {INTEGRATOR_RK4, 0.5f},
      {INTEGRATOR_RK4, 0.25f}};
  const double E = x->target;
  int best = -1, rc = BK_OK;
  double best_cost = x->cost / (E * E), ms;
  double floor_of[2] = {0.0, 0.0}; /* per integrator: the least cost of a finer step */
  float *keep = NULL;
  for (int c = 0; c < (int)(sizeof cand / sizeof cand[0]) && !rc; c++) {
    unsigned dev = integrator_kind(cand[c].i)->device;
    const int k = cand[c].i == INTEGRATOR_RK4;
    if (best_cost <= floor_of[k]) continue;
    if ((rc = twin_with(cl, x, acc, dev, cand[c].step, &ms, err))) break;
    floor_of[k] = x->cost / (E * E);
    double st = ee_twin_step(x->tr, x->fine);
    double cost = st >= 0.0 && st <= 0.8 * E ? x->cost / (E * E - st * st) : HUGE_VAL;
    bk_log(2, "target error %g: %s step %g: bias %.4f, twin %.0f ms, relative cost %.3g", E,
           integrator_kind(cand[c].i)->name, (double)cand[c].step, st, ms, cost / best_cost);
    if (cost < best_cost) best_cost = cost, best = c, rc = ee_twin_save(x->tr, &keep, err);
  }
  if (!rc && best < 0) { /* the truth's own integrator */
    x->s->params.integrator = integrator_kind(INTEGRATOR_RK4)->device;
    x->s->params.step = BT_TRUTH_STEP;
    x->step_exact = 1;
  } else if (!rc) {
    x->s->params.integrator = integrator_kind(cand[best].i)->device;
    x->s->params.step = cand[best].step;
    if (keep) ee_twin_restore(x->tr, keep, BT_TWIN_BATCHES);
  }
  free(keep);
  return rc;
}

/* The step term: twins with the truth's integrator, then with the bake's
 * (target mode: with each candidate, choosing one). */
static int run_twin(clh_context_t *cl, bt_run_t *x, uint64_t *acc, bk_error_t *err) {
  double ms_truth, ms;
  x->fine = bk_calloc_touched(x->tr->count * BT_TWIN_BATCHES, sizeof(float),
                              "error estimate: twin", err);
  if (!x->fine) return BK_ERR_RUNTIME;
  int rc = twin_truth(cl, x, acc, &ms_truth, err);
  bk_log(2, "error estimate: twins with the truth's RK4 at %g voxel: %.0f ms",
         (double)BT_TRUTH_STEP, ms_truth);
  if (!rc && x->target > 0.0) rc = choose_integrator(cl, x, acc, err);
  else if (!rc) {
    rc = twin_with(cl, x, acc, x->s->params.integrator, x->s->params.step, &ms, err);
    bk_log(2, "error estimate: twins with the bake's integrator: %.0f ms", ms);
  }
  free(x->fine);
  x->fine = NULL;
  return rc;
}

/* Whether to trace another batch after `done`. */
static int keep_going(bt_run_t *x, int done) {
  if (x->batches) return done < x->batches;
  if (x->target > 0.0 && done >= BT_MIN_BATCHES && x->terms.estimate >= 0.0 &&
      x->terms.estimate <= x->target)
    return x->stop_reason = 1, 0;
  /* more photons do not lower the step's bias: a target below it is never
   * met (twins of few photons can hide the bias when the integrator is
   * chosen; the armadillo at 128³ ran 4096 batches, 66 s, for nothing), so
   * the bake ends once it has the photons a fixed bake would */
  if (x->target > 0.0 && done >= BT_MIN_BATCHES && x->terms.step >= x->target &&
      x->traced >= (uint64_t)x->scene->photon_count)
    return x->stop_reason = 4, 0;
  if (x->budget_ms > 0.0 && done >= 1) {
    double now = bk_now_ms();
    double per = (now - x->t_main) / (double)x->traced * (double)x->photons;
    if (now - x->t0 + per > x->budget_ms) return x->stop_reason = 2, 0;
  }
  if (done >= x->cap || x->traced + x->photons > x->photon_cap) return x->stop_reason = 3, 0;
  return 1;
}

/* The progress line: ε̂ as it falls, and how far along. */
static void show_progress(bt_run_t *x, int done) {
  double frac = 0.0;
  if (x->batches) frac = (double)done / x->batches;
  else if (x->budget_ms > 0.0) frac = (bk_now_ms() - x->t0) / x->budget_ms;
  if (x->target > 0.0 && x->terms.noise > 0.0) {
    double room = x->target * x->target - x->terms.step * x->terms.step;
    double need = room > 0.0 ? done * x->terms.noise * x->terms.noise / room : 1e9;
    double f = done / (need > done ? need : done);
    frac = frac > f ? frac : f;
  }
  if (x->terms.estimate >= 0.0)
    snprintf(x->label, sizeof x->label, "photon marching, error %.4f", x->terms.estimate);
  bk_progress_update(&x->prog, (uint64_t)(1e6 * (frac < 1.0 ? frac : 1.0)));
}

/* Target mode, after the pilot: the batch size whose BT_MIN_BATCHES batches
 * are predicted to meet the target. Rotated Hammersley sets gain from size:
 * the noise of B batches of n falls about as n^(-BT_QMC_RATE / 2) at fixed
 * B, faster than B^(-1/2) at fixed n, so a few large batches need fewer
 * photons than many small ones (docs/error.md). The prediction uses only
 * the measured noise and counted photons; a prediction short of the target
 * is finished by more batches of the new size. Returns 1 when it restarts. */
static int plan_batches(bt_run_t *x) {
  x->planned = 1;
  const double E = x->target, room = E * E - x->terms.step * x->terms.step;
  if (!(x->terms.noise > 0.0)) return 0;
  double n = 0.0, left = (double)(x->photon_cap - x->traced);
  if (room > 0.0) {
    double g = x->terms.noise / sqrt(room); /* noise over what the target leaves */
    /* Finishing with pilot-sized batches costs (g² − 1) B more of them
     * (exact: equal independent batches average as 1/B); a restart, B of
     * `grow` times their size (the rate's prediction; the pilot is spent
     * either way): restart when that is cheaper. */
    double grow = pow(g * BT_PLAN_MARGIN, 2.0 / BT_QMC_RATE);
    if (g * g - 1.0 <= grow) return 0;
    n = ceil((double)x->photons * grow);
  } else { /* the step alone is above it: the scene's photons as a fixed bake */
    n = ceil((double)x->scene->photon_count / BT_MIN_BATCHES);
  }
  n = n < left / BT_MIN_BATCHES ? n : floor(left / BT_MIN_BATCHES);
  if (n <= (double)x->photons) return 0;
  bk_log(2, "target error %g: pilot noise %.4f in %d batches of %llu; restarting with batches "
            "of %.0f", E, x->terms.noise, x->done, (unsigned long long)x->photons, n);
  ee_batches_reset(x->tr); /* and the sums: main_next has them zeroed */
  if (x->grid) ee_batches_reset(x->grid);
  if (x->half) memset(x->half, 0, x->s->voxels * sizeof(float));
  x->pilot = x->done;
  x->done = 0;
  x->photons = (uint64_t)n;
  x->terms.noise = x->terms.estimate = EE_UNKNOWN;
  return 1;
}

/* Half A's luminance sum: in fixed mode the sums after its ceil(B/2)
 * batches (one pass); in the open modes, whose B is not known, the
 * even-numbered batches: + the sums after an odd count, − after an even
 * one (undone at the end when the count is even: finish). */
static void track_half(bt_run_t *x, int done, const uint64_t *acc) {
  if (!x->half) return;
  if (x->batches) {
    if (done == (x->batches + 1) / 2) ee_add_lum(x->tr, x->s, acc, 1.0f, x->half);
  } else {
    ee_add_lum(x->tr, x->s, acc, done & 1 ? 1.0f : -1.0f, x->half);
  }
}

/* Target mode with o->target_terms: the terms of the grid the bake would
 * write after `done` batches (half A as finish would leave it, on a copy),
 * in x->terms; returns 1 when made, 0 when not, -1 on an error. */
static int written_terms(bt_run_t *x, int done, const uint64_t *acc, bk_error_t *err) {
  if (!x->o->target_terms || !(x->target > 0.0) || done < BT_MIN_BATCHES) return 0;
  /* a call costs a filter: at the first chance, then when the last call's
   * ratio to the raw noise predicts the target met, at batch counts a
   * quarter apart (a filter per batch costs as much as a batch at 256³
   * once many are needed) */
  const double raw = x->terms.noise, st = x->terms.step > 0.0 ? x->terms.step : 0.0;
  const double guess = x->written_ratio * raw;
  if (x->written_ratio > 0.0 && (done < x->written_next ||
                                 sqrt(guess * guess + st * st) > BT_WRITTEN_SLACK * x->target))
    return 0; /* x->terms stay the raw mean's */
  x->written_next = (int)ceil(done * BT_WRITTEN_SPACING);
  float *half = NULL;
  if (x->half) {
    if (!(half = bk_calloc(x->s->voxels, sizeof(float), "target mode: half A", err))) return -1;
    memcpy(half, x->half, x->s->voxels * sizeof(float));
    if (!(done & 1)) ee_add_lum(x->tr, x->s, acc, 1.0f, half);
  }
  int rc = x->o->target_terms(x->o->target_ctx, done, acc, half, &x->terms, err);
  free(half);
  const double w = sqrt(x->terms.noise * x->terms.noise + x->terms.filter * x->terms.filter);
  if (raw > 0.0) x->written_ratio = w / raw;
  return rc ? -1 : 1;
}

/* The statistics after batch `done`; returns the batches that count (0
 * when target mode restarts after its pilot; -1 on an error). */
static int track_batch(bt_run_t *x, int done, uint64_t *acc, bk_error_t *err) {
  double t = bk_now_ms();
  ee_after_batch(x->tr, x->s, acc);
  if (x->grid) ee_after_batch(x->grid, x->s, acc);
  track_half(x, done, acc);
  if (done >= 2 && (x->target > 0.0 || x->prog.enabled)) ee_terms(x->tr, done, x->step_exact, &x->terms);
  /* the plan on the raw mean's noise, the stop on the grid written: a
   * filtered grid's error falls slower with the photons than the raw
   * noise (the filter smooths less), and a plan on it fell short at 256³,
   * ending in many small batches (docs/error.md, "Steering") */
  if (!x->planned && x->pilot_split && done >= BT_MIN_BATCHES && x->terms.estimate > x->target &&
      plan_batches(x))
    done = 0;
  else if (written_terms(x, done, acc, err) < 0)
    return -1;
  x->ms_track += bk_now_ms() - t;
  return done;
}

/* pm_run_batches' callback; `all` counts the pilot batches too. */
static int main_next(void *ctx, int all, uint64_t *acc, pm_setup_t *run, bk_error_t *err) {
  bt_run_t *x = ctx;
  int done = x->done = all - x->pilot, restarted = 0;
  if (done > 0) {
    if (x->batches != 1) done = track_batch(x, done, acc, err); /* one batch has no spread */
    if (done < 0) return -1;
    restarted = done == 0; /* target mode's plan starts over */
    show_progress(x, done);
  }
  if (!keep_going(x, done)) {
    if (restarted) memset(acc, 0, pm_acc_count(x->s) * sizeof *acc); /* the result: none */
    return 0;
  }
  if (x->o->retable && x->o->retable(x->o->retable_ctx, done, x->tr, err)) return -1;
  uint64_t n = x->batches ? ph_batch_photons(x->photons, x->batches, done) : x->photons;
  x->traced += n;
  int rc = load_batch(x, x->first_id + all, n, run, err);
  return rc > 0 && restarted ? PM_BATCH_GO_ZERO : rc;
}

/* The integrator needs no twin: no refraction (straight DDA, exact), or it
 * is the truth's own. */
static int step_is_exact(const pm_setup_t *s) {
  return !s->has_refraction || (s->params.integrator == integrator_kind(INTEGRATOR_RK4)->device &&
                                s->params.step <= BT_TRUTH_STEP);
}

/* The batches of a bake: fixed (B of the count's share) or open (target,
 * budget: batches of count / B up to the cap); limit > 0 caps the photons
 * of all batches together (sampling tables count them in bounded sums). */
static void set_mode(bt_run_t *x, const scene_t *scene, const bt_options_t *o) {
  const uint64_t n = (uint64_t)scene->photon_count, limit = o->photon_limit;
  int b = scene_batches(scene, bt_per_voxel(o->error_grid, o->shard_count));
  x->target = scene->target_error;
  x->budget_ms = scene->time_budget_s * 1000.0;
  if (x->target > 0.0 || x->budget_ms > 0.0) {
    x->photons = n / (uint64_t)b > 0 ? n / (uint64_t)b : 1;
    double most = limit ? (double)limit : (double)PH_MAX_PHOTONS;
    double cap = floor(most / (double)x->photons);
    x->cap = cap > BT_MAX_OPEN_BATCHES ? BT_MAX_OPEN_BATCHES : cap < 1.0 ? 1 : (int)cap;
    x->photon_cap = (uint64_t)x->cap * x->photons;
  } else {
    x->photons = n;
    x->batches = (uint64_t)b > n && n > 0 ? (int)n : b;
    x->cap = x->batches;
    x->photon_cap = n;
  }
}

uint64_t bt_photons_at_most(const scene_t *scene, const bt_options_t *o) {
  bt_run_t x;
  memset(&x, 0, sizeof x);
  set_mode(&x, scene, o);
  return x.photon_cap;
}

void bt_report(const bt_result_t *res, const pm_stats_t *st, bk_timings_t *timings) {
  const double ms_march = res->ms_march, sec = ms_march > 0.0 ? ms_march / 1000.0 : 1e-9;
  bk_timings_add(timings, "photon marching", ms_march,
                 "%d batches of %llu, %.1f M photon-steps/s, %.0f M voxels/s", res->batches,
                 (unsigned long long)res->batch_photons, st->steps / sec * 1e-6,
                 st->voxels / sec * 1e-6);
  const ee_terms_t *t = &res->terms;
  char step[48];
  if (res->step_exact) snprintf(step, sizeof step, "step 0 (exact)");
  else snprintf(step, sizeof step, "step %.4f (%d twins)", t->step, t->twin_batches);
  if (t->estimate >= 0.0)
    bk_timings_add(timings, "error estimate", res->ms_twin + res->ms_track,
                   "error %.4f = noise %.4f (%d batches) + %s", t->estimate, t->noise,
                   t->batches, step);
  else
    bk_timings_add(timings, "error estimate", res->ms_twin + res->ms_track,
                   "unknown: %d batch(es), noise needs 2 (photons.batches)", t->batches);
}

/* Stops explained: a budget too short, a target not reached. */
static void warn_stop(const bt_run_t *x, bt_result_t *res) {
  const char *path = x->scene->path;
  if (x->stop_reason == 2 && res->batches < 2) {
    res->budget_short = 1;
    bk_warn("%s: photons.time_budget_s %g s is shorter than two batches of %llu photons (%.3g s "
            "each): wrote %d batch(es) with no noise estimate; raise the budget or lower "
            "photons.count to make batches smaller",
            path, (double)x->scene->time_budget_s, (unsigned long long)x->photons,
            (bk_now_ms() - x->t_main) / 1000.0 / (res->batches ? res->batches : 1), res->batches);
  }
  if (x->target > 0.0 && x->stop_reason != 1) {
    res->target_missed = 1;
    bk_warn("%s: photons.target_error %g not reached: error estimate %.4f after %d batches "
            "(%s)", path, x->target, res->terms.estimate, res->batches,
            x->stop_reason == 2   ? "the time budget ended it"
            : x->stop_reason == 4 ? "the step term alone is above it, and more photons do not "
                                    "lower it: bake with RK4 at a finer photons.step, or aim higher"
                                  : "the batch limit ended it");
  }
}

/* Twin, then the main batches; acc zeroed by the caller. */
static int run_all(clh_context_t *cl, bt_run_t *x, bt_result_t *res, uint64_t *acc,
                   pm_stats_t *stats, double *ms_march, bk_error_t *err) {
  const pm_setup_t *s = x->s;
  int rc = BK_OK;
  x->t0 = bk_now_ms();
  if (!x->step_exact && s->lights.photons > 0 && x->batches != 1 && !x->o->shard_count) {
    const uint64_t keep = x->photons;
    uint64_t total = x->batches ? x->photons : x->photons * BT_OPEN_TWIN_BATCHES;
    uint64_t n = (uint64_t)(total * BT_TWIN_FRACTION / BT_TWIN_BATCHES);
    x->photons = n > BT_TWIN_MIN ? n : BT_TWIN_MIN;
    res->terms.twin_photons = x->photons;
    rc = run_twin(cl, x, acc, err);
    x->photons = keep;
  }
  /* The pilot: one batch's photons in 4. Not with a time budget, which
   * could end the bake between dropping the pilot and the next batch. */
  x->pilot_split = x->target > 0.0 && !(x->budget_ms > 0.0) && x->photons >= BT_PILOT_SPLIT;
  if (x->pilot_split) x->photons /= BT_PILOT_SPLIT;
  res->ms_twin = bk_now_ms() - x->t0;
  if (rc) return rc;
  x->t_main = bk_now_ms();
  bk_progress_begin(&x->prog, x->label, 1000000);
  rc = pm_run_batches(cl, s, acc, stats, main_next, x, err);
  bk_progress_end(&x->prog);
  *ms_march = bk_now_ms() - x->t_main - x->ms_track; /* the statistics are the estimate's */
  return rc;
}

/* radiance_flux from the summed batches, when the march kept it. */
static int make_flux(const pm_setup_t *s, const uint64_t *acc, bt_result_t *res, bk_error_t *err) {
  if (!s->params.flux) return BK_OK;
  res->flux = bk_calloc(s->voxels, 3 * sizeof(float), "radiance_flux grid", err);
  res->uncollided = bk_calloc(s->voxels, (size_t)pm_uncollided_floats(s) * sizeof(float),
                              "radiance_uncollided grids", err);
  if (!res->flux || !res->uncollided) return err->code;
  pm_to_flux(s, acc, res->flux, res->uncollided);
  res->camera = (int)s->params.camera;
  return BK_OK;
}

/* The checks of options that cannot go together. */
static int check_options(const bt_run_t *x, const bt_options_t *o, bk_error_t *err) {
  const char *path = x->scene->path;
  if (o->shard_count && (x->target > 0.0 || x->budget_ms > 0.0 || o->error_grid))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: --shard traces a fixed share of a fixed photon count: it cannot be "
                   "combined with a target error, a time budget or --error-grid", path);
  if ((o->error_grid || o->halves) && x->batches == 1)
    return bk_fail(err, BK_ERR_INPUT, "%s: %s needs at least 2 batches (photons.batches is 1)",
                   path, o->error_grid ? "--error-grid" : "the adaptive filter's error");
  return BK_OK;
}

/* What the batches leave in res; s->to_radiance becomes the mean's. */
static void finish(bt_run_t *x, pm_setup_t *s, const uint64_t *acc, bt_result_t *res,
                   const bt_options_t *o) {
  res->batches = x->done;
  const integrator_kind_t *marched = integrator_of_device(s->params.integrator);
  res->integrator = marched ? marched->id : x->scene->integrator;
  res->step = s->params.step;
  res->step_exact = x->step_exact;
  res->batch_photons = x->batches ? ph_batch_photons(x->photons, x->batches, 0) : x->photons;
  if (x->half && !x->batches && x->done > 0 && !(x->done & 1))
    ee_add_lum(x->tr, s, acc, 1.0f, x->half); /* the last batch was B's, not A's */
  for (int c = 0; c < 3 && x->done > 1; c++) s->to_radiance[c] /= (double)x->done;
  ee_terms(x->tr, x->done, x->step_exact, &res->terms);
  res->terms.twin_photons = x->step_exact ? 0 : res->terms.twin_photons;
  if (o->sums) res->terms.estimate = res->terms.noise = res->terms.step = -1.0;
}

int bt_march(clh_context_t *cl, const scene_t *scene, pm_setup_t *s, const bt_options_t *o,
             uint64_t *acc, bt_result_t *res, pm_stats_t *stats, bk_error_t *err) {
  ee_tracker_t tr;
  bt_run_t x;
  memset(res, 0, sizeof *res);
  memset(&x, 0, sizeof x);
  memset(&tr, 0, sizeof tr);
  x.scene = scene, x.o = o, x.s = s, x.tr = &tr;
  snprintf(x.label, sizeof x.label, "photon marching");
  set_mode(&x, scene, o);
  int rc = check_options(&x, o, err);
  if (rc) return rc;
  if (o->t_start > 0.0 && x.budget_ms > 0.0) /* the stages before the march spent some */
    x.budget_ms = fmax(1e-3, x.budget_ms - (bk_now_ms() - o->t_start));
  pm_scale_batches(s, (double)x.cap * (o->w_max > 1.0 ? o->w_max : 1.0));
  x.step_exact = step_is_exact(s);
  rc = ee_tracker_init(&tr, s, 0, err);
  if (!rc && o->error_grid && !(rc = ee_tracker_init(&res->full, s, 1, err)))
    x.grid = &res->full;
  if (!rc && o->halves) {
    x.half = res->half_a = bk_calloc(s->voxels, sizeof(float), "error estimate: half A", err);
    if (!res->half_a) rc = BK_ERR_RUNTIME;
  }
  if (!rc) rc = run_all(cl, &x, res, acc, stats, &res->ms_march, err);
  if (!rc) {
    double t = bk_now_ms();
    finish(&x, s, acc, res, o);
    res->ms_track = x.ms_track + bk_now_ms() - t;
    stats->ms_march = res->ms_march;
    warn_stop(&x, res);
  }
  ee_tracker_free(&tr);
  if (rc) {
    ee_tracker_free(&res->full);
    free(res->half_a);
    res->half_a = NULL;
  }
  return rc;
}

int bt_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol, const bt_options_t *o,
            float *radiance, bt_result_t *res, pm_stats_t *stats, bk_timings_t *timings,
            bk_error_t *err) {
  pm_setup_t s;
  uint64_t *acc = NULL;
  memset(res, 0, sizeof *res);
  memset(stats, 0, sizeof *stats);
  int rc = pm_prepare_kept(scene, vol, o->fields, &s, timings, stats, err);
  if (rc != BK_OK) return rc;
  if (o->fields_built) o->fields_built(o->fields_built_ctx);
  acc = bk_calloc(pm_acc_count(&s), sizeof(uint64_t), "march: radiance accumulator", err);
  rc = acc ? bt_march(cl, scene, &s, o, acc, res, stats, err) : BK_ERR_RUNTIME;
  if (rc) goto done;
  double t = bk_now_ms();
  if (o->sums) { /* a shard: the sums, scaled for the whole bake's batches */
    pm_sums_keep(&s, acc, o->sums);
    acc = NULL;
  } else {
    res->radiance_channels = 3;
    if ((rc = make_flux(&s, acc, res, err))) goto done;
    if (o->radiance_out) { /* the fields are done with: their memory goes to radiance */
      pm_setup_free_fields(&s);
      res->radiance_channels = pm_radiance_channels(&s);
      radiance = pm_to_radiance_in_place(&s, acc, res->radiance_channels);
      if (radiance) {
        acc = NULL; /* it became radiance */
      } else if (!(radiance = bk_calloc(s.voxels, (size_t)res->radiance_channels * sizeof(float),
                                        "radiance grid", err))) {
        rc = err->code;
        goto done;
      }
      *o->radiance_out = radiance;
    }
    if (acc) pm_to_radiance(&s, acc, radiance, res->radiance_channels);
  }
  stats->ms_march = res->ms_march += bk_now_ms() - t; /* the sums made radiance: the march's end */
  t = bk_now_ms();
  if (o->error_grid) res->error_grid = ee_take_error_grid(&res->full, res->batches);
  ee_tracker_free(&res->full);
  res->ms_track += bk_now_ms() - t;
  if (timings) bt_report(res, stats, timings);
  pm_report_scattering(&s, stats, timings);
done:
  free(acc);
  pm_setup_free(&s);
  return rc;
}
