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
 *
 * "omp" adds the yardstick of issue 15: the same physics (pm_march_photon of
 * kernels/photon_march.h, compiled here) in a plain OpenMP loop over the
 * photons on every core, stepping Δs everywhere (no octree), each thread
 * depositing into its own copy of the grid and the copies summed at the end
 * (integer sums: the grid equals the one-thread march's bit for bit, which is
 * checked). The ratio printed is its march time over the OpenCL march's.
 * Usage: bench_march_run [RES] [PHOTONS] [euler|rk4] [RUNS] [host,cl,noct,omp] */
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "tests/test_march_util.h"
#include "vox_medium.h"

typedef struct best {
  double octree, generate, build, march, readout;
  pm_stats_t st;
  size_t cells; /* accumulator entries: voxels x channels */
} best_t;

static best_t run(clh_context_t *cl, const scene_t *s, const volume_t *v, int octree, int runs,
                  uint64_t **acc_keep) {
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
    pm_to_radiance(&su, acc, rad, 3);
    double t3 = bk_now_ms();
    double march = t2 - t1 - st.ms_build;
    if (march < b.march) {
      b.octree = st.ms_octree;
      b.generate = st.ms_generate;
      b.build = st.ms_build;
      b.march = march;
      b.readout = t3 - t2;
      b.st = st;
      b.cells = su.voxels * su.channels;
      if (acc_keep) {
        free(*acc_keep);
        *acc_keep = acc;
        acc = NULL;
      }
    }
    free(acc);
    free(rad);
    pm_setup_free(&su);
  }
  return b;
}

static void stats_merge(pm_stats_t *a, const pm_stats_t *b) {
  a->photons += b->photons;
  a->missed_grid += b->missed_grid;
  a->left_grid += b->left_grid;
  a->absorbed += b->absorbed;
  a->step_limit += b->step_limit;
  a->steps += b->steps;
  a->voxels += b->voxels;
  a->path_voxels += b->path_voxels;
}

#ifdef _OPENMP
/* The yardstick: pm_march_photon in `#pragma omp parallel for`, no octree
 * (no pyramid at all: not even its lookups), private grids summed after
 * the loop; the sum is inside the timed part. */
static best_t run_omp(const scene_t *s, const volume_t *v, int runs, uint64_t **acc_out) {
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
    pm_disable_octree(&su);
    const size_t cells = su.voxels * su.channels;
    const int T = omp_get_max_threads();
    uint64_t *priv = calloc((size_t)T * cells, sizeof(uint64_t));
    uint64_t *acc = calloc(cells, sizeof(uint64_t));
    REQUIRE(priv && acc, "out of memory");
    const long long n = (long long)su.lights.photons;
    double t1 = bk_now_ms();
#pragma omp parallel
    {
      uint64_t *mine = priv + (size_t)omp_get_thread_num() * cells;
      pm_stats_t local;
      memset(&local, 0, sizeof local);
#pragma omp for schedule(dynamic, 1024)
      for (long long i = 0; i < n; i++) {
        pm_result res;
        pm_march_photon(&su.params, su.lights.lights, su.ng, NULL, su.sigma_t, mine,
                        su.masks, su.tables, (bk_uint)i, &res, NULL);
        pm_stats_add(&local, &res);
      }
#pragma omp critical
      stats_merge(&st, &local);
#pragma omp for
      for (long long c = 0; c < (long long)cells; c++)
        for (int t = 0; t < T; t++) acc[c] += priv[(size_t)t * cells + (size_t)c];
    }
    double march = bk_now_ms() - t1;
    if (march < b.march) {
      b.march = march;
      b.octree = st.ms_octree;
      b.generate = st.ms_generate;
      b.st = st;
      b.cells = cells;
      free(*acc_out);
      *acc_out = acc;
      acc = NULL;
    }
    free(acc);
    free(priv);
    pm_setup_free(&su);
  }
  return b;
}
#endif

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
  v.sigma_channels = 3; /* finished as the voxelizer finishes a volume: grey σ once per voxel */
  vox_summarise(&v);
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
  double t_cl = 0.0;
  uint64_t *acc_noct = NULL, *acc_omp = NULL;
  if (strstr(which, "cl")) {
    /* the first launch in a process also pays PoCL's work-group compile */
    best_t first = run(&cl, &s, &v, 1, 1, NULL);
    report("OpenCL, octree, first launch", &first, s.step);
    best_t b = run(&cl, &s, &v, 1, runs, NULL);
    report("OpenCL, octree", &b, s.step);
    t_cl = b.march;
    if (noct) {
      b = run(&cl, &s, &v, 0, runs, NULL);
      report("OpenCL, no octree", &b, s.step);
    }
  }
  if (strstr(which, "host")) {
    best_t b = run(NULL, &s, &v, 1, runs, NULL);
    report("host C (1 thread), octree", &b, s.step);
    if (noct) {
      b = run(NULL, &s, &v, 0, runs, &acc_noct);
      report("host C (1 thread), no octree", &b, s.step);
    }
  }
  if (strstr(which, "omp")) {
#ifdef _OPENMP
    best_t b = run_omp(&s, &v, runs, &acc_omp);
    char label[64];
    snprintf(label, sizeof label, "plain OpenMP loop (%d threads), no oct.", omp_get_max_threads());
    report(label, &b, s.step);
    if (t_cl > 0.0)
      printf("yardstick: the OpenCL march (octree) takes 1/%.2f of the plain OpenMP loop's time\n",
             b.march / t_cl);
    if (acc_noct) {
      int same = 1;
      for (size_t c = 0; c < b.cells && same; c++) same = acc_noct[c] == acc_omp[c];
      printf("yardstick grid %s the one-thread host march's (no octree)\n",
             same ? "equals" : "DIFFERS FROM");
    }
#else
    printf("plain OpenMP loop: this build has no OpenMP\n");
#endif
  }
  free(acc_noct);
  free(acc_omp);
  clh_release(&cl);
  tv_free(&v);
  return 0;
}
