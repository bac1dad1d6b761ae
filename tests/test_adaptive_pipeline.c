/* test_adaptive_pipeline.c: the adaptive pipeline end to end (ad_bake on
 * OpenCL, PoCL), against the reference march. The sphere scene
 * (scenes/sphere.json: an n = 1.5 ball in fog under a spot light) at 64^3
 * instead of its 128^3, so that each test takes seconds on 2 cores; at 64^3
 * the photons per voxel column of N/4 photons match those of N at 128^3, so
 * photon counts are quoted both ways.
 *
 * Error metric everywhere: the relative L2 error over the radiance grid,
 *   e(X, T) = sqrt(sum_v,c (X - T)^2 / sum_v,c T^2),
 * over all voxels and the three channels. The reference is the reference
 * mode as a bake runs it (bt_bake, photons.batches batches), as the
 * adaptive march is.
 *
 * Usage: test_adaptive_pipeline SCENE_DIR OUT_DIR TEST, TEST one of
 *  unbiased        filter off, 300 000 photons each in 2 batches: adaptive
 *                  within 1% of the reference, with a PDF far from uniform;
 *                  the same with the tables rebuilt between the batches
 *  lights          a faint light the pilot gives no photon, listed first:
 *                  each light keeps its own PDF, the estimate its bias-free
 *                  agreement
 *  quality         at a converged step (RK4, 1/4 voxel), adaptive with half
 *                  the photons (pilot included): true error ε (docs/error.md;
 *                  truth RK4 1/8 voxel, 32x the photons) and relative L2 no
 *                  worse than the reference pipeline's with all of them
 *  estimate        the filtered bake's ε̂ (noise, the filter's bias, the
 *                  step) within [0.75, 1.33] x its true ε over 4 seeds at
 *                  2N, 1.5N and N photons (docs/error.md, "The filter");
 *                  photons.target_error stops on it: ε̂ <= E, the true ε at
 *                  most 1.3 E, in fewer batches than the unfiltered bake
 *  filter_radius   the radius grid: small across the caustic's sharp edges,
 *                  large in the smooth lit fog (voxels told apart by the
 *                  gradient of a converged bake)
 *  host_vs_device  the adaptive bake on the host C path and on OpenCL
 *  cli             baker bake --mode adaptive: the grids photon_count,
 *                  photon_weight, filter_radius and the metadata */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adaptive.h"
#include "bake.h"
#include "batches.h"
#include "vdbio.h"
#include "voxelize.h"
#include "test_util.h"

#define TEST_RES 64
/* 122 000 photons at 128^3 (the slides' reference count) have the photons
 * per voxel column of 30 500 at 64^3 */
#define TEST_N 30500

static const char *scene_dir, *out_dir;
static clh_context_t cl;
static scene_t scene;
static volume_t vol;
static size_t V;

static void setup(int with_cl, int resolution) {
  bk_error_t err;
  char path[1024];
  memset(&err, 0, sizeof err);
  snprintf(path, sizeof path, "%s/sphere.json", scene_dir);
  REQUIRE(scene_load(path, &scene, &err) == BK_OK, "%s", err.msg);
  scene.resolution = resolution;
  /* the adaptive pipeline's accuracy, measured as before photons.bounces:
   * single scattering (multiple scattering has tests/test_scatter.c) */
  scene.bounces = 0;
  REQUIRE(vox_build(&scene, &vol, NULL, &err) == BK_OK, "%s", err.msg);
  V = grid_count(&vol.dims);
  if (with_cl) REQUIRE(clh_init(&cl, NULL, &err) == BK_OK, "clh_init: %s", err.msg);
}

static float *grid3(void) {
  float *g = calloc(3 * V, sizeof(float));
  REQUIRE(g, "out of memory");
  return g;
}
static float *grid1(void) {
  float *g = calloc(V, sizeof(float));
  REQUIRE(g, "out of memory");
  return g;
}

/* The reference mode as a bake runs it: in scene.batches batches
 * (batches.h), like the adaptive march. */
