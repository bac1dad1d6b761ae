/* bench_error_run: the bake's error estimate against the truth, for
 * scripts/bench_error (docs/bench.md, "Error estimate").
 *
 *   bench_error_run SCENE RES TRUTH_PHOTONS N1,N2,... [KEY=VALUE ...]
 *   bench_error_run SCENE RES TRUTH_PHOTONS target:E|budget:S|fixed: [KEY=VALUE ...]
 *
 * Voxelizes SCENE (with --set style overrides) at RES, bakes the truth (RK4,
 * step 1/8 voxel, TRUTH_PHOTONS photons, 8 batches, the scene's seed + 1000
 * so that its photons are not the runs'; cached as
 * SCENE-HASH-RES-TRUTH-s1000.truth in $BENCH_ERROR_CACHE when set), then for Euler and
 * RK4 at step 0.5 and each photon count bakes with the scene's batches
 * (default 2 for a fixed bake: scene_batches) and prints one
 * JSON line: the estimate ε̂ and its terms, the true ε (docs/error.md), the
 * ratio, the relative L2 over all voxels and channels, and the times of the
 * march, the twin and the per-batch statistics, with the march time of the
 * same bake in one batch (no estimate) as the yardstick of the overhead
 * (kernels built first; times the best of 2).
 * The second form makes one bake with photons.target_error E or
 * photons.time_budget_s S (the scene's count and batches) and prints its
 * choice, batches, estimate, true ε and times.
 *
 *   bench_error_run SCENE RES TRUTH_PHOTONS pays:N [KEY=VALUE ...]
 *
 * The third (scripts/bench_adaptive_pays, issue 12 "Pays"): with RK4 at step
 * 1/4 voxel (converged), the reference mode with N photons, then the adaptive
 * mode (filter on, its pilot included) at fractions of N; one JSON line per
 * bake with the true ε, the relative L2 over all voxels, ε̂ (adaptive: and
 * its terms: filtered noise, the filter's bias, the step) and the wall time of
 * the whole stage (reference: octree, twins, march; adaptive: octree, pilot,
 * distribution, twins, march, filter, error terms), kernels built first;
 * each the least of $BENCH_REPEAT bakes (default 2). With $BENCH_DUMP set to a
 * folder, each bake's radiance is written there as raw floats (ref-F.raw,
 * ad-F.raw, F the fraction of N; the truth as truth-0.0000.raw; RGB, x
 * fastest) with the adaptive filter's radius per voxel (rad-F.raw, voxels,
 * one float), for scripts/bench_filter_bound and scripts/bench_filter_bias;
 * $BENCH_NOFILTER=1 makes the adaptive bakes unfiltered (the raw, unbiased
 * weighted estimate), $BENCH_NOISE_K and $BENCH_MAX_RADIUS set the filter's
 * noise allowance (< 0: no noise test) and largest radius (voxels), and
 * $BENCH_REF_ONLY=1 stops after the reference. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sys/resource.h>

#include "adaptive.h"
#include "batches.h"
#include "integrators.h"
#include "voxelize.h"

static scene_t scene;
static volume_t vol;
static clh_context_t cl;
static size_t V;

/* CPU time of the process (every PoCL thread), ms: less sensitive than wall
 * time to the other jobs on a shared machine. */
