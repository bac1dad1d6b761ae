/* test_march_robust.c: the fixed-point sums, host against device, and the
 * extremes (no NaN, Inf or hang).
 *   precision host|cl: 1e8 equal deposits into one counter sum exactly.
 *   host_vs_device: the same scene on the host C path and on OpenCL, bit for bit.
 *   extremes host|cl: n 1.0001..4, smoothing 0.5..8 voxels, σt 0..1e4, 8^3
 *     grids, photons trapped by total internal reflection.
 *   extremes_512: a 512^3 grid with a handful of photons (host, memory
 *     permitting; exit 77 = skipped otherwise).
 *   lattice host|cl: the error estimate twins' packed sums
 *     (pm_deposit_lattice) are the full march's at the even lattice. */
#include <unistd.h>

#include "error_est.h"
#include "test_march_util.h"
#include "vox_code.h"
#include "vox_medium.h"

static int test_precision(clh_context_t *cl) {
  /* a photon of 1e8 sharing 1 W, crossing 0.37 voxel, on a 128^3 grid: the
   * scale the march would choose */
  const double N = 1e8, phi = 1.0 / N, len = 0.37;
  const double diag = sqrt(3.0) * 128.0;
  const double S = pm_fixed_scale(1.0, (PM_MAX_PATH_DIAGONALS + 1.0) * diag);
  const float value = (float)(phi * len * S);
  uint64_t sum;
  double t0 = bk_now_ms();
  if (cl) {
    bk_error_t err;
    memset(&err, 0, sizeof err);
    REQUIRE(pm_deposit_repeat_cl(cl, value, 10000, 10000, &sum, &err) == BK_OK, "%s", err.msg);
  } else {
    sum = pm_deposit_repeat_host(value, (uint64_t)N);
  }
  double ms = bk_now_ms() - t0;
  double exact = N * phi * len, got = (double)sum / S;
  double rel = got / exact - 1.0;
  /* what a float accumulator would have made of it */
  float f = 0.0f;
  for (long i = 0; i < (long)N; i++) f += (float)(phi * len);
  printf("precision (%s): 1e8 deposits of %.3g quanta (scale %.4g per W·voxel): sum %.10g, "
         "exact %.10g, relative error %.2e (limit 1e-5) [%.0f ms]; a float sum gives %.6g (%.1e)\n",
         cl ? "OpenCL atom_add" : "host", (double)value, S, got, exact, rel, ms, (double)f,
         (double)f / exact - 1.0);
  REQUIRE(fabs(rel) < 1e-5, "fixed-point sum off by %.3e", rel);
  return 0;
}

/* The sphere-in-fog scene, coloured, with σ varying inside the sphere. */
static void hvd_scene(volume_t *v, int sphere) {
  const int N = 32;
  tv_alloc(v, N, N, N, 2.0f / N, -1, -1, -1);
  const float ss[3] = {0.5f, 0.4f, 0.3f}, sa[3] = {0.1f, 0.1f, 0.1f};
  tv_fill(v, 1.0f, ss, sa);
  if (sphere) {
    const float c[3] = {0.05f, -0.1f, 0.02f}, osa[3] = {0.3f, 0.2f, 0.1f}, oss[3] = {0, 0, 0};
    tv_ball(v, c, 0.45f, 1.5f, 2.0f, oss, osa);
  }
  tv_summarise(v);
}