static float *reference(clh_context_t *c, long long photons, double *ms) {
  bk_error_t err;
  pm_stats_t st;
  bt_options_t o = {0};
  bt_result_t res;
  memset(&err, 0, sizeof err);
  float *r = grid3();
  scene.photon_count = photons;
  double t0 = bk_now_ms();
  REQUIRE(bt_bake(c, &scene, &vol, &o, r, &res, &st, NULL, &err) == BK_OK, "bt_bake: %s",
          err.msg);
  if (ms) *ms = bk_now_ms() - t0;
  return r;
}

/* The relative L2 of a against b (RGB grids) over the means of 4^3-voxel
 * blocks of channel 0: the photon noise averages down by about 8, a bias
 * over a region does not. */
static double block_rel_l2(const float *a, const float *b) {
  const grid_dims_t *d = &vol.dims;
  const int B = 4, bx = (d->nx + B - 1) / B, by = (d->ny + B - 1) / B, bz = (d->nz + B - 1) / B;
  double *sa = calloc((size_t)bx * by * bz, sizeof(double));
  double *sb = calloc((size_t)bx * by * bz, sizeof(double));
  double num = 0.0, den = 0.0;
  REQUIRE(sa && sb, "out of memory");
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        size_t v = grid_index(d, i, j, k);
        size_t c = (size_t)(i / B) + (size_t)bx * (j / B + (size_t)by * (k / B));
        sa[c] += a[3 * v], sb[c] += b[3 * v];
      }
  for (size_t c = 0; c < (size_t)bx * by * bz; c++)
    num += (sa[c] - sb[c]) * (sa[c] - sb[c]), den += sb[c] * sb[c];
  free(sa), free(sb);
  return den > 0.0 ? sqrt(num / den) : 0.0;
}

static int retable; /* the allocation loop (ad_loop_t) */

static float *adaptive(clh_context_t *c, long long photons, int filter, float *count,
                       float *weight, float *radius, ad_stats_t *st) {
  bk_error_t err;
  ad_bake_opts_t o;
  memset(&err, 0, sizeof err);
  ad_bake_defaults(&o);
  o.filter = filter;
  o.retable = retable;
  float *r = grid3();
  scene.photon_count = photons;
  REQUIRE(ad_bake(c, &scene, &vol, &o, r, count, weight, radius, st, NULL, &err) == BK_OK,
        "ad_bake: %s", err.msg);
  REQUIRE(st->march.photons == (uint64_t)photons, "%llu photons marched, %lld asked",
        (unsigned long long)st->march.photons, photons);
  return r;
}

/* --- unbiased -------------------------------------------------------------- */

