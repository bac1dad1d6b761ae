/* bench_march_run.c: the march benchmark behind scripts/bench_march (not a
 * test: it asserts nothing about time). The slides' sphere scene: a ball of
 * n = 1.5 (radius 0.5, 2-voxel smoothing) in fog (σs 0.5, σa 0.05 per m)
 * over [-1,1]^3 under a spot light (25°, from 1.8 m above), 122 000 photons.
 * It runs the march on OpenCL and on the host C path, with the octree and
 * without it (stepping Δs everywhere: the paper's march without its octree,
 * in plain scalar C on one thread), each RUNS times, and reports the fastest.
 *
 * Rates: "steps/s" counts march iterations (integrator steps and straight
 * crossings of constant blocks); "Euler-equivalent steps/s" is the path
 * length over Δs per second, the rate a march stepping Δs everywhere would
 * need to match, and the figure to hold against a plain Euler march.
 * Usage: bench_march_run [RES] [PHOTONS] [euler|rk4] [RUNS] [host,cl,noct] */
#include <unistd.h>

#include "tests/test_march_util.h"

typedef struct best {
  double octree, generate, build, march, readout;
  pm_stats_t st;
} best_t;

static best_t run(clh_context_t *cl, const scene_t *s, const volume_t *v, int octree, int runs) {
  best_t b;
  memset(&b, 0, sizeof b);
  b.march = 1e300;
  for (int r = 0; r < runs; r++) {
    bk_error_t err;
    memset(&err, 0, sizeof err);
    pm_setup_t su;
    pm_stats_t st;
    memset(&st, 0, sizeof st);
    REQUIRE(pm_prepare(s, v, &su, NULL, &st, &err) == BK_OK, "pm_prepare: %s", err.msg);
    if (!octree) pm_disable_octree(&su);
    uint64_t *acc = calloc(su.voxels * su.channels, sizeof(uint64_t));
    float *rad = malloc(su.voxels * 3 * sizeof(float));
    REQUIRE(acc && rad, "out of memory");
    double t1 = bk_now_ms();
    int rc = cl ? pm_run_cl(cl, &su, acc, &st, &err) : pm_run_host(&su, acc, &st, &err);
    REQUIRE(rc == BK_OK, "march: %s", err.msg);
    double t2 = bk_now_ms();
    pm_to_radiance(&su, acc, rad);
    double t3 = bk_now_ms();
    double march = t2 - t1 - st.ms_build;
    if (march < b.march) {
      b.octree = st.ms_octree;
      b.generate = st.ms_generate;
      b.build = st.ms_build;
      b.march = march;
      b.readout = t3 - t2;
      b.st = st;
    }
    free(acc);
    free(rad);
    pm_setup_free(&su);
  }
  return b;
}

static void report(const char *label, const best_t *b, float step) {
  double sec = b->march / 1000.0;
  printf("%-36s %8.1f %8.2f %8.1f %9.1f %8.1f | %7.2f %8.2f %8.2f | %.2f steps, %.1f voxels per "
         "photon\n",
         label, b->octree, b->generate, b->build, b->march, b->readout, b->st.steps / sec * 1e-6,
         b->st.voxels / sec * 1e-6, b->st.path_voxels / step / sec * 1e-6,
         (double)b->st.steps / b->st.photons, b->st.path_voxels / b->st.photons);
  fflush(stdout);
}

int main(int argc, char **argv) {
  int res = argc > 1 ? atoi(argv[1]) : 128;
  long long photons = argc > 2 ? atoll(argv[2]) : 122000;
  int rk4 = argc > 3 && !strcmp(argv[3], "rk4");
  int runs = argc > 4 ? atoi(argv[4]) : 3;
  const char *which = argc > 5 ? argv[5] : "host,cl,noct";
  if (runs < 1) runs = 1;
  bk_verbosity = 0;

  const float h = 2.0f / res;
  volume_t v;
  tv_alloc(&v, res, res, res, h, -1, -1, -1);
  const float fs[3] = {0.5f, 0.5f, 0.5f}, fa[3] = {0.05f, 0.05f, 0.05f};
  tv_fill(&v, 1.0f, fs, fa);
  const float c[3] = {0, 0, 0}, zero[3] = {0, 0, 0};
  tv_ball(&v, c, 0.5f, 1.5f, 2.0f, zero, zero);
  tv_summarise(&v);
  scene_light_t light = tl_spot(0, 1.8f, 0, 0, -1, 0, 25, 10, 10, 10);
  scene_t s;
  ts_init(&s, &light, 1, photons);
  s.integrator = rk4 ? INTEGRATOR_RK4 : INTEGRATOR_EULER;

  clh_context_t cl;
  bk_error_t err;
  memset(&err, 0, sizeof err);
  REQUIRE(clh_init(&cl, NULL, &err) == BK_OK, "clh_init: %s", err.msg);
  printf("sphere n=1.5 in fog, spot light, %d^3, %lld photons, %s, step %.2f voxel, best of %d; "
         "%ld online cores; OpenCL: %s, %u compute units\n",
         res, photons, rk4 ? "RK4" : "Euler", s.step, runs, sysconf(_SC_NPROCESSORS_ONLN),
         cl.device_name, cl.compute_units);
  printf("%-36s %8s %8s %8s %9s %8s | %7s %8s %8s\n", "", "octree", "gen", "build", "march",
         "readout", "Msteps/s", "Mvox/s", "MEuler/s");
  printf("%-36s %8s %8s %8s %9s %8s | %7s %8s %8s\n", "", "ms", "ms", "ms", "ms", "ms", "", "",
         "equiv.");
  int noct = strstr(which, "noct") != NULL;
  if (strstr(which, "cl")) {
    /* the first launch in a process also pays PoCL's work-group compile */
    best_t first = run(&cl, &s, &v, 1, 1);
    report("OpenCL, octree, first launch", &first, s.step);
    best_t b = run(&cl, &s, &v, 1, runs);
    report("OpenCL, octree", &b, s.step);
    if (noct) {
      b = run(&cl, &s, &v, 0, runs);
      report("OpenCL, no octree", &b, s.step);
    }
  }
  if (strstr(which, "host")) {
    best_t b = run(NULL, &s, &v, 1, runs);
    report("host C (1 thread), octree", &b, s.step);
    if (noct) {
      b = run(NULL, &s, &v, 0, runs);
      report("host C (1 thread), no octree", &b, s.step);
    }
  }
  clh_release(&cl);
  tv_free(&v);
  return 0;
}