static int test_host_vs_device(void) {
  clh_context_t *cl = tm_path("cl");
  scene_light_t lights[2] = {tl_spot(0.1f, 1.7f, -0.2f, 0, -1, 0.1f, 30, 6, 4, 2),
                             tl_point(-0.6f, 0.5f, 0.6f, 1, 1, 1)};
  const char *names[4] = {"constant n (pure DDA)", "sphere, Euler", "sphere, RK4",
                          "sphere, Euler, coded σ"};
  float *plain = NULL; /* the sphere's Euler grid from plain σ arrays */
  for (int m = 0; m < 4; m++) {
    volume_t v;
    hvd_scene(&v, m > 0);
    if (m == 3) { /* σ as the medium's density 1 and a table (kernels/medium_code.h) */
      const float ss[3] = {0.5f, 0.4f, 0.3f}, sa[3] = {0.1f, 0.1f, 0.1f};
      memcpy(v.medium_s, ss, sizeof ss), memcpy(v.medium_a, sa, sizeof sa);
      vox_scan(&v, &v.scan); /* the march's summary, read before the arrays go */
      v.scanned = 1;
      vox_code(&v);
      REQUIRE(v.sigma_code != NULL, "vox_code failed");
    }
    scene_t s;
    ts_init(&s, lights, 2, 20000);
    s.integrator = m == 2 ? INTEGRATOR_RK4 : INTEGRATOR_EULER;
    pm_stats_t sh, sd;
    float *a = tm_bake(NULL, &s, &v, &sh);
    float *b = tm_bake(cl, &s, &v, &sd);
    double l1 = 0.0, ref = 0.0, worst = 0.0, peak = 0.0, tot[2][3] = {{0}};
    size_t n3 = 3 * grid_count(&v.dims);
    for (size_t i = 0; i < n3; i++) {
      REQUIRE(isfinite(a[i]) && isfinite(b[i]), "non-finite radiance");
      l1 += fabs((double)a[i] - b[i]);
      ref += fabs((double)a[i]);
      peak = fmax(peak, a[i]);
      worst = fmax(worst, fabs((double)a[i] - b[i]));
      tot[0][i % 3] += a[i];
      tot[1][i % 3] += b[i];
    }
    double dtot = 0.0;
    for (int c = 0; c < 3; c++) dtot = fmax(dtot, fabs(tot[1][c] / tot[0][c] - 1.0));
    long dsteps = (long)sd.steps - (long)sh.steps;
    printf("host vs device, %-22s: L1 difference %.2e of the total, largest voxel difference "
           "%.2e of the peak, totals %.2e apart; fates host %llu/%llu/%llu device %llu/%llu/%llu "
           "(missed/left/absorbed), steps %+ld of %llu\n",
           names[m], l1 / ref, worst / peak, dtot, (unsigned long long)sh.missed_grid,
           (unsigned long long)sh.left_grid, (unsigned long long)sh.absorbed,
           (unsigned long long)sd.missed_grid, (unsigned long long)sd.left_grid,
           (unsigned long long)sd.absorbed, dsteps, (unsigned long long)sh.steps);
    /* the same float operations on both sides, IEEE division and square
     * root, exp/log/sin/cos of kernels/shared.h instead of libm's and the
     * device's, no fused multiply-add: the same bits (an NVIDIA GPU too,
     * docs/gpu.md) */
    REQUIRE(worst == 0.0, "%s: grids differ: L1 %.3e of the total, largest voxel %.3e of the "
            "peak", names[m], l1 / ref, worst / peak);
    REQUIRE(dtot == 0.0, "%s: totals differ by %.3e", names[m], dtot);
    REQUIRE(sh.missed_grid == sd.missed_grid && sh.step_limit == sd.step_limit,
          "%s: photon fates differ", names[m]);
    if (m == 3) /* coding changes no value the march reads */
      REQUIRE(memcmp(plain, a, n3 * sizeof(float)) == 0, "coded σ: grid differs from plain σ");
    if (m == 1) plain = a;
    else free(a);
    free(b);
    tv_free(&v);
  }
  free(plain);
  return 0;
}

/* Every radiance value finite and >= 0. */
static void check_finite(const float *rad, size_t n3, const char *what) {
  for (size_t i = 0; i < n3; i++)
    REQUIRE(isfinite(rad[i]) && rad[i] >= 0.0f, "%s: radiance[%zu] = %g", what, i, (double)rad[i]);
}