static int test_unbiased(void) {
  setup(1, TEST_RES);
  const long long N = 300000;
  /* both in 2 batches: the batched march (its tables may change between
   * batches) at a noise 1% can see; 8 batches of 37500 differ by 1.7% */
  scene.batches = 2;
  ad_stats_t st;
  float *count = grid1(), *weight = grid1();
  float *ref = reference(&cl, N, NULL);
  float *ad = adaptive(&cl, N, 0, count, weight, NULL, &st);
  double e = tu_rel_l2(ad, ref, 3 * V), sum_r = 0.0, sum_a = 0.0, wmin = 1e30, wmax = 0.0;
  size_t reached = 0;
  for (size_t v = 0; v < V; v++) {
    sum_r += ref[3 * v];
    sum_a += ad[3 * v];
    if (count[v] > 0.0f) {
      reached++;
      wmin = fmin(wmin, weight[v]);
      wmax = fmax(wmax, weight[v]);
    }
  }
  printf("unbiased: %dx%dx%d, %lld photons each (pilot %d): relative L2 adaptive (no filter) vs "
         "reference %.4f; total radiance ratio %.5f; pdf %.2f..%.2f over the light's cells, mean "
         "photon weight %.2f..%.2f over %zu reached voxels\n",
         vol.dims.nx, vol.dims.ny, vol.dims.nz, N, st.pilot_photons, e, sum_a / sum_r,
         (double)st.pdf_min, (double)st.pdf_max, wmin, wmax, reached);
  /* the estimate is unbiased only if the photons really were redistributed:
   * a uniform PDF would pass trivially */
  REQUIRE(st.pdf_max > 1.3f && st.pdf_min < 0.9f, "the PDF is nearly uniform (%.2f..%.2f)",
        (double)st.pdf_min, (double)st.pdf_max);
  REQUIRE(wmax / wmin > 1.5, "photon weights %.2f..%.2f: nearly uniform", wmin, wmax);
  REQUIRE(e < 0.01, "adaptive (no filter) differs from the reference by %.4f (limit 0.01)", e);
  REQUIRE(fabs(sum_a / sum_r - 1.0) < 0.003, "total radiance off by %.4f", sum_a / sum_r - 1.0);
  /* the tables rebuilt between the batches (after the second, which is
   * when a spread exists): still unbiased */
  retable = 1, scene.batches = 3;
  float *loop = adaptive(&cl, N, 0, count, weight, NULL, &st);
  retable = 0, scene.batches = 2;
  double el = tu_rel_l2(loop, ref, 3 * V), bl = block_rel_l2(loop, ref), sum_l = 0.0;
  for (size_t v = 0; v < V; v++) sum_l += loop[3 * v];
  printf("unbiased, tables rebuilt after each batch (%d times): relative L2 vs reference %.4f, "
         "over 4^3 block means %.4f (pilot tables: %.4f)\n",
         st.retabled, el, bl, block_rel_l2(ad, ref));
  REQUIRE(st.retabled >= 1, "the loop rebuilt no table");
  /* the loop's third batch is drawn from tables that follow the measured
   * spread, so per voxel it is a little noisier than the pilot's (measured
   * 0.0100-0.0101); a bias would not average out over the blocks */
  REQUIRE(el < 0.012, "adaptive with the loop differs from the reference by %.4f", el);
  REQUIRE(bl < 0.003, "adaptive with the loop differs from the reference by %.4f over blocks", bl);
  REQUIRE(fabs(sum_l / sum_r - 1.0) < 0.003, "loop: total radiance off by %.4f",
          sum_l / sum_r - 1.0);
  free(loop);
  free(count);
  free(weight);
  free(ref);
  free(ad);
  return 0;
}

/* --- lights ---------------------------------------------------------------- */

/* A faint point light listed before the spot: the pilot gives it no photon
 * (its share of 4000 rounds to 0) while the main march does, so the two
 * marches number their lights differently; each light must still get its
 * own PDF, and the estimate stay unbiased. */
static int test_lights(void) {
  setup(1, TEST_RES);
  scene_light_t lights[2];
  memset(&lights[0], 0, sizeof lights[0]);
  lights[0].type = LIGHT_POINT;
  lights[0].position[0] = 0.5f, lights[0].position[1] = -0.5f, lights[0].position[2] = 0.3f;
  /* the spot emits 10 W/sr into 0.38 sr: 3.8 W; this one 1e-3 of the
   * pilot's 1/4000 */
  for (int c = 0; c < 3; c++) lights[0].intensity[c] = 3.8e-7f / (4.0f * 3.14159265f);
  /* the scene's own array is put back before returning: overwriting it lost
   * the allocation (a LeakSanitizer report) and left a stack pointer behind */
  scene_light_t *own = scene.lights;
  int own_count = scene.light_count;
  lights[1] = own[0];
  scene.lights = lights;
  scene.light_count = 2;
  /* one batch: this tests the lights' numbering (test_unbiased the
   * batches); in 2 batches the two estimates differ by 1.02% */
  scene.batches = 1;
  const long long N = 300000;
  ad_stats_t st;
  float *count = grid1(), *weight = grid1();
  float *ref = reference(&cl, N, NULL);
  float *ad = adaptive(&cl, N, 0, count, weight, NULL, &st);
  double e = tu_rel_l2(ad, ref, 3 * V), wmin = 1e30, wmax = 0.0;
  /* voxels the spot's photons cross by the dozen: their mean weight shows
   * whether the spot's photons followed a PDF (a uniform one gives 1) */
  for (size_t v = 0; v < V; v++)
    if (count[v] >= 50.0f) {
      wmin = fmin(wmin, weight[v]);
      wmax = fmax(wmax, weight[v]);
    }
  printf("lights: a faint point light before the spot, %lld photons: pilot %llu photons, pdf "
         "%.2f..%.2f, mean weights %.2f..%.2f where 50+ photons passed, relative L2 adaptive "
         "(no filter) vs reference %.4f\n",
         N, (unsigned long long)st.pilot.photons, (double)st.pdf_min, (double)st.pdf_max, wmin,
         wmax, e);
  REQUIRE(wmin < 0.8 && wmax > 1.5, "the spot's photons did not follow its PDF");
  REQUIRE(e < 0.01, "adaptive differs from the reference by %.4f", e);
  scene.lights = own;
  scene.light_count = own_count;
  free(count);
  free(weight);
  free(ref);
  free(ad);
  return 0;
}

