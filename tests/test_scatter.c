/* test_scatter.c: multiple scattering (kernels/scatter.h, scatter_march.h,
 * baker/bounces.h) against analytic truths, on the host C path and on
 * OpenCL. Usage: test_scatter TEST [host|cl]. */
#include "kernels/scatter_march.h"
#include "kernels/view_march.h"
#include "test_march_util.h"
#include "voxelize.h"

/* A cube of side 1 m, N voxels a side, filled with the given coefficients;
 * a directional light of irradiance 1 W/m² along +z covers its top face:
 * 1 W enters. */
static float *bake_cube(clh_context_t *cl, int N, float sigma_s, float sigma_a, float g,
                        int bounces, long long photons, unsigned seed, volume_t *v, pm_stats_t *st) {
  tv_alloc(v, N, N, N, 1.0f / N, 0, 0, 0);
  const float ss[3] = {sigma_s, sigma_s, sigma_s}, sa[3] = {sigma_a, sigma_a, sigma_a};
  tv_fill(v, 1.0f, ss, sa);
  tv_summarise(v);
  static scene_light_t light;
  light = tl_directional(0, 0, 1, 1.0f);
  scene_t s;
  ts_init(&s, &light, 1, photons);
  s.bounces = bounces;
  s.medium_g = g;
  s.seed = seed;
  return tm_bake(cl, &s, v, st);
}

/* Energy conservation. σa = 0: every watt that enters leaves (the power
 * the photons carry out of the grid, summed over all their legs). σa > 0:
 * what enters = what leaves + what is absorbed, the absorbed power read off
 * the radiance grid, Σ σa 4π L̄ V. */
static int test_energy(clh_context_t *cl) {
  const int N = 32;
  const double V = pow(1.0 / N, 3);
  for (int absorbing = 0; absorbing < 2; absorbing++) {
    const float sa = absorbing ? 0.3f : 0.0f;
    volume_t v;
    pm_stats_t st;
    float *rad = bake_cube(cl, N, 3.0f, sa, 0.0f, 10000, 100000, 1, &v, &st);
    double absorbed = 0.0;
    for (size_t i = 0; i < grid_count(&v.dims); i++)
      for (int c = 0; c < 3; c++) absorbed += sa * 4.0 * M_PI * rad[3 * i + c] * V;
    printf("energy (sigma_a %.1f): entered %.5f W, left %.5f W, absorbed %.5f W, "
           "%.2f events per photon, %.1f%% of the deposit after the first event, %llu at the "
           "step limit\n",
           sa, st.entered, st.escaped, absorbed, (double)st.events / st.photons,
           100.0 * pm_scattered_share(&st), (unsigned long long)st.step_limit);
    /* every photon of the 1 W light enters, summed in float per photon */
    REQUIRE(fabs(st.entered / 3.0 - 1.0) < 1e-4, "entered %.6f W of 3 (RGB)", st.entered);
    double balance = (st.escaped + absorbed) / st.entered - 1.0; /* all sums over RGB */
    printf("  (left + absorbed) / entered - 1 = %+.4f (limit 1%%)\n", balance);
    REQUIRE(fabs(balance) < 0.01, "energy balance off by %+.4f", balance);
    REQUIRE(st.events > st.photons, "a 3-mean-free-path cube should scatter photons more than once");
    free(rad);
    tv_free(&v);
  }
  return 0;
}