static double cpu_ms(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return (ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) * 1e3 +
         (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-3;
}

static float *bake(integrator_t integ, float step, long long n, int batches, bt_result_t *res,
                   pm_stats_t *st) {
  bk_error_t err = {0, ""};
  bt_options_t o = {0};
  float *r = calloc(3 * V, sizeof(float));
  if (!r) exit(1);
  scene.integrator = integ, scene.step = step, scene.photon_count = n, scene.batches = batches;
  if (bt_bake(&cl, &scene, &vol, &o, r, res, st, NULL, &err) != BK_OK) {
    fprintf(stderr, "bench_error_run: %s\n", err.msg);
    exit(1);
  }
  return r;
}

/* The adaptive mode as a bake runs it (filter on), its photons counted
 * with the pilot's. */
static float *bake_adaptive(long long n, int batches, bt_result_t *res, pm_stats_t *st) {
  bk_error_t err = {0, ""};
  ad_bake_opts_t o;
  ad_stats_t as;
  ad_bake_defaults(&o);
  float *r = calloc(3 * V, sizeof(float));
  if (!r) exit(1);
  scene.photon_count = n, scene.batches = batches;
  if (ad_bake(&cl, &scene, &vol, &o, r, NULL, NULL, NULL, &as, NULL, &err) != BK_OK) {
    fprintf(stderr, "bench_error_run: %s\n", err.msg);
    exit(1);
  }
  *res = as.error;
  *st = as.march;
  st->photons += as.pilot.photons;
  free(as.error.error_grid);
  return r;
}

/* The truth, from the cache when it holds one. */
static float *truth(const char *scene_path, int res, long long n) {
  const char *dir = getenv("BENCH_ERROR_CACHE");
  char path[2048] = "";
  const char *base = strrchr(scene_path, '/');
  if (dir) /* the scene hash covers the overrides */
    snprintf(path, sizeof path, "%s/%s-%016llx-%d-%lld-s1000.truth", dir, base ? base + 1 : scene_path,
             (unsigned long long)scene.hash, res, n);
  float *t = calloc(3 * V, sizeof(float));
  FILE *f = path[0] ? fopen(path, "rb") : NULL;
  if (f && fread(t, sizeof(float), 3 * V, f) == 3 * V) {
    fclose(f);
    return t;
  }
  if (f) fclose(f);
  free(t);
  bt_result_t r;
  pm_stats_t st;
  unsigned seed = scene.seed;
  scene.seed = seed + 1000; /* the truth's photons independent of the runs' */
  t = bake(INTEGRATOR_RK4, 0.125f, n, 8, &r, &st);
  scene.seed = seed;
  fprintf(stderr, "truth: %lld photons in %.1f s, its own noise %.4f\n", n, st.ms_march / 1000.0,
          r.terms.noise);
  if (path[0] && (f = fopen(path, "wb"))) {
    fwrite(t, sizeof(float), 3 * V, f);
    fclose(f);
  }
  return t;
}

static double rel_l2(const float *x, const float *t) {
  double se = 0.0, st = 0.0;
  for (size_t i = 0; i < 3 * V; i++) se += (double)(x[i] - t[i]) * (x[i] - t[i]), st += (double)t[i] * t[i];
  return st > 0.0 ? sqrt(se / st) : 0.0;
}

/* "target:E" or "budget:S": one steered bake (the scene's photons and
 * batches, its photons.mode); "fixed:": one bake as the scene says, for
 * comparison. */
static void steered(const char *what, const float *T) {
  bt_result_t r;
  pm_stats_t st;
  long long n = scene.photon_count;
  int b = scene.batches;
  float v = (float)atof(strchr(what, ':') + 1);
  if (!strncmp(what, "target:", 7)) scene.target_error = v;
  else if (!strncmp(what, "budget:", 7)) scene.time_budget_s = v;
  double t0 = bk_now_ms();
  float *x = scene.mode == MODE_ADAPTIVE ? bake_adaptive(n, b, &r, &st)
                                         : bake(scene.integrator, scene.step, n, b, &r, &st);
  double ms = bk_now_ms() - t0, eps = ee_true_error(x, T, V);
  printf("{\"run\": \"%s\", \"integrator\": \"%s\", \"step_voxels\": %g, \"batches\": %d, "
         "\"photons\": %llu, \"estimate\": %.5f, \"true\": %.5f, \"march_ms\": %.1f, "
         "\"twin_ms\": %.1f, \"stage_ms\": %.1f}\n",
         what, integrator_kind(r.integrator)->name, (double)r.step, r.batches,
         (unsigned long long)st.photons, r.terms.estimate, eps, st.ms_march, r.ms_twin, ms);
  scene.target_error = scene.time_budget_s = 0.0f;
  free(x);
}

/* Bakes per "pays:" point, the least time kept: $BENCH_REPEAT, default 2
 * (a bake's bits do not change between repeats; its time, on a shared
 * machine, by ±10%). */
static int pays_repeat(void) {
  const char *e = getenv("BENCH_REPEAT");
  int k = e ? atoi(e) : 2;
  return k >= 1 ? k : 1;
}

/* A grid of `per_voxel` floats per voxel into $BENCH_DUMP/NAME-FRACTION.raw,
 * when the variable is set (see the header). */
static void dump(const char *name, double fraction, const float *x, size_t per_voxel) {
  const char *dir = getenv("BENCH_DUMP");
  if (!dir) return;
  char path[2048];
  snprintf(path, sizeof path, "%s/%s-%.4f.raw", dir, name, fraction);
  FILE *f = fopen(path, "wb");
  if (!f || fwrite(x, sizeof(float), per_voxel * V, f) != per_voxel * V || fclose(f) != 0) {
    fprintf(stderr, "bench_error_run: cannot write %s\n", path);
    exit(1);
  }
}

static int env_flag(const char *name) {
  const char *e = getenv(name);
  return e && atoi(e);
}

/* "pays:N": the reference with N photons, adaptive at fractions of N. */
static void pays(const char *what, const float *T) {
  static const double frac[] = {1.0, 0.75, 0.5, 0.375, 0.25, 0.1875, 0.125};
  long long n = atoll(what + 5);
  scene.integrator = INTEGRATOR_RK4, scene.step = 0.25f; /* converged: noise is what is left */
  bt_result_t r;
  pm_stats_t st;
  bk_error_t err = {0, ""};
  int b = scene.batches; /* the adaptive bakes' (0: scene_batches decides) */
  free(bake(scene.integrator, scene.step, 4096, b, &r, &st)); /* kernels built */
  float *x = NULL;
  double ms = HUGE_VAL, cpu = HUGE_VAL;
  for (int rep = 0; rep < pays_repeat(); rep++) { /* the same bits each time: the least time */
    double t0 = bk_now_ms(), c0 = cpu_ms();
    free(x);
    x = bake(scene.integrator, scene.step, n, b, &r, &st);
    ms = fmin(ms, bk_now_ms() - t0), cpu = fmin(cpu, cpu_ms() - c0);
  }
  dump("ref", 1.0, x, 3);
  printf("{\"mode\": \"reference\", \"photons\": %lld, \"true\": %.5f, \"rel_l2\": %.5f, "
         "\"estimate\": %.5f, \"ms\": %.1f, \"cpu_ms\": %.1f}\n", n, ee_true_error(x, T, V),
         rel_l2(x, T), r.terms.estimate, ms, cpu);
  fflush(stdout);
  free(x);
  if (env_flag("BENCH_REF_ONLY")) return;
  x = calloc(3 * V, sizeof(float));
  float *rad = calloc(V, sizeof(float));
  ad_bake_opts_t o;
  ad_bake_defaults(&o);
  o.retable = env_flag("BENCH_RETABLE");
  if (env_flag("BENCH_NOFILTER")) o.filter = 0;
  if (getenv("BENCH_NOISE_K")) o.noise_k = (float)atof(getenv("BENCH_NOISE_K"));
  if (getenv("BENCH_MAX_RADIUS")) o.max_radius = (float)atof(getenv("BENCH_MAX_RADIUS"));
  for (int warm = 1, i = 0; i < (int)(sizeof frac / sizeof frac[0]); warm = 0) {
    ad_stats_t as;
    long long m = warm ? 4096 : (long long)(frac[i] * (double)n) - scene.pilot;
    scene.photon_count = m > 1000 ? m : 1000;
    ms = cpu = HUGE_VAL;
    for (int rep = 0; rep < (warm ? 1 : pays_repeat()); rep++) {
      double t0 = bk_now_ms(), c0 = cpu_ms();
      if (ad_bake(&cl, &scene, &vol, &o, x, NULL, NULL, rad, &as, NULL, &err) != BK_OK) {
        fprintf(stderr, "bench_error_run: %s\n", err.msg);
        exit(1);
      }
      ms = fmin(ms, bk_now_ms() - t0), cpu = fmin(cpu, cpu_ms() - c0);
      free(as.error.error_grid);
    }
    if (warm) continue;
    dump("ad", frac[i], x, 3);
    dump("rad", frac[i], rad, 1);
    printf("{\"mode\": \"%s\", \"photons\": %lld, \"fraction\": %.4f, \"true\": %.5f, "
           "\"rel_l2\": %.5f, \"estimate\": %.5f, \"noise\": %.5f, \"filter\": %.5f, "
           "\"step\": %.5f, \"ms\": %.1f, \"cpu_ms\": %.1f, \"march_ms\": %.1f}\n",
           o.retable ? "adaptive+loop" : "adaptive", scene.photon_count + scene.pilot, frac[i],
           ee_true_error(x, T, V), rel_l2(x, T), as.error.terms.estimate, as.error.terms.noise,
           as.error.terms.filter, as.error.terms.step, ms, cpu, as.ms_march);
    fflush(stdout);
    i++;
  }
  free(x);
  free(rad);
}

int main(int argc, char **argv) {
  bk_error_t err = {0, ""};
  if (argc < 5) {
    fprintf(stderr, "usage: bench_error_run SCENE RES TRUTH_PHOTONS N1,N2,... [KEY=VALUE ...]\n");
    return 2;
  }
  if (scene_load_with(argv[1], (const char *const *)argv + 5, argc - 5, &scene, &err) != BK_OK ||
      (scene.resolution = atoi(argv[2]), vox_build(&scene, &vol, NULL, &err)) != BK_OK ||
      clh_init(&cl, NULL, &err) != BK_OK) {
    fprintf(stderr, "bench_error_run: %s\n", err.msg);
    return 2;
  }
  V = grid_count(&vol.dims);
  scene_t loaded = scene;
  float *T = truth(argv[1], scene.resolution, atoll(argv[3]));
  if (!strncmp(argv[4], "pays:", 5)) {
    scene = loaded;
    dump("truth", 0.0, T, 3);
    pays(argv[4], T);
    free(T);
    return 0;
  }
  if (strchr(argv[4], ':')) {
    scene = loaded;
    steered(argv[4], T);
    free(T);
    return 0;
  }
  const integrator_t integ[2] = {INTEGRATOR_EULER, INTEGRATOR_RK4};
  bt_result_t r, r1;
  pm_stats_t st, st1;
  for (int i = 0; i < 2; i++) /* warm the kernel cache: timings without builds */
    free(bake(integ[i], 0.5f, 4096, loaded.batches, &r, &st));
  for (int i = 0; i < 2; i++)
    for (char *p = argv[4]; *p;) {
      long long n = strtoll(p, &p, 10);
      if (*p == ',') p++;
      double ms8 = HUGE_VAL, ms1 = HUGE_VAL, twin = HUGE_VAL, track = HUGE_VAL;
      double cpu8 = HUGE_VAL, cpu1 = HUGE_VAL, c0;
      float *x = NULL;
      for (int rep = 0; rep < 2; rep++) { /* best of 2: the machine is shared */
        c0 = cpu_ms();
        free(bake(integ[i], 0.5f, n, 1, &r1, &st1));
        cpu1 = fmin(cpu1, cpu_ms() - c0);
        ms1 = fmin(ms1, st1.ms_march);
        free(x);
        c0 = cpu_ms();
        x = bake(integ[i], 0.5f, n, loaded.batches, &r, &st);
        cpu8 = fmin(cpu8, cpu_ms() - c0);
        ms8 = fmin(ms8, st.ms_march), twin = fmin(twin, r.ms_twin), track = fmin(track, r.ms_track);
      }
      double eps = ee_true_error(x, T, V);
      printf("{\"integrator\": \"%s\", \"photons\": %lld, \"estimate\": %.5f, \"noise\": %.5f, "
             "\"step\": %.5f, \"true\": %.5f, \"ratio\": %.3f, \"rel_l2\": %.5f, \"march_ms\": %.1f, "
             "\"twin_ms\": %.1f, \"track_ms\": %.1f, \"one_batch_ms\": %.1f, \"cpu_ms\": %.1f, "
             "\"one_batch_cpu_ms\": %.1f}\n",
             integrator_kind(integ[i])->name, n, r.terms.estimate, r.terms.noise, r.terms.step, eps,
             r.terms.estimate / eps, rel_l2(x, T), ms8, twin, track, ms1, cpu8, cpu1);
      fflush(stdout);
      free(x);
    }
  free(T);
  return 0;
}