/* --- quality --------------------------------------------------------------- */

/* The truth of docs/error.md: RK4 at 1/8 voxel, 32x the photons, in 8
 * batches, seeded apart from the runs (as scripts/bench_error_run's). */
static float *truth(long long photons, double *ms) {
  integrator_t integ = scene.integrator;
  float step = scene.step;
  int batches = scene.batches;
  unsigned seed = scene.seed;
  scene.integrator = INTEGRATOR_RK4, scene.step = 0.125f, scene.batches = 8;
  scene.seed = seed + 1000;
  float *t = reference(&cl, photons, ms);
  scene.integrator = integ, scene.step = step, scene.batches = batches, scene.seed = seed;
  return t;
}

/* Issue 12's test: at a converged step (RK4, 1/4 voxel), so that noise is
 * what sampling can change, adaptive with half the photons (its pilot
 * included) has a true error ε no larger than the reference with all of
 * them, and no larger a relative L2 over all voxels. */
static int test_quality(void) {
  setup(1, TEST_RES);
  const long long N = TEST_N;
  ad_stats_t st;
  double ms_truth;
  scene.integrator = INTEGRATOR_RK4, scene.step = 0.25f;
  float *T = truth(32 * N, &ms_truth);
  float *ref = reference(&cl, N, NULL);
  /* the pilot scaled with the grid like N (4000 at 128^3, 1000 here: the
   * same photons per pilot cell) */
  scene.pilot /= 4;
  long long half = N / 2 - scene.pilot;
  float *ad = adaptive(&cl, half, 1, NULL, NULL, NULL, &st);
  float *raw = adaptive(&cl, half, 0, NULL, NULL, NULL, &st);
  double eps_ref = ee_true_error(ref, T, V), eps_ad = ee_true_error(ad, T, V);
  double e_ref = tu_rel_l2(ref, T, 3 * V), e_ad = tu_rel_l2(ad, T, 3 * V);
  printf("quality: %dx%dx%d (the sphere scene's 128^3 reduced; %lld photons here are %lld at "
         "128^3), RK4 at 1/4 voxel; truth RK4 1/8 with %lld photons (%.0f ms). Reference with "
         "%lld photons: true eps %.4f, relative L2 %.4f; adaptive with %lld + %d pilot = %lld "
         "photons: %.4f (%.2f of the reference's), %.4f (%.2f); unfiltered eps %.4f\n",
         vol.dims.nx, vol.dims.ny, vol.dims.nz, N, 4 * N, 32 * N, ms_truth, N, eps_ref, e_ref,
         half, scene.pilot, half + scene.pilot, eps_ad, eps_ad / eps_ref, e_ad, e_ad / e_ref,
         ee_true_error(raw, T, V));
  REQUIRE(eps_ad <= eps_ref, "adaptive with half the photons: true eps %.4f, reference with all %.4f",
          eps_ad, eps_ref);
  REQUIRE(e_ad <= e_ref, "adaptive with half the photons: relative L2 %.4f, reference with all %.4f",
          e_ad, e_ref);
  free(T);
  free(ref);
  free(ad);
  free(raw);
  return 0;
}

/* --- estimate -------------------------------------------------------------- */