/* Slope of ln(mean L̄) against depth over the layers [k0, k1]. */
static double log_slope(const double *layer, int k0, int k1, double h) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int n = 0;
  for (int k = k0; k <= k1; k++, n++) {
    double x = (k + 0.5) * h, y = log(layer[k]);
    sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

/* The diffusion limit: in a deep, highly scattering slab the fluence falls
 * as e^(−σ_tr z), σ_tr = sqrt(3 σa (σa + σs (1 − g))). A slab 12 m wide and
 * 4 m deep lit from above; L̄ averaged over its columns 2 m (3.5 diffusion
 * lengths) or more from its sides, its log-slope fitted over depths 0.75 m
 * to 2.1 m (7.5 mean free paths from the lit face, 1.9 m from the far one,
 * whose vacuum boundary steepens the decay there by under 0.5%). With 3e6
 * photons the fit gives 1.723 and 1.744 /m (two seeds, g = 0) and 1.735 /m
 * (g = 0.5) against 1.741. */
static int test_diffusion(clh_context_t *cl, float g) {
  const int NX = 72, NZ = 24;
  const float h = 12.0f / NX, sa = 0.1f, ss = 10.0f / (1.0f - g);
  volume_t v;
  tv_alloc(&v, NX, NX, NZ, h, 0, 0, 0);
  const float s3[3] = {ss, ss, ss}, a3[3] = {sa, sa, sa};
  tv_fill(&v, 1.0f, s3, a3);
  tv_summarise(&v);
  scene_light_t light = tl_directional(0, 0, 1, 1.0f);
  scene_t s;
  ts_init(&s, &light, 1, 400000); /* the deep layers see few photons: fewer is too noisy */
  s.bounces = SCENE_MAX_BOUNCES;
  s.medium_g = g;
  pm_stats_t st;
  float *rad = tm_bake(cl, &s, &v, &st);
  double layer[64] = {0};
  const int c0 = 12, c1 = NX - 12; /* 2 m from the sides */
  for (int k = 0; k < NZ; k++) {
    for (int j = c0; j < c1; j++)
      for (int i = c0; i < c1; i++) layer[k] += rad[3 * grid_index(&v.dims, i, j, k)];
    layer[k] /= (double)(c1 - c0) * (c1 - c0);
  }
  double sigma_tr = sqrt(3.0 * sa * (sa + ss * (1.0 - g)));
  double slope = -log_slope(layer, 4, 12, h);
  printf("diffusion (g %.1f, sigma_s %.1f, sigma_a %.1f): %.1f events per photon; fitted decay "
         "%.4f /m, sigma_tr %.4f /m (%+.2f%%, limit 5%%)\n",
         g, ss, sa, (double)st.events / st.photons, slope, sigma_tr,
         100.0 * (slope / sigma_tr - 1.0));
  for (int k = 0; k < NZ; k += 3) printf("  depth %.2f m: L %.4e\n", (k + 0.5) * h, layer[k]);
  REQUIRE(fabs(slope / sigma_tr - 1.0) < 0.05, "decay %.4f, expected %.4f", slope, sigma_tr);
  free(rad);
  tv_free(&v);
  return 0;
}

/* bounces 0 is single scattering bit for bit, and a scattering march whose
 * photons may not scatter deposits exactly what the single-scattering march
 * does: its first leg is that march. Host path, photon by photon. */
static int test_first_leg(void) {
  volume_t v;
  tv_alloc(&v, 24, 24, 24, 1.0f / 24, 0, 0, 0);
  const float ss[3] = {1.0f, 1.0f, 1.0f}, sa[3] = {0.1f, 0.1f, 0.1f};
  tv_fill(&v, 1.0f, ss, sa);
  const float c[3] = {0.5f, 0.5f, 0.5f};
  tv_ball(&v, c, 0.25f, 1.5f, 2.0f, NULL, NULL);
  tv_summarise(&v);
  scene_light_t light = tl_spot(0.5f, 1.5f, 0.5f, 0, -1, 0, 25.0f, 1, 1, 1);
  scene_t s;
  ts_init(&s, &light, 1, 5000);
  bk_error_t err;
  memset(&err, 0, sizeof err);
  pm_setup_t setup;
  REQUIRE(pm_prepare(&s, &v, &setup, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
  REQUIRE(setup.ms.params.max_bounces == 0, "bounces 0 must leave multiple scattering off");
  size_t n = pm_acc_count(&setup);
  uint64_t *a = calloc(n, 8), *b = calloc(n, 8);
  REQUIRE(a && b, "out of memory");
  ms_params M = setup.ms.params;
  M.sigma_s[0] = M.sigma_s[1] = M.sigma_s[2] = 1.0f / 24;
  for (bk_uint i = 0; i < setup.lights.photons; i++) {
    pm_result r1, r2;
    ms_tally t;
    const ms_medium med = {NULL, NULL};
    pm_march_photon(&setup.params, setup.lights.lights, setup.ng, setup.pyramid.level,
                    setup.sigma_t, a, NULL, NULL, i, &r1, NULL);
    pm_march_scattered(&setup.params, &M, setup.lights.lights, setup.ng, setup.pyramid.level,
                       setup.sigma_t, med, b, NULL, NULL, i, &r2, &t, NULL);
    REQUIRE(memcmp(&r1, &r2, sizeof r1) == 0, "photon %u: outcomes differ", i);
    REQUIRE(t.events == 0 && t.later == 0.0f, "photon %u scattered with bounces 0", i);
  }
  REQUIRE(memcmp(a, b, n * 8) == 0, "deposits differ");
  printf("first leg: %llu photons through a refracting ball, deposits bit-identical\n",
         (unsigned long long)setup.lights.photons);
  free(a);
  free(b);
  pm_setup_free(&setup);
  tv_free(&v);
  return 0;
}

/* The "auto" rule (bounces.h) on a 2 m box: thin haze stays single
 * scattering (and the march prepares no scattering), the bundled fog gets a
 * few events, thicker fog more. */
static int test_auto(void) {
  struct {
    float ss, sa;
    int lo, hi;
  } cases[] = {{0.01f, 0.0f, 0, 0}, {0.012f, 0.001f, 0, 0}, {0.03f, 0.001f, 1, 2}, {0.5f, 0.02f, 4, 8},
               {1.5f, 0.05f, 10, 40}, {1.0f, 0.0f, 10, 20}, {0.0f, 1.0f, 0, 0}};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    volume_t v;
    tv_alloc(&v, 16, 16, 16, 2.0f / 16, -1, -1, -1);
    const float ss[3] = {cases[i].ss, cases[i].ss, cases[i].ss};
    const float sa[3] = {cases[i].sa, cases[i].sa, cases[i].sa};
    tv_fill(&v, 1.0f, ss, sa);
    tv_summarise(&v);
    scene_light_t light = tl_directional(0, -1, 0, 1.0f);
    scene_t s;
    ts_init(&s, &light, 1, 1000);
    s.bounces = SCENE_BOUNCES_AUTO;
    bk_error_t err;
    memset(&err, 0, sizeof err);
    pm_setup_t setup;
    REQUIRE(pm_prepare(&s, &v, &setup, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
    int n = (int)setup.ms.params.max_bounces;
    char defs[128];
    ms_kernel_defines(&setup.ms, defs, sizeof defs);
    printf("auto: sigma_s %.3f sigma_a %.3f: r %.4f -> %d events%s\n", cases[i].ss, cases[i].sa,
           setup.ms.ratio, n, n ? "" : " (single-scattering kernel)");
    REQUIRE(n >= cases[i].lo && n <= cases[i].hi, "%d events, expected %d to %d", n,
            cases[i].lo, cases[i].hi);
    REQUIRE(n > 0 || defs[0] == '\0', "single scattering must build no scattering kernel");
    pm_setup_free(&setup);
    tv_free(&v);
  }
  return 0;
}

/* Henyey–Greenstein sampling: the mean cosine is g, and ms_rotate turns a
 * direction by the sampled angle. */
static int test_phase(void) {
  const float gs[] = {-0.5f, 0.0f, 0.3f, 0.8f, 0.95f};
  const int M = 200000;
  for (size_t i = 0; i < sizeof gs / sizeof gs[0]; i++) {
    double mean = 0.0;
    for (int k = 0; k < M; k++) mean += ms_hg_cos(gs[i], (k + 0.5f) / M);
    mean /= M;
    printf("phase: g %.2f: mean cosine %.5f\n", gs[i], mean);
    REQUIRE(fabs(mean - gs[i]) < 2e-3, "mean cosine %.5f for g %.2f", mean, gs[i]);
  }
  bk_v3 d = rc_normalize(v3(0.3f, -0.5f, 0.8f));
  for (int k = 0; k < 100; k++) {
    float ct = -1.0f + 2.0f * k / 99.0f;
    bk_v3 r = ms_rotate(d, ct, ms_uniform(1, 2, (bk_uint)k));
    REQUIRE(fabs(rc_length(r) - 1.0f) < 1e-5f && fabs(v3_dot(r, d) - ct) < 1e-4f,
            "rotation %d: |r| %.6f, cos %.6f (wanted %.6f)", k, rc_length(r), v3_dot(r, d), ct);
  }
  return 0;
}

/* Counter-based random numbers: a bake is the same every time, another seed
 * another sample. */
static int test_reproducible(clh_context_t *cl) {
  volume_t v;
  pm_stats_t st;
  float *a = bake_cube(cl, 16, 2.0f, 0.1f, 0.5f, 20, 20000, 7, &v, &st);
  size_t n = 3 * grid_count(&v.dims);
  tv_free(&v);
  float *b = bake_cube(cl, 16, 2.0f, 0.1f, 0.5f, 20, 20000, 7, &v, &st);
  tv_free(&v);
  float *c = bake_cube(cl, 16, 2.0f, 0.1f, 0.5f, 20, 20000, 8, &v, &st);
  tv_free(&v);
  REQUIRE(memcmp(a, b, n * sizeof(float)) == 0, "two bakes with one seed differ");
  REQUIRE(memcmp(a, c, n * sizeof(float)) != 0, "two seeds gave the same bake");
  printf("reproducible: same seed bit-identical, another seed differs\n");
  free(a);
  free(b);
  free(c);
  return 0;
}

/* objects[].g is voxelized like the coefficients and reaches the scattering
 * march as a per-voxel g grid; a scene whose objects share the medium's g
 * gets none. */
static int test_object_g(void) {
  const char *obj = "scatter_object_g_cube.obj";
  FILE *f = fopen(obj, "w");
  REQUIRE(f, "cannot write %s", obj);
  fprintf(f, "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\n"
             "v -1 1 1\nf 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 7 3\n"
             "f 4 8 7\nf 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n");
  fclose(f);
  for (int differs = 0; differs < 2; differs++) {
    scene_t s;
    scene_object_t o;
    scene_light_t light = tl_directional(0, -1, 0, 1.0f);
    ts_init(&s, &light, 1, 1000);
    for (int a = 0; a < 3; a++) s.bounds_min[a] = -1.0f, s.bounds_max[a] = 1.0f;
    s.resolution = 32;
    for (int c = 0; c < 3; c++) s.medium_sigma_s[c] = 0.5f;
    s.medium_g = 0.2f;
    scene_object_defaults(&o);
    snprintf(o.mesh, sizeof o.mesh, "%s", obj);
    o.ior = 1.0f;
    o.scale[0] = o.scale[1] = o.scale[2] = 0.5f;
    for (int c = 0; c < 3; c++) o.sigma_s[c] = 2.0f;
    o.g = differs ? 0.7f : 0.2f;
    s.objects = &o;
    s.object_count = 1;
    volume_t v;
    bk_error_t err;
    memset(&err, 0, sizeof err);
    REQUIRE(vox_build(&s, &v, NULL, &err) == BK_OK, "vox_build: %s", err.msg);
    ms_setup_t ms;
    int grey;
    ms_decide(&s, &v, &ms, &grey);
    if (!differs) {
      REQUIRE(v.g == NULL && !ms.g_grid && ms.hg, "one g everywhere needs no g grid");
    } else {
      float centre = v.g[grid_index(&v.dims, 16, 16, 16)], corner = v.g[0];
      printf("object g: centre %.3f (object 0.7), corner %.3f (medium 0.2)\n", centre, corner);
      REQUIRE(centre == 0.7f && corner == 0.2f && ms.g_grid && ms.hg, "g grid wrong");
    }
    vox_free(&v);
  }
  remove(obj);
  return 0;
}

/* A 16³ cube of 1 m with g = 0.5 (so the march keeps radiance_flux) under a
 * directional light along dir; RGB absorption when rgb (three channels,
 * the flux weighted in the kernel), else grey (one); with cam (world; NULL:
 * none) a scene camera there, so the camera's counter too. The raw sums
 * (*count counters), with radiance and flux (3 floats per voxel each) and
 * the uncollided luminance (1), then its flux (3) and, with cam,
 * radiance_camera (1), filled from them. */
static uint64_t *flux_bake(clh_context_t *cl, int bounces, int rgb, const float dir[3],
                           const float *cam, float *rad, float *flux, float *unc, size_t *count) {
  volume_t v;
  tv_alloc(&v, 16, 16, 16, 1.0f / 16, 0, 0, 0);
  const float ss[3] = {3.0f, 3.0f, 3.0f}, sa[3] = {0.1f, rgb ? 0.3f : 0.1f, rgb ? 0.9f : 0.1f};
  tv_fill(&v, 1.0f, ss, sa);
  tv_summarise(&v);
  scene_light_t light = tl_directional(dir[0], dir[1], dir[2], 1.0f);
  scene_t s;
  ts_init(&s, &light, 1, 20000);
  s.bounces = bounces;
  s.medium_g = 0.5f;
  if (cam) memcpy(s.camera.position, cam, sizeof s.camera.position);
  s.camera.present = cam != NULL;
  bk_error_t err;
  memset(&err, 0, sizeof err);
  pm_setup_t setup;
  REQUIRE(pm_prepare(&s, &v, &setup, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
  REQUIRE(setup.params.flux == 1, "g = 0.5 must turn the flux on");
  REQUIRE((int)setup.params.camera == (cam != NULL), "camera counter %s",
          cam ? "missing with a camera" : "kept without a camera");
  REQUIRE(setup.channels == (rgb ? 3 : 1), "expected %d channels", rgb ? 3 : 1);
  *count = pm_acc_count(&setup);
  uint64_t *acc = calloc(*count, sizeof *acc);
  REQUIRE(acc, "out of memory");
  int rc = cl ? pm_run_cl(cl, &setup, acc, NULL, &err) : pm_run_host(&setup, acc, NULL, &err);
  REQUIRE(rc == BK_OK, "march: %s", err.msg);
  pm_to_radiance(&setup, acc, rad, 3);
  pm_to_flux(&setup, acc, flux, unc);
  pm_setup_free(&setup);
  tv_free(&v);
  return acc;
}

static double lum3(const float *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

/* The view's phase factor 4π p_HG(|A|, Â·(−d)): 1 over the sphere on
 * average, (1 + k)/(1 − k)² looking into the lobe, the HG formula itself at
 * an angle. */
static int check_phase_factor(void) {
  const float k = 0.7f;
  const bk_v3 a = v3(0.0f, k * 0.6f, k * 0.8f);
  double sum = 0.0;
  const int nt = 400, np = 200;
  for (int i = 0; i < nt; i++)
    for (int j = 0; j < np; j++) {
      double mu = -1.0 + (i + 0.5) * 2.0 / nt, phi = (j + 0.5) * 2.0 * M_PI / np;
      double r = sqrt(1.0 - mu * mu);
      sum += view_phase_factor(a, v3((float)(r * cos(phi)), (float)(r * sin(phi)), (float)mu));
    }
  double mean = sum / ((double)nt * np);
  double peak = view_phase_factor(a, v3(0.0f, -0.6f, -0.8f)), want = (1 + k) / pow(1 - k, 2);
  /* at 60° from the lobe's axis: 4π p_HG(k, cos 60°) */
  double c60 = 0.5, side = (1 - k * k) / pow(1 + k * k - 2 * k * c60, 1.5);
  bk_v3 d60 = v3(0.0f, -(float)(0.6 * c60 - 0.8 * sqrt(0.75)), -(float)(0.8 * c60 + 0.6 * sqrt(0.75)));
  double got60 = view_phase_factor(a, d60);
  printf("view phase factor (|A| %.1f): sphere mean %.5f, into the lobe %.4f (want %.4f), at 60° "
         "%.5f (want %.5f)\n", k, mean, peak, want, got60, side);
  REQUIRE(fabs(mean - 1.0) < 2e-3, "phase factor not normalised: mean %.5f", mean);
  REQUIRE(fabs(peak / want - 1.0) < 1e-5, "peak %.6f, want %.6f", peak, want);
  REQUIRE(fabs(got60 / side - 1.0) < 1e-5, "60 degrees: %.6f, want %.6f", got60, side);
  return 0;
}

/* radiance_flux and radiance_uncollided (march.h pm_to_flux). Single
 * scattering of a parallel beam: in every lit voxel F = Y(L̄) ω0 (mean
 * cosine 1, the direction exact) and all of Y(L̄) uncollided, RGB and grey.
 * Multiple scattering: |F| <= Y(L̄) everywhere, the net flux down the beam,
 * the uncollided part of Y(L̄) between 0 and all of it, less deep down. On OpenCL the signed fixed-point sums of two bakes are
 * bit-identical whatever order the work-items' atomics came in. */
static int test_flux(clh_context_t *cl) {
  const size_t n = 16 * 16 * 16;
  const float dir[3] = {0.3f, 0.2f, 1.0f};
  const double dn = sqrt(0.09 + 0.04 + 1.0), w0[3] = {0.3 / dn, 0.2 / dn, 1.0 / dn};
  float *rad = calloc(3 * n, sizeof(float)), *flux = calloc(3 * n, sizeof(float));
  float *unc = calloc(4 * n, sizeof(float)); /* Y0, then the uncollided flux F0 */
  size_t count;
  REQUIRE(rad && flux && unc, "out of memory");
  for (int rgb = 0; rgb < 2; rgb++) {
    uint64_t *acc = flux_bake(cl, 0, rgb, dir, NULL, rad, flux, unc, &count);
    double worst = 0.0, worst_u = 0.0;
    size_t lit = 0;
    for (size_t i = 0; i < n; i++) {
      double y = lum3(rad + 3 * i);
      if (!(y > 0.0)) continue;
      lit++;
      for (int a = 0; a < 3; a++) {
        worst = fmax(worst, fabs(flux[3 * i + a] / y - w0[a]));
        worst_u = fmax(worst_u, fabs(unc[n + 3 * i + a] - flux[3 * i + a]) / y); /* F0 = F */
      }
      worst_u = fmax(worst_u, fabs(unc[i] / y - 1.0));
    }
    printf("flux, single scattering (%s): %zu lit voxels, |F/Y(L) - w0| at most %.2e, "
           "|uncollided/Y(L) - 1| and |F0 - F|/Y(L) at most %.2e (limits 1e-4)\n", rgb ? "RGB" : "grey", lit,
           worst, worst_u);
    REQUIRE(lit > n / 2 && worst < 1e-4, "beam flux off by %.3e", worst);
    REQUIRE(worst_u < 1e-4, "uncollided share off by %.3e", worst_u);
    free(acc);
  }
  uint64_t *acc = flux_bake(cl, 8, 0, dir, NULL, rad, flux, unc, &count);
  double along = 0.0, ysum = 0.0, over = -1.0, ymax = 0.0, usum = 0.0, umin = 1.0, uover = -1.0;
  double beam = 0.0;
  for (size_t i = 0; i < n; i++) ymax = fmax(ymax, lum3(rad + 3 * i));
  for (size_t i = 0; i < n; i++) {
    const float *F = flux + 3 * i;
    double y = lum3(rad + 3 * i), f = sqrt((double)F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
    over = fmax(over, (f - y) / ymax); /* rounding: a few quanta, ~1e-12 of ymax */
    along += flux[3 * i] * w0[0] + flux[3 * i + 1] * w0[1] + flux[3 * i + 2] * w0[2];
    ysum += y;
    usum += unc[i];
    uover = fmax(uover, (unc[i] - y) / ymax);
    for (int a = 0; a < 3; a++) /* the uncollided light is the beam: F0 = Y0 w0 */
      beam = fmax(beam, fabs(unc[n + 3 * i + a] - unc[i] * w0[a]) / ymax);
    if (y > 1e-3 * ymax) umin = fmin(umin, unc[i] / y);
  }
  printf("uncollided, multiple scattering: %.3f of Y(L) in all, at least %.3f in a voxel, "
         "max (uncollided - Y(L)) / max Y(L) = %.2e\n", usum / ysum, umin, uover);
  REQUIRE(uover < 1e-6 && umin >= 0.0 && umin < 0.5 && usum / ysum > 0.2 && usum / ysum < 0.9,
          "uncollided share %.3f (voxel minimum %.3f, above Y by %.2e)", usum / ysum, umin, uover);
  printf("uncollided flux, multiple scattering: max |F0 - Y0 w0| / max Y(L) = %.2e (limit 1e-5)\n",
         beam);
  REQUIRE(beam < 1e-5, "the uncollided flux leaves the beam by %.3e of the largest Y(L)", beam);
  printf("flux, multiple scattering (g 0.5, 3 mean free paths): mean cosine along the beam "
         "%.3f, max (|F| - Y(L)) / max Y(L) = %.2e (limit 1e-6)\n", along / ysum, over);
  REQUIRE(over < 1e-6, "|F| exceeds Y(L) by %.3e of the largest Y(L)", over);
  REQUIRE(along / ysum > 0.2 && along / ysum < 0.95, "mean cosine %.3f", along / ysum);
  if (cl) {
    float *r2 = calloc(3 * n, sizeof(float)), *f2 = calloc(3 * n, sizeof(float));
    REQUIRE(r2 && f2, "out of memory");
    uint64_t *again = flux_bake(cl, 8, 0, dir, NULL, r2, f2, unc, &count);
    REQUIRE(count == n * (1 + PM_FLUX_SLOTS) && memcmp(again, acc, count * sizeof *acc) == 0,
            "two OpenCL bakes' sums differ");
    printf("flux: two OpenCL bakes' sums bit-identical (the atomics' order does not matter)\n");
    free(again), free(r2), free(f2);
  }
  free(acc), free(rad), free(flux), free(unc);
  return check_phase_factor();
}

/* flux_bake with a camera at cam: radiance (3 floats per voxel) and
 * radiance_camera (1) into rad and cam_c. */
static uint64_t *camera_bake(clh_context_t *cl, int bounces, int rgb, const float dir[3],
                             const float cam[3], float *rad, float *cam_c, size_t *count) {
  const size_t n = 16 * 16 * 16;
  float *flux = calloc(3 * n, sizeof(float)), *unc = calloc(5 * n, sizeof(float));
  REQUIRE(flux && unc, "out of memory");
  uint64_t *acc = flux_bake(cl, bounces, rgb, dir, cam, rad, flux, unc, count);
  memcpy(cam_c, pm_radiance_camera(unc, n), n * sizeof(float));
  free(flux), free(unc);
  return acc;
}

/* g per voxel (0.2 for x < 1/2, 0.7 beyond), thin fog (τ 0.05 across, so
 * a few % of the light has scattered) and multiple scattering, whose march
 * reads g per voxel. The uncollided beam Y0 sends Y0·P towards the camera,
 * P = 4π p_HG(g, w0·ω_c) with the voxel's own g, and the scattered rest
 * Y − Y0 between 0 and (Y − Y0)·P_max(g), so
 *   Y0·P <= C <= Y0·P + (Y − Y0)·(1 + g)/(1 − g)²
 * in every voxel (to 1e-4 of Y; a march that took the other half's g
 * breaks it: the halves' P differ by up to 3×). OpenCL's sums are the
 * host's bit for bit. */
static int test_camera_g_grid(clh_context_t *cl) {
  const int N = 16;
  const size_t n = (size_t)N * N * N;
  volume_t v;
  tv_alloc(&v, N, N, N, 1.0f / N, 0, 0, 0);
  const float ss[3] = {0.05f, 0.05f, 0.05f}, sa[3] = {0.01f, 0.01f, 0.01f};
  tv_fill(&v, 1.0f, ss, sa);
  tv_summarise(&v);
  v.g = malloc(n * sizeof(float));
  REQUIRE(v.g, "out of memory");
  for (size_t i = 0; i < n; i++) v.g[i] = (int)(i % N) < N / 2 ? 0.2f : 0.7f;
  scene_light_t light = tl_directional(0.3f, 0.2f, 1.0f, 1.0f);
  scene_t s;
  ts_init(&s, &light, 1, 40000);
  s.bounces = 8;
  s.medium_g = 0.2f;
  s.camera.present = 1;
  const float cam[3] = {-1.5f, 0.6f, 0.4f};
  memcpy(s.camera.position, cam, sizeof cam);
  bk_error_t err = {0, ""};
  pm_setup_t setup;
  REQUIRE(pm_prepare(&s, &v, &setup, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
  REQUIRE(setup.ms.g_grid && setup.params.camera && setup.params.cam_g_grid,
          "a g grid with multiple scattering must keep the camera's counter");
  const size_t count = pm_acc_count(&setup);
  uint64_t *acc = calloc(count, sizeof *acc), *host = calloc(count, sizeof *host);
  float *rad = calloc(3 * n, sizeof(float)), *flux = calloc(3 * n, sizeof(float));
  float *unc = calloc(5 * n, sizeof(float));
  REQUIRE(acc && host && rad && flux && unc, "out of memory");
  REQUIRE((cl ? pm_run_cl(cl, &setup, acc, NULL, &err) : pm_run_host(&setup, acc, NULL, &err)) ==
              BK_OK, "march: %s", err.msg);
  pm_to_radiance(&setup, acc, rad, 3);
  pm_to_flux(&setup, acc, flux, unc);
  const double dn = sqrt(0.09 + 0.04 + 1.0), w0[3] = {0.3 / dn, 0.2 / dn, 1.0 / dn};
  double out = -1.0, share = 0.0, y_all = 0.0;
  for (size_t i = 0; i < n; i++) {
    const double y = lum3(rad + 3 * i), y0 = unc[i], g = v.g[i];
    const double C = pm_radiance_camera(unc, n)[i];
    const size_t ijk[3] = {i % N, i / N % N, i / ((size_t)N * N)};
    double p[3], pl = 0.0;
    for (int a = 0; a < 3; a++) p[a] = cam[a] - (ijk[a] + 0.5) / N, pl += p[a] * p[a];
    const double cs = (p[0] * w0[0] + p[1] * w0[1] + p[2] * w0[2]) / sqrt(pl);
    const double P = (1 - g * g) / pow(1 + g * g - 2 * g * cs, 1.5), pmax = (1 + g) / pow(1 - g, 2);
    out = fmax(out, fmax(y0 * P - C, C - y0 * P - (y - y0) * pmax) / y);
    share += y - y0, y_all += y;
  }
  printf("camera, g per voxel (0.2 | 0.7), thin fog, multiple scattering (%.1f%% scattered): "
         "C outside [Y0 P, Y0 P + (Y - Y0) P_max] by %.2e of Y at most (limit 1e-4)\n",
         100.0 * share / y_all, out);
  REQUIRE(out < 1e-4, "camera phase with g per voxel out of its bounds by %.3e", out);
  if (cl) {
    REQUIRE(pm_run_host(&setup, host, NULL, &err) == BK_OK, "host march: %s", err.msg);
    REQUIRE(memcmp(host, acc, count * sizeof *acc) == 0, "g per voxel: OpenCL differs from host");
    printf("camera, g per voxel: OpenCL and host sums bit-identical\n");
  }
  free(acc), free(host), free(rad), free(flux), free(unc), free(v.g);
  pm_setup_free(&setup);
  tv_free(&v);
  return 0;
}

/* radiance_camera, the light scattered towards the camera (march.h
 * pm_to_flux). Single scattering of a parallel beam along w0: every photon
 * in a voxel moves along w0, so C / Y(L̄) is the phase 4π p_HG(g, w0·ω_c)
 * towards the camera from the voxel's centre, exactly (to float rounding),
 * grey and RGB. Multiple scattering: C / Y(L̄) within the phase's range,
 * and its mean over the lit voxels between the back and forward values.
 * On OpenCL the sums equal the host C path's bit for bit. The camera is
 * left out without a camera, with camera.bake_phase false, or when g
 * varies. */
static int test_camera(clh_context_t *cl) {
  const size_t n = 16 * 16 * 16;
  const float dir[3] = {0.3f, 0.2f, 1.0f}, cam[3] = {-1.5f, 0.6f, 0.4f}, g = 0.5f;
  const double dn = sqrt(0.09 + 0.04 + 1.0), w0[3] = {0.3 / dn, 0.2 / dn, 1.0 / dn};
  float *rad = calloc(3 * n, sizeof(float)), *c = calloc(n, sizeof(float));
  REQUIRE(rad && c, "out of memory");
  size_t count;
  for (int rgb = 0; rgb < 2; rgb++) {
    uint64_t *acc = camera_bake(cl, 0, rgb, dir, cam, rad, c, &count);
    double worst = 0.0;
    size_t lit = 0;
    for (size_t i = 0; i < n; i++) {
      double y = lum3(rad + 3 * i), p[3], pl = 0.0;
      if (!(y > 0.0)) continue;
      const size_t ijk[3] = {i % 16, i / 16 % 16, i / 256};
      for (int a = 0; a < 3; a++) p[a] = cam[a] - (ijk[a] + 0.5) / 16.0, pl += p[a] * p[a];
      double cs = (p[0] * w0[0] + p[1] * w0[1] + p[2] * w0[2]) / sqrt(pl);
      double want = (1 - g * g) / pow(1 + g * g - 2 * g * cs, 1.5);
      worst = fmax(worst, fabs(c[i] / y / want - 1.0));
      lit++;
    }
    printf("camera, single scattering (%s): %zu lit voxels, C / Y(L) against 4pi p_HG(g, w0.w_c) "
           "off by %.2e at most (limit 1e-4)\n", rgb ? "RGB" : "grey", lit, worst);
    REQUIRE(lit > n / 2 && worst < 1e-4, "camera phase off by %.3e", worst);
    free(acc);
  }
  uint64_t *acc = camera_bake(cl, 8, 0, dir, cam, rad, c, &count);
  double lo = (1 - g) / pow(1 + g, 2), hi = (1 + g) / pow(1 - g, 2), csum = 0, ysum = 0, out = 0;
  for (size_t i = 0; i < n; i++) {
    double y = lum3(rad + 3 * i);
    csum += c[i], ysum += y;
    if (y > 1e-3 * ysum / (i + 1)) out = fmax(out, fmax(lo - c[i] / y, c[i] / y - hi));
  }
  printf("camera, multiple scattering: C / Y(L) %.3f over the grid, out of [%.3f, %.3f] by %.2e "
         "at most\n", csum / ysum, lo, hi, out);
  REQUIRE(out < 1e-4 && csum / ysum > lo && csum / ysum < hi, "camera factor out of range");
  if (cl) {
    size_t count_h;
    uint64_t *host = camera_bake(NULL, 8, 0, dir, cam, rad, c, &count_h);
    REQUIRE(count_h == count && memcmp(host, acc, count * sizeof *acc) == 0,
            "the OpenCL sums differ from the host's");
    printf("camera: OpenCL and host sums bit-identical (%zu counters)\n", count);
    free(host);
  }
  free(acc), free(rad), free(c);
  if (test_camera_g_grid(cl)) return 1;
  /* not kept: no camera, camera.bake_phase false */
  volume_t v;
  tv_alloc(&v, 8, 8, 8, 1.0f / 8, 0, 0, 0);
  const float ss[3] = {1, 1, 1}, sa[3] = {0.1f, 0.1f, 0.1f};
  tv_fill(&v, 1.0f, ss, sa);
  tv_summarise(&v);
  scene_light_t light = tl_directional(0, 0, 1, 1);
  for (int k = 0; k < 2; k++) {
    scene_t s;
    ts_init(&s, &light, 1, 100);
    s.medium_g = 0.5f;
    s.camera.present = k;
    s.camera.bake_phase = 0;
    pm_setup_t setup;
    bk_error_t err = {0, ""};
    REQUIRE(pm_prepare(&s, &v, &setup, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
    REQUIRE(setup.params.flux && !setup.params.camera &&
                pm_acc_count(&setup) == setup.voxels * (1 + PM_FLUX_SLOTS),
            "camera counter kept (camera %d, bake_phase 0)", k);
    pm_setup_free(&setup);
  }
  tv_free(&v);
  printf("camera: no counter without a camera or with bake_phase false\n");
  return 0;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: test_scatter TEST [host|cl]\n");
    return 2;
  }
  const char *t = argv[1];
  clh_context_t *cl = tm_path(argc > 2 ? argv[2] : "host");
  if (strcmp(t, "energy") == 0) return test_energy(cl);
  if (strcmp(t, "diffusion") == 0) return test_diffusion(cl, 0.0f);
  if (strcmp(t, "diffusion_hg") == 0) return test_diffusion(cl, 0.5f);
  if (strcmp(t, "first_leg") == 0) return test_first_leg();
  if (strcmp(t, "auto") == 0) return test_auto();
  if (strcmp(t, "phase") == 0) return test_phase();
  if (strcmp(t, "reproducible") == 0) return test_reproducible(cl);
  if (strcmp(t, "object_g") == 0) return test_object_g();
  if (strcmp(t, "flux") == 0) return test_flux(cl);
  if (strcmp(t, "camera") == 0) return test_camera(cl);
  fprintf(stderr, "test_scatter: unknown test %s\n", t);
  return 2;
}
