/* bench_adaptive_run.c: the benchmark behind scripts/bench_adaptive (not a
 * test: timings depend on the machine and its load). For one scene:
 *  1. a converged bake, reference mode, CONV x N photons (cached in
 *     CACHE_DIR, keyed by the scene file's hash, the resolution and the
 *     photon count);
 *  2. a ladder of photon counts for each pipeline: each bake RUNS times,
 *     keeping the fastest; its error is the relative L2 error over the
 *     radiance grid against the converged bake,
 *       e = sqrt(sum (X - T)^2 / sum T^2) over voxels and channels
 *     (a bake is deterministic: the error is the same every run);
 *  3. the target error: the reference's at N photons; the time each
 *     pipeline needs to reach it, interpolated log-log between the two
 *     ladder points that bracket it (extrapolated from the nearest two,
 *     and said so, when none does).
 * Times: "photon stages" is the sum of the pipeline's timing rows after the
 * octree (reference: photon generation, photon marching; adaptive: pilot
 * marching, photon distribution, photon generation, photon marching,
 * filtering), the rows the slides' table compares; "total" is the whole
 * pm_bake / ad_bake call, octree included (voxelization is shared and not
 * counted); "cpu" is the process's user + system time over the call (all
 * OpenCL threads), less sensitive than wall time to other programs on the
 * machine.
 *
 * Usage: bench_adaptive_run SCENE RES N CONV RUNS CACHE_DIR REF_FRACTIONS ADA_FRACTIONS
 * fractions: comma-separated multiples of N, e.g. 0.5,0.7,1,1.4. */
#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "adaptive.h"
#include "voxelize.h"
#include "tests/test_util.h"

#define MAX_POINTS 16

typedef struct point {
  long long photons;
  double err, ms_stages, ms_total, cpu_s;
  double rows[8]; /* per-row ms of the fastest run */
} point_t;

static double cpu_seconds(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + ru.ru_stime.tv_sec +
         ru.ru_stime.tv_usec * 1e-6;
}

static int parse_fractions(const char *s, double *out) {
  int n = 0;
  char *copy = strdup(s), *save = NULL;
  for (char *tok = strtok_r(copy, ",", &save); tok && n < MAX_POINTS;
       tok = strtok_r(NULL, ",", &save))
    out[n++] = atof(tok);
  free(copy);
  return n;
}

static double row_ms(const bk_timings_t *t, const char *name) {
  for (int i = 0; i < t->count; i++)
    if (!strcmp(t->stages[i].name, name)) return t->stages[i].ms;
  return 0.0;
}

static const char *ref_rows[] = {"photon generation", "photon marching"};
static const char *ada_rows[] = {"pilot marching", "photon distribution", "photon generation",
                                 "photon marching", "filtering"};

/* One ladder point: `runs` bakes, the fastest kept. */
static int run_point(clh_context_t *cl, scene_t *sc, const volume_t *vol, int adaptive,
                     long long photons, int runs, const float *conv, float *buf, point_t *p,
                     bk_error_t *err) {
  size_t V = grid_count(&vol->dims);
  memset(p, 0, sizeof *p);
  p->photons = photons;
  p->ms_stages = p->ms_total = p->cpu_s = 1e30;
  sc->photon_count = photons;
  for (int r = 0; r < runs; r++) {
    bk_timings_t tm;
    memset(&tm, 0, sizeof tm);
    double c0 = cpu_seconds(), t0 = bk_now_ms();
    int rc;
    if (adaptive) {
      ad_stats_t st;
      rc = ad_bake(cl, sc, vol, NULL, buf, NULL, NULL, NULL, &st, &tm, err);
    } else {
      pm_stats_t st;
      rc = pm_bake(cl, sc, vol, buf, &st, &tm, err);
    }
    if (rc != BK_OK) return rc;
    double total = bk_now_ms() - t0, cpu = cpu_seconds() - c0;
    const char **rows = adaptive ? ada_rows : ref_rows;
    int nrows = adaptive ? 5 : 2;
    double stages = 0.0;
    for (int i = 0; i < nrows; i++) stages += row_ms(&tm, rows[i]);
    if (stages < p->ms_stages) {
      p->ms_stages = stages;
      for (int i = 0; i < nrows; i++) p->rows[i] = row_ms(&tm, rows[i]);
    }
    if (total < p->ms_total) p->ms_total = total;
    if (cpu < p->cpu_s) p->cpu_s = cpu;
  }
  p->err = tu_rel_l2(buf, conv, 3 * V);
  return BK_OK;
}