/* photons.target_error E with the filter on and off: one target bake. */
static float *target_bake(int filter, float E, ad_stats_t *st) {
  bk_error_t err = {0, ""};
  ad_bake_opts_t o;
  ad_bake_defaults(&o);
  o.filter = filter;
  float *ad = grid3();
  scene.seed = 1, scene.photon_count = 40000, scene.target_error = E;
  REQUIRE(ad_bake(&cl, &scene, &vol, &o, ad, NULL, NULL, NULL, st, NULL, &err) == BK_OK,
          "ad_bake: %s", err.msg);
  scene.target_error = 0.0f;
  return ad;
}

/* A target stops on the estimate of the grid written, the filtered one:
 * sooner than on the raw mean's (which the unfiltered bake stops on, as
 * the filtered one did before 2026-11-29: 5 batches here, against 2 now),
 * with its true error within 1.3 E. */
static void target_case(const float *T) {
  const float E = 0.05f;
  ad_stats_t on, off;
  float *ad = target_bake(1, E, &on);
  free(target_bake(0, E, &off));
  const double est = on.error.terms.estimate, eps = ee_true_error(ad, T, V);
  printf("target %g: filtered, %d batches of %llu photons: estimate %.4f, true %.4f; "
         "unfiltered: %d batches of %llu\n", (double)E, on.error.batches,
         (unsigned long long)on.error.batch_photons, est, eps, off.error.batches,
         (unsigned long long)off.error.batch_photons);
  EXPECT(!on.error.target_missed && est <= E, "target %g: estimate %.4f", (double)E, est);
  EXPECT(eps <= 1.3 * E, "target %g: true error %.4f", (double)E, eps);
  EXPECT(on.error.batches < off.error.batches, "target %g: %d batches filtered, %d unfiltered",
         (double)E, on.error.batches, off.error.batches);
  free(ad);
}

/* The adaptive bake's ε̂ against its true ε, filter on, at a converged step,
 * over seeds and photon counts: the filter's bias term must follow the bias
 * whatever the noise did (the rule before 2026-11-29, filtered minus raw
 * less its noise, gave 0.73-1.80 x ε on these bakes; this rule 0.80-0.94). */
static int test_estimate(void) {
  setup(1, TEST_RES);
  scene.integrator = INTEGRATOR_RK4, scene.step = 0.25f;
  float *T = truth(32 * TEST_N, NULL);
  const long long photons[] = {2 * TEST_N, 3 * TEST_N / 2, TEST_N};
  double lo = HUGE_VAL, hi = 0.0;
  for (unsigned seed = 1; seed <= 4; seed++)
    for (int p = 0; p < 3; p++) {
      ad_stats_t st;
      scene.seed = seed;
      float *ad = adaptive(&cl, photons[p] - scene.pilot, 1, NULL, NULL, NULL, &st);
      const ee_terms_t *e = &st.error.terms;
      const double eps = ee_true_error(ad, T, V), r = e->estimate / eps;
      printf("estimate: seed %u, %lld photons: %.4f (noise %.4f, filter %.4f, step %.4f), "
             "true %.4f, ratio %.2f\n", seed, photons[p], e->estimate, e->noise, e->filter,
             e->step, eps, r);
      lo = fmin(lo, r), hi = fmax(hi, r);
      free(ad);
    }
  EXPECT(lo >= 0.75 && hi <= 1.33, "estimate / true error in [%.2f, %.2f], expected within "
         "[0.75, 1.33]", lo, hi);
  target_case(T);
  free(T);
  return tu_failures ? 1 : 0;
}

/* --- filter_radius --------------------------------------------------------- */

static int cmp_float(const void *a, const void *b) {
  float x = *(const float *)a, y = *(const float *)b;
  return (x > y) - (x < y);
}