static int test_extremes(clh_context_t *cl) {
  const float ns[2] = {1.0001f, 4.0f}, smooth[2] = {0.5f, 8.0f}, sig[2] = {0.0f, 1e4f};
  const int res[2] = {8, 24};
  for (int r = 0; r < 2; r++)
    for (int a = 0; a < 2; a++)
      for (int b = 0; b < 2; b++)
        for (int c = 0; c < 2; c++) {
          volume_t v;
          tv_alloc(&v, res[r], res[r], res[r], 2.0f / res[r], -1, -1, -1);
          const float ss[3] = {0.5f * sig[c], 0.5f * sig[c], 0.5f * sig[c]};
          tv_fill(&v, 1.0f, ss, ss);
          const float ctr[3] = {0.1f, 0, 0};
          tv_ball(&v, ctr, 0.5f, ns[a], smooth[b], NULL, NULL);
          tv_summarise(&v);
          scene_light_t lights[3] = {tl_spot(0, 1.5f, 0, 0, -1, 0, 40, 3, 3, 3),
                                     tl_point(0.3f, 0.1f, 0.05f, 1, 1, 1),
                                     tl_directional(1, -2, 0.5f, 1)};
          scene_t s;
          ts_init(&s, lights, 3, 3000);
          s.integrator = (a + b + c) % 2 ? INTEGRATOR_RK4 : INTEGRATOR_EULER;
          pm_stats_t st;
          float *rad = tm_bake(cl, &s, &v, &st);
          char what[160];
          snprintf(what, sizeof what, "%2d^3, n %.4f, smoothing %.1f, sigma_t %g, %s", res[r],
                   (double)ns[a], (double)smooth[b], (double)sig[c] * 1.0,
                   s.integrator ? "RK4" : "Euler");
          check_finite(rad, 3 * grid_count(&v.dims), what);
          printf("extremes %s: %llu left, %llu absorbed, %llu step limit, %llu steps\n", what,
                 (unsigned long long)st.left_grid, (unsigned long long)st.absorbed,
                 (unsigned long long)st.step_limit, (unsigned long long)st.steps);
          if (sig[c] > 0.0f) REQUIRE(st.absorbed > 0, "%s: nothing absorbed", what);
          else REQUIRE(st.absorbed == 0, "%s: absorbed in a clear medium", what);
          free(rad);
          tv_free(&v);
        }

  /* total internal reflection: a point light inside a ball of n = 4 (critical
   * angle 14.5°), off centre, traps most of its photons (RK4: the paper's
   * Euler lets them leak, kernels/photon_march.h); with a tiny step it is
   * PM_MAX_STEPS that stops them, with the default one the path cap */
  const float steps[2] = {0.5f, 0.005f};
  for (int q = 0; q < 2; q++) {
    volume_t v;
    tv_alloc(&v, 32, 32, 32, 2.0f / 32, -1, -1, -1);
    const float zero[3] = {0, 0, 0};
    tv_fill(&v, 1.0f, zero, zero);
    const float ctr[3] = {0, 0, 0};
    tv_ball(&v, ctr, 0.7f, 4.0f, 2.0f, NULL, NULL);
    tv_summarise(&v);
    scene_light_t light = tl_point(0.5f, 0.02f, 0.01f, 1, 1, 1);
    scene_t s;
    ts_init(&s, &light, 1, q ? 40 : 400);
    s.step = steps[q];
    s.integrator = INTEGRATOR_RK4;
    pm_stats_t st;
    double t0 = bk_now_ms();
    float *rad = tm_bake(cl, &s, &v, &st);
    double ms = bk_now_ms() - t0;
    check_finite(rad, 3 * grid_count(&v.dims), "TIR");
    printf("TIR, step %.3f voxel: %llu photons: %llu left, %llu stopped at the step limit, %llu "
           "steps [%.0f ms]\n",
           (double)steps[q], (unsigned long long)st.photons, (unsigned long long)st.left_grid,
           (unsigned long long)st.step_limit, (unsigned long long)st.steps, ms);
    REQUIRE(st.step_limit > st.photons / 4, "too few photons trapped: %llu",
          (unsigned long long)st.step_limit);
    if (!cl) {
      /* one trapped photon, traced: which limit stopped it */
      pm_setup_t su;
      bk_error_t err;
      REQUIRE(pm_prepare(&s, &v, &su, NULL, NULL, &err) == BK_OK, "%s", err.msg);
      int found = 0;
      for (uint32_t i = 0; i < su.lights.photons && !found; i++) {
        static float pts[3 * 16];
        int count;
        pm_result r;
        REQUIRE(pm_trace_photon(&su, i, pts, 16, &count, &r, &err) == BK_OK, "%s", err.msg);
        if (r.fate != PM_FATE_STEP_LIMIT) continue;
        found = 1;
        printf("  trapped photon %u: %u steps (PM_MAX_STEPS %d), path %.0f voxels (cap %.0f)\n", i,
               r.steps, PM_MAX_STEPS, (double)r.path, (double)su.params.path_cap);
        if (q) REQUIRE(r.steps == PM_MAX_STEPS, "expected the step limit, got %u steps", r.steps);
        else REQUIRE(r.path >= su.params.path_cap, "expected the path cap");
      }
      REQUIRE(found, "no trapped photon found");
      pm_setup_free(&su);
    }
    free(rad);
    tv_free(&v);
  }
  return 0;
}