/* log t at log err = log target, between the bracketing points (errors fall
 * with photons); *how says interpolated or extrapolated. */
static double time_at(const point_t *pts, int n, double target, int which, const char **how) {
  double x[MAX_POINTS], y[MAX_POINTS];
  for (int i = 0; i < n; i++) {
    x[i] = log(pts[i].err);
    y[i] = log(which == 0 ? pts[i].ms_stages : which == 1 ? pts[i].ms_total : pts[i].cpu_s);
  }
  double lt = log(target);
  int a = -1;
  for (int i = 0; i + 1 < n; i++)
    if ((x[i] >= lt && x[i + 1] <= lt) || (x[i] <= lt && x[i + 1] >= lt)) {
      a = i;
      break;
    }
  *how = "interpolated";
  if (a < 0) {
    *how = "EXTRAPOLATED";
    a = lt > x[0] ? 0 : n - 2; /* larger error than the ladder: its cheap end */
  }
  double dx = x[a + 1] - x[a];
  double t = dx != 0.0 ? (lt - x[a]) / dx : 0.0;
  return exp(y[a] + t * (y[a + 1] - y[a]));
}

int main(int argc, char **argv) {
  if (argc < 9) {
    fprintf(stderr,
            "usage: %s SCENE RES N CONV RUNS CACHE_DIR REF_FRACTIONS ADA_FRACTIONS\n", argv[0]);
    return 2;
  }
  const char *path = argv[1], *cache_dir = argv[6];
  int res = atoi(argv[2]), runs = atoi(argv[5]);
  long long N = atoll(argv[3]), conv_n = N * atoll(argv[4]);
  double fr_ref[MAX_POINTS], fr_ada[MAX_POINTS];
  int n_ref = parse_fractions(argv[7], fr_ref), n_ada = parse_fractions(argv[8], fr_ada);
  bk_error_t err;
  scene_t sc;
  volume_t vol;
  clh_context_t cl;
  memset(&err, 0, sizeof err);
  bk_verbosity = 0;
  if (scene_load(path, &sc, &err) != BK_OK) {
    fprintf(stderr, "bench_adaptive_run: %s\n", err.msg);
    return 1;
  }
  sc.resolution = res;
  if (vox_build(&sc, &vol, NULL, &err) != BK_OK || clh_init(&cl, NULL, &err) != BK_OK) {
    fprintf(stderr, "bench_adaptive_run: %s\n", err.msg);
    return 1;
  }
  size_t V = grid_count(&vol.dims);
  float *conv = calloc(3 * V, sizeof(float)), *buf = calloc(3 * V, sizeof(float));
  if (!conv || !buf) return 1;

  /* the converged bake, cached */
  char cpath[4096];
  snprintf(cpath, sizeof cpath, "%s/converged_%016" PRIx64 "_%d_%lld.f32", cache_dir, sc.hash, res,
           conv_n);
  FILE *f = fopen(cpath, "rb");
  double conv_ms = 0.0;
  int cached = f && fread(conv, sizeof(float), 3 * V, f) == 3 * V;
  if (f) fclose(f);
  if (!cached) {
    pm_stats_t st;
    sc.photon_count = conv_n;
    double t0 = bk_now_ms();
    if (pm_bake(&cl, &sc, &vol, conv, &st, NULL, &err) != BK_OK) {
      fprintf(stderr, "bench_adaptive_run: %s\n", err.msg);
      return 1;
    }
    conv_ms = bk_now_ms() - t0;
    f = fopen(cpath, "wb");
    if (f) {
      fwrite(conv, sizeof(float), 3 * V, f);
      fclose(f);
    }
  }
  char how[64];
  if (cached) snprintf(how, sizeof how, "cached");
  else snprintf(how, sizeof how, "%.0f ms", conv_ms);
  printf("scene %s, %dx%dx%d, converged bake: %lld photons, reference mode (%s)\n", path,
         vol.dims.nx, vol.dims.ny, vol.dims.nz, conv_n, how);

  /* warm-up: kernel builds and PoCL's own caches out of the timings */
  point_t p;
  if (run_point(&cl, &sc, &vol, 0, N / 8, 1, conv, buf, &p, &err) != BK_OK ||
      run_point(&cl, &sc, &vol, 1, N / 8, 1, conv, buf, &p, &err) != BK_OK) {
    fprintf(stderr, "bench_adaptive_run: %s\n", err.msg);
    return 1;
  }

  point_t ref[MAX_POINTS], ada[MAX_POINTS];
  printf("%-9s %9s %8s %10s %9s %7s   rows (ms)\n", "pipeline", "photons", "error", "stages ms",
         "total ms", "cpu s");
  for (int pass = 0; pass < 2; pass++) {
    int n = pass ? n_ada : n_ref;
    for (int i = 0; i < n; i++) {
      point_t *q = pass ? &ada[i] : &ref[i];
      long long photons = (long long)llround((pass ? fr_ada[i] : fr_ref[i]) * N);
      if (run_point(&cl, &sc, &vol, pass, photons, runs, conv, buf, q, &err) != BK_OK) {
        fprintf(stderr, "bench_adaptive_run: %s\n", err.msg);
        return 1;
      }
      printf("%-9s %9lld %8.4f %10.1f %9.1f %7.3f  ", pass ? "adaptive" : "reference",
             q->photons, q->err, q->ms_stages, q->ms_total, q->cpu_s);
      int nrows = pass ? 5 : 2;
      for (int r = 0; r < nrows; r++)
        printf(" %s %.1f%s", (pass ? ada_rows : ref_rows)[r], q->rows[r], r + 1 < nrows ? "," : "");
      printf("\n");
      fflush(stdout);
    }
  }
  /* the target: the reference's error at N (the ladder point at fraction 1,
   * else interpolated) */
  double target = -1.0;
  for (int i = 0; i < n_ref; i++)
    if (ref[i].photons == N) target = ref[i].err;
  if (target < 0.0) {
    fprintf(stderr, "bench_adaptive_run: the reference ladder must contain the fraction 1\n");
    return 2;
  }
  const char *names[3] = {"photon stages", "total", "cpu"};
  printf("target error %.4f (reference at %lld photons)\n", target, N);
  for (int w = 0; w < 3; w++) {
    const char *h1, *h2;
    double tr = time_at(ref, n_ref, target, w, &h1), ta = time_at(ada, n_ada, target, w, &h2);
    const char *unit = w == 2 ? "s" : "ms";
    printf("time to the target, %-13s: reference %8.1f %s (%s), adaptive %8.1f %s (%s), ratio "
           "adaptive/reference %.3f\n",
           names[w], tr, unit, h1, ta, unit, h2, ta / tr);
  }
  /* the photons each needs, for the record */
  double lp_ref = 0.0, lp_ada = 0.0;
  {
    const char *h;
    point_t tmp[MAX_POINTS];
    for (int i = 0; i < n_ref; i++) tmp[i] = ref[i], tmp[i].ms_stages = (double)ref[i].photons;
    lp_ref = time_at(tmp, n_ref, target, 0, &h);
    for (int i = 0; i < n_ada; i++) tmp[i] = ada[i], tmp[i].ms_stages = (double)ada[i].photons;
    lp_ada = time_at(tmp, n_ada, target, 0, &h);
  }
  printf("photons to the target: reference %.0f, adaptive %.0f (+ %d pilot), ratio %.3f\n", lp_ref,
         lp_ada, sc.pilot, lp_ada / lp_ref);
  free(conv);
  free(buf);
  clh_release(&cl);
  vox_free(&vol);
  scene_free(&sc);
  return 0;
}