static int test_filter_radius(void) {
  setup(1, TEST_RES);
  const grid_dims_t *d = &vol.dims;
  ad_stats_t st;
  float *conv = reference(&cl, 20 * TEST_N, NULL);
  float *radius = grid1();
  float *ad = adaptive(&cl, TEST_N, 1, NULL, NULL, radius, &st);
  /* luminance and its gradient (per voxel, central differences) of the
   * converged bake */
  float *lum = grid1(), *grad = grid1(), *tmp = grid1();
  for (size_t v = 0; v < V; v++) lum[v] = ad_luminance(conv[3 * v], conv[3 * v + 1], conv[3 * v + 2]);
  size_t lit = 0;
  for (int k = 1; k < d->nz - 1; k++)
    for (int j = 1; j < d->ny - 1; j++)
      for (int i = 1; i < d->nx - 1; i++) {
        size_t v = grid_index(d, i, j, k);
        float gx = 0.5f * (lum[v + 1] - lum[v - 1]);
        float gy = 0.5f * (lum[v + d->nx] - lum[v - d->nx]);
        float gz = 0.5f * (lum[v + (size_t)d->nx * d->ny] - lum[v - (size_t)d->nx * d->ny]);
        grad[v] = sqrtf(gx * gx + gy * gy + gz * gz);
        if (lum[v] > 0.0f) tmp[lit++] = grad[v] / lum[v];
      }
  /* sharp: the 1% of lit voxels with the largest relative gradient (the
   * caustic's and the shadow's edges, the rim of the light's cone); smooth:
   * lit voxels at least the median luminance whose relative gradient is in
   * the lowest half, interior voxels only */
  qsort(tmp, lit, sizeof(float), cmp_float);
  float sharp_thr = tmp[(size_t)(0.99 * (lit - 1))], smooth_thr = tmp[(lit - 1) / 2];
  size_t nl = 0;
  for (size_t v = 0; v < V; v++)
    if (lum[v] > 0.0f) tmp[nl++] = lum[v];
  qsort(tmp, nl, sizeof(float), cmp_float);
  float lum_med = tmp[(nl - 1) / 2];
  double r_sharp = 0.0, r_smooth = 0.0;
  size_t n_sharp = 0, n_smooth = 0, sharp_small = 0;
  for (int k = 1; k < d->nz - 1; k++)
    for (int j = 1; j < d->ny - 1; j++)
      for (int i = 1; i < d->nx - 1; i++) {
        size_t v = grid_index(d, i, j, k);
        if (!(lum[v] > 0.0f)) continue;
        float rel = grad[v] / lum[v];
        if (rel >= sharp_thr) {
          r_sharp += radius[v];
          sharp_small += radius[v] <= 0.5f;
          n_sharp++;
        } else if (rel <= smooth_thr && lum[v] >= lum_med) {
          r_smooth += radius[v];
          n_smooth++;
        }
      }
  r_sharp /= n_sharp;
  r_smooth /= n_smooth;
  printf("filter_radius: %dx%dx%d, %d photons, largest radius %g voxels: mean radius %.3f over "
         "%zu sharp voxels (%.1f%% at most 1/2 voxel), %.3f over %zu smooth lit voxels\n",
         d->nx, d->ny, d->nz, TEST_N, (double)st.max_radius, r_sharp, n_sharp,
         100.0 * sharp_small / n_sharp, r_smooth, n_smooth);
  /* the default largest radius is 1 voxel (levels 0, 1/2, 1): sharp voxels
   * keep their own value or the narrowest Gaussian, smooth ones mostly the
   * widest */
  REQUIRE(n_sharp > 100 && n_smooth > 1000, "too few voxels classified");
  REQUIRE(sharp_small >= 0.9 * n_sharp, "sharp voxels: mean radius %.3f of at most %g, %zu of %zu "
        "at most 1/2", r_sharp, (double)st.max_radius, sharp_small, n_sharp);
  REQUIRE(r_smooth >= 0.75 * st.max_radius, "smooth voxels: mean radius %.3f of at most %g",
        r_smooth, (double)st.max_radius);
  REQUIRE(r_smooth >= 1.6 * r_sharp, "smooth %.3f vs sharp %.3f: not told apart", r_smooth, r_sharp);
  free(conv);
  free(radius);
  free(ad);
  free(lum);
  free(grad);
  free(tmp);
  return 0;
}

/* --- host_vs_device -------------------------------------------------------- */