static uint64_t mem_available(void) {
  FILE *f = fopen("/proc/meminfo", "r");
  char line[256];
  unsigned long long kb = 0;
  if (!f) return 0;
  while (fgets(line, sizeof line, f))
    if (sscanf(line, "MemAvailable: %llu kB", &kb) == 1) break;
  fclose(f);
  return (uint64_t)kb * 1024;
}

/* 512^3 with a ball (n and ∇n, the pyramid, the counters: about 9 GiB in
 * all on the host), a handful of photons. */
static int test_extremes_512(void) {
  const uint64_t need = 12ull << 30;
  if (mem_available() < need) {
    printf("extremes 512^3: skipped, %.1f GiB available, %.0f GiB wanted\n",
           mem_available() / 1073741824.0, need / 1073741824.0);
    return 77;
  }
  volume_t v;
  const int N = 512;
  tv_alloc(&v, N, N, N, 2.0f / N, -1, -1, -1);
  const float ss[3] = {0.2f, 0.2f, 0.2f}, sa[3] = {0.01f, 0.01f, 0.01f};
  tv_fill(&v, 1.0f, ss, sa);
  const float ctr[3] = {0, 0, 0};
  tv_ball(&v, ctr, 0.4f, 1.5f, 2.0f, NULL, NULL);
  tv_summarise(&v);
  scene_light_t light = tl_spot(0, 1.5f, 0, 0, -1, 0, 20, 1, 1, 1);
  scene_t s;
  ts_init(&s, &light, 1, 64);
  pm_stats_t st;
  double t0 = bk_now_ms();
  float *rad = tm_bake(NULL, &s, &v, &st);
  double ms = bk_now_ms() - t0;
  check_finite(rad, 3 * grid_count(&v.dims), "512^3");
  double sum = 0.0;
  for (size_t i = 0; i < 3 * grid_count(&v.dims); i++) sum += rad[i];
  printf("extremes 512^3: %llu photons, %llu left, %llu steps, radiance sum %.4g, octree %.0f ms, "
         "march %.0f ms, all %.0f ms\n",
         (unsigned long long)st.photons, (unsigned long long)st.left_grid,
         (unsigned long long)st.steps, sum, st.ms_octree, st.ms_march, ms);
  REQUIRE(st.left_grid == st.photons - st.missed_grid && sum > 0.0, "512^3: photons lost");
  free(rad);
  tv_free(&v);
  return 0;
}