static int test_host_vs_device(void) {
  setup(1, 40);
  ad_stats_t sh, sd;
  const long long N = 20000;
  float *ch = grid1(), *wh = grid1(), *rh = grid1(), *cd = grid1(), *wd = grid1(), *rd = grid1();
  float *h = adaptive(NULL, N, 1, ch, wh, rh, &sh);
  float *dv = adaptive(&cl, N, 1, cd, wd, rd, &sd);
  size_t count_diff = 0, radius_diff = 0;
  double wdiff = 0.0;
  for (size_t v = 0; v < V; v++) {
    count_diff += ch[v] != cd[v];
    radius_diff += rh[v] != rd[v];
    wdiff = fmax(wdiff, fabs(wh[v] - wd[v]));
  }
  double e = tu_rel_l2(dv, h, 3 * V);
  printf("host_vs_device: %dx%dx%d, %lld photons: relative L2 host vs OpenCL %.2e; %zu photon "
         "counts and %zu radii differ, mean weights by %.2e at most; pdf %.3f..%.3f vs "
         "%.3f..%.3f; selected cells %zu vs %zu\n",
         vol.dims.nx, vol.dims.ny, vol.dims.nz, N, e, count_diff, radius_diff, wdiff,
         (double)sh.pdf_min, (double)sh.pdf_max, (double)sd.pdf_min, (double)sd.pdf_max,
         sh.select.selected, sd.select.selected);
  REQUIRE(sh.select.selected == sd.select.selected && sh.pdf_max == sd.pdf_max,
        "the pilots differ");
  /* the fixed-point sums are exact; only float rounding of the march may
   * move a photon by an ulp */
  REQUIRE(e < 1e-4, "host and OpenCL differ by %.2e", e);
  REQUIRE(count_diff <= V / 1000 && radius_diff <= V / 1000, "counts or radii differ");
  free(ch);
  free(wh);
  free(rh);
  free(cd);
  free(wd);
  free(rd);
  free(h);
  free(dv);
  return 0;
}

/* --- cli ------------------------------------------------------------------- */

static void expect_meta(const char *path, const char *key, const char *want) {
  char got[256];
  bk_error_t err;
  memset(&err, 0, sizeof err);
  REQUIRE(vdbio_read_meta(path, key, got, sizeof got, &err) == BK_OK, "%s", err.msg);
  REQUIRE(got[0], "%s: no metadata %s", path, key);
  if (want) REQUIRE(strcmp(got, want) == 0, "%s: %s = %s, expected %s", path, key, got, want);
}

static int has_grid(const char *path, const char *name) {
  char **names, **types;
  int n, found = 0;
  bk_error_t err;
  memset(&err, 0, sizeof err);
  REQUIRE(vdbio_list_grids(path, &names, &types, &n, &err) == BK_OK, "%s", err.msg);
  for (int i = 0; i < n; i++) found |= strcmp(names[i], name) == 0;
  vdbio_free_names(names, types, n);
  return found;
}

static int test_cli(void) {
  char scene_path[1024], out[1024], out2[1024];
  snprintf(scene_path, sizeof scene_path, "%s/sphere.json", scene_dir);
  snprintf(out, sizeof out, "%s/adaptive_cli.vdb", out_dir);
  snprintf(out2, sizeof out2, "%s/adaptive_cli_nofilter.vdb", out_dir);
  char *a1[] = {"bake", scene_path, "-o", out, "--mode", "adaptive", "--resolution", "32",
                "--photons", "6000", "--write-filter-radius", "--force", "-q"};
  REQUIRE(bake_main((int)(sizeof a1 / sizeof a1[0]), a1) == 0, "bake --mode adaptive failed");
  const char *grids[] = {"radiance", "ior", "density", "photon_count", "photon_weight",
                         "filter_radius"};
  for (size_t i = 0; i < sizeof grids / sizeof grids[0]; i++)
    REQUIRE(has_grid(out, grids[i]), "%s has no grid %s", out, grids[i]);
  expect_meta(out, "mode", "adaptive");
  expect_meta(out, "photon_count", "6000");
  expect_meta(out, "adaptive_pilot_photons", "4000");
  expect_meta(out, "adaptive_gradient_threshold", NULL);
  expect_meta(out, "adaptive_gradient_threshold_rule", "auto");
  expect_meta(out, "adaptive_luminance_threshold", NULL);
  expect_meta(out, "adaptive_luminance_threshold_rule", "auto");
  expect_meta(out, "adaptive_filter", "on");
  /* the grids hold what the bake computed: counts are whole numbers, the
   * mean weights within the PDF's bounds, radii multiples of 1/2 */
  bk_error_t err;
  vdbio_dense_t cnt, w, r;
  int found;
  memset(&err, 0, sizeof err);
  REQUIRE(vdbio_read_dense(out, "photon_count", 0, &cnt, &err) == BK_OK, "%s", err.msg);
  REQUIRE(vdbio_read_dense_like(out, "photon_weight", &cnt, &w, &found, &err) == BK_OK && found,
        "%s", err.msg);
  REQUIRE(vdbio_read_dense_like(out, "filter_radius", &cnt, &r, &found, &err) == BK_OK && found,
        "%s", err.msg);
  size_t n = (size_t)cnt.nx * cnt.ny * cnt.nz, counted = 0, bad = 0;
  /* w = 1/pdf with floor <= pdf <= floor + (1 - floor) * cells */
  const float wlo = 0.999f / (AD_DEFAULT_FLOOR + (1.0f - AD_DEFAULT_FLOOR) * LD_CELLS);
  const float whi = 1.001f / AD_DEFAULT_FLOOR;
  float wmin = 1e30f, wmax = 0.0f;
  for (size_t v = 0; v < n; v++) {
    if (cnt.data[v] > 0.0f) {
      counted++;
      bad += cnt.data[v] != floorf(cnt.data[v]) || !(w.data[v] >= wlo && w.data[v] <= whi);
      wmin = fminf(wmin, w.data[v]);
      wmax = fmaxf(wmax, w.data[v]);
    }
    bad += 2.0f * r.data[v] != floorf(2.0f * r.data[v]) || r.data[v] < 0.0f ||
           r.data[v] > AD_DEFAULT_MAX_RADIUS;
  }
  printf("cli: %s: %zu voxels with photons, mean weights %.3f..%.3f, %zu impossible values\n",
         out, counted, (double)wmin, (double)wmax, bad);
  REQUIRE(counted > 1000 && bad == 0, "%zu of %zu voxels hold impossible values", bad, counted);
  REQUIRE(wmin < 0.9f && wmax > 1.5f, "mean weights %.3f..%.3f: the PDF did nothing", (double)wmin,
        (double)wmax);
  vdbio_dense_free(&cnt);
  vdbio_dense_free(&w);
  vdbio_dense_free(&r);
  char *a2[] = {"bake", scene_path, "-o", out2, "--mode", "adaptive", "--resolution", "32",
                "--photons", "6000", "--no-filter", "--force", "-q"};
  REQUIRE(bake_main((int)(sizeof a2 / sizeof a2[0]), a2) == 0, "bake --no-filter failed");
  expect_meta(out2, "adaptive_filter", "off");
  REQUIRE(!has_grid(out2, "filter_radius"), "filter_radius written without being asked");
  REQUIRE(has_grid(out2, "photon_count") && has_grid(out2, "photon_weight"), "grids missing");
  return 0;
}

int main(int argc, char **argv) {
  if (argc < 4) {
    fprintf(stderr,
            "usage: %s SCENE_DIR OUT_DIR unbiased|lights|quality|estimate|filter_radius|host_vs_device|cli\n",
            argv[0]);
    return 2;
  }
  scene_dir = argv[1];
  out_dir = argv[2];
  bk_verbosity = 0;
  const char *t = argv[3];
  if (!strcmp(t, "unbiased")) return test_unbiased();
  if (!strcmp(t, "lights")) return test_lights();
  if (!strcmp(t, "quality")) return test_quality();
  if (!strcmp(t, "estimate")) return test_estimate();
  if (!strcmp(t, "filter_radius")) return test_filter_radius();
  if (!strcmp(t, "host_vs_device")) return test_host_vs_device();
  if (!strcmp(t, "cli")) return test_cli();
  fprintf(stderr, "unknown test '%s'\n", t);
  return 2;
}