/* A twin march that keeps only the even lattice (pm_deposit_lattice) holds
 * the full march's sums there, bit for bit, packed; on an odd-sized grid
 * (the lattice rounds up), refracting ball, RGB, single and multiple
 * scattering. */
static int test_lattice(clh_context_t *cl) {
  volume_t v;
  tv_alloc(&v, 33, 31, 29, 2.0f / 33, -1, -1, -1);
  const float ss[3] = {0.5f, 0.4f, 0.3f}, sa[3] = {0.1f, 0.1f, 0.1f};
  tv_fill(&v, 1.0f, ss, sa);
  const float c[3] = {0.05f, -0.1f, 0.02f}, osa[3] = {0.3f, 0.2f, 0.1f}, oss[3] = {0, 0, 0};
  tv_ball(&v, c, 0.45f, 1.5f, 2.0f, oss, osa);
  tv_summarise(&v);
  scene_light_t lights[1] = {tl_spot(0.1f, 1.7f, -0.2f, 0, -1, 0.1f, 30, 6, 4, 2)};
  for (int bounces = 0; bounces <= 4; bounces += 4) {
    scene_t s;
    ts_init(&s, lights, 1, 20000);
    s.bounces = bounces;
    pm_setup_t full;
    bk_error_t err = {0};
    pm_stats_t st;
    REQUIRE(pm_prepare(&s, &v, &full, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
    pm_setup_t packed = full; /* a shallow copy: full owns the arrays */
    pm_deposit_lattice(&packed);
    const size_t ch = (size_t)full.channels, lat = (size_t)17 * 16 * 15;
    REQUIRE(pm_acc_count(&packed) == lat * ch, "packed sums: %zu, expected %zu",
            pm_acc_count(&packed), lat * ch);
    uint64_t *a = calloc(pm_acc_count(&full), sizeof *a), *b = calloc(lat * ch, sizeof *b);
    REQUIRE(a && b, "out of memory");
    for (int r = 0; r < 2; r++) {
      memset(&st, 0, sizeof st);
      const pm_setup_t *su = r ? &packed : &full;
      int rc = cl ? pm_run_cl(cl, su, r ? b : a, &st, &err) : pm_run_host(su, r ? b : a, &st, &err);
      REQUIRE(rc == BK_OK, "march: %s", err.msg);
    }
    size_t differ = 0, lit = 0;
    for (size_t k = 0; k < lat; k++)
      for (size_t j = 0; j < ch; j++) {
        const uint64_t want = a[ee_lattice_voxel(&full.dims, k) * ch + j];
        differ += want != b[k * ch + j];
        lit += want != 0;
      }
    printf("lattice (%s, bounces %d): %zu of %zu packed sums differ, %zu lit\n",
           cl ? "OpenCL" : "host", bounces, differ, lat * ch, lit);
    EXPECT(differ == 0 && lit > lat * ch / 2, "packed sums differ or too few lit");
    free(a);
    free(b);
    pm_setup_free(&full);
  }
  tv_free(&v);
  return tu_failures;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: test_march_robust TEST [host|cl]\n");
    return 2;
  }
  bk_verbosity = 0;
  const char *t = argv[1];
  int rc = 2;
  if (!strcmp(t, "precision")) rc = test_precision(tm_path(argc > 2 ? argv[2] : "host"));
  else if (!strcmp(t, "host_vs_device")) rc = test_host_vs_device();
  else if (!strcmp(t, "extremes")) rc = test_extremes(tm_path(argc > 2 ? argv[2] : "host"));
  else if (!strcmp(t, "extremes_512")) rc = test_extremes_512();
  else if (!strcmp(t, "lattice")) rc = test_lattice(tm_path(argc > 2 ? argv[2] : "host"));
  else fprintf(stderr, "unknown test %s\n", t);
  if (tm_cl_ready) clh_release(&tm_cl_ctx);
  return rc;
}
