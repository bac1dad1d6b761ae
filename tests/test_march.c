/* test_march.c: analytic tests of photon generation and marching, on the
 * host C path and on OpenCL (PoCL). Usage: test_march TEST [host|cl]. */
#include "test_march_util.h"

/* Collimated light into a homogeneous slab: L̄(d) = E e^{-σt d} / (4π). The
 * expected value of a voxel layer [z0, z1] is its exact average. */
static int test_beer_lambert(clh_context_t *cl) {
  const int N = 64;
  const float h = 4.0f / N, sigma = 1.0f, E = 1.0f;
  volume_t v;
  tv_alloc(&v, N, N, N, h, 0, 0, 0);
  const float ss[3] = {0.6f, 0.6f, 0.6f}, sa[3] = {0.4f, 0.4f, 0.4f};
  tv_fill(&v, 1.0f, ss, sa);
  tv_summarise(&v);
  scene_light_t light = tl_directional(0, 0, 1, E);
  scene_t s;
  ts_init(&s, &light, 1, 1000000);
  pm_stats_t st;
  float *rad = tm_bake(cl, &s, &v, &st);
  tm_print_stats("beer-lambert", &st);
  REQUIRE(st.missed_grid == 0 && st.left_grid == st.photons, "every photon should cross the slab");
  double sum2 = 0.0, worst_voxel = 0.0;
  for (int k = 0; k < N; k++) {
    double z0 = k * h, z1 = (k + 1) * h;
    double expect = E * (exp(-sigma * z0) - exp(-sigma * z1)) / (sigma * h) / (4.0 * M_PI);
    double mean = 0.0;
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) {
        size_t idx = grid_index(&v.dims, i, j, k);
        for (int c = 0; c < 3; c++) {
          double r = rad[3 * idx + c];
          mean += r / (3.0 * N * N);
          worst_voxel = fmax(worst_voxel, fabs(r / expect - 1.0));
        }
      }
    double rel = mean / expect - 1.0;
    sum2 += rel * rel;
    if (k % 16 == 0 || k == N - 1)
      printf("  depth %5.3f m: L %.6e, expected %.6e (%+.2e)\n", 0.5 * (z0 + z1), mean, expect, rel);
  }
  double rms = sqrt(sum2 / N);
  printf("beer-lambert: RMS relative error of the layers %.3e (limit 1e-2), worst voxel %.3e\n",
         rms, worst_voxel);
  REQUIRE(rms < 1e-2, "RMS error %.3e over 1%%", rms);
  free(rad);
  tv_free(&v);
  return 0;
}

/* A point light in a clear medium: L̄(r) = I / (4π r²), compared shell by
 * shell (voxel-centre radius in [r, r+1) voxels) against the voxels' exact
 * averages of I / (4π r²) (4^3 midpoint samples per voxel). */
static int test_inverse_square(clh_context_t *cl, int spot) {
  const int N = 96;
  const float h = 2.0f / N, I = 1.0f;
  const float lp[3] = {0.013f, -0.007f, 0.004f};
  /* spot: 30° half angle along a tilted axis; only voxels wholly inside the
   * cone (their centre's angle plus the half-diagonal's, asin(0.87/r), below
   * 30°) are compared */
  const double axis[3] = {0.2 / sqrt(1.04), 0.0, 1.0 / sqrt(1.04)};
  volume_t v;
  tv_alloc(&v, N, N, N, h, -1, -1, -1);
  const float zero[3] = {0, 0, 0};
  tv_fill(&v, 1.0f, zero, zero);
  tv_summarise(&v);
  scene_light_t light = spot ? tl_spot(lp[0], lp[1], lp[2], 0.2f, 0, 1, 30, I, I, I)
                             : tl_point(lp[0], lp[1], lp[2], I, I, I);
  scene_t s;
  ts_init(&s, &light, 1, 1000000);
  pm_stats_t st;
  float *rad = tm_bake(cl, &s, &v, &st);
  tm_print_stats(spot ? "inverse-square (spot)" : "inverse-square", &st);
  enum { R0 = 4, R1 = 40 };
  double got[R1 + 1] = {0}, want[R1 + 1] = {0};
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) {
        float c[3];
        grid_voxel_center(&v.dims, i, j, k, c);
        double dx = c[0] - lp[0], dy = c[1] - lp[1], dz = c[2] - lp[2];
        double r = sqrt(dx * dx + dy * dy + dz * dz) / h;
        if (r < R0 || r >= R1) continue;
        if (spot && acos(fmin(1.0, (dx * axis[0] + dy * axis[1] + dz * axis[2]) / (r * h))) +
                            asin(fmin(1.0, 0.87 / r)) >
                        30.0 * M_PI / 180.0)
          continue;
        int shell = (int)r;
        double avg = 0.0;
        for (int q = 0; q < 64; q++) {
          double px = dx + ((q & 3) - 1.5) * 0.25 * h, py = dy + (((q >> 2) & 3) - 1.5) * 0.25 * h,
                 pz = dz + (((q >> 4) & 3) - 1.5) * 0.25 * h;
          avg += I / (4.0 * M_PI * (px * px + py * py + pz * pz)) / 64.0;
        }
        want[shell] += avg;
        got[shell] += rad[3 * grid_index(&v.dims, i, j, k)];
      }
  double worst = 0.0;
  for (int r = R0; r < R1; r++) {
    double rel = got[r] / want[r] - 1.0;
    worst = fmax(worst, fabs(rel));
    if (r % 6 == 4) printf("  shell r=%2d voxels: measured/expected - 1 = %+.3e\n", r, rel);
  }
  printf("inverse-square%s: worst shell error %.3e (limit 2e-2)\n", spot ? " (spot)" : "", worst);
  REQUIRE(worst < 2e-2, "shell error %.3e over 2%%", worst);
  free(rad);
  tv_free(&v);
  return 0;
}

/* Largest distance of a path's points (from the grid entry on) from the line
 * through the first point along dir, in voxels. */
static double path_deviation(const float *pts, int count, const float o[3], const float dir[3],
                             float h) {
  double worst = 0.0;
  for (int p = 1; p < count; p++) {
    double w[3] = {pts[3 * p] - o[0], pts[3 * p + 1] - o[1], pts[3 * p + 2] - o[2]};
    double t = w[0] * dir[0] + w[1] * dir[1] + w[2] * dir[2];
    double q[3] = {w[0] - t * dir[0], w[1] - t * dir[1], w[2] - t * dir[2]};
    worst = fmax(worst, sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) / h);
  }
  return worst;
}

/* Straight lines at constant n: pure DDA (n constant everywhere), the
 * octree's straight crossings (n varies only in one far corner), and
 * stepping everywhere with ∇n = 0 (octree off, Euler and RK4). */
static int test_straight(void) {
  const int N = 64;
  const float h = 1.0f / N;
  enum { MAXP = 4096 };
  static float pts[3 * MAXP];
  const char *names[] = {"pure DDA", "octree", "stepping (Euler)", "stepping (RK4)"};
  const double limits[] = {1e-4, 1e-4, 1e-3, 1e-3};
  for (int mode = 0; mode < 4; mode++) {
    volume_t v;
    tv_alloc(&v, N, N, N, h, 0, 0, 0);
    const float zero[3] = {0, 0, 0};
    tv_fill(&v, 1.33f, zero, zero);
    if (mode > 0) v.ior[0] = 1.5f; /* n varies in the corner voxel only */
    tv_summarise(&v);
    scene_light_t light = tl_directional(0, 0, 1, 1);
    scene_t s;
    ts_init(&s, &light, 1, 1);
    s.integrator = mode == 3 ? INTEGRATOR_RK4 : INTEGRATOR_EULER;
    pm_setup_t su;
    bk_error_t err;
    REQUIRE(pm_prepare(&s, &v, &su, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
    REQUIRE(su.has_refraction == (mode > 0), "refraction flag");
    if (mode >= 2) pm_disable_octree(&su);
    double worst = 0.0;
    int rays = 0, most_points = 0;
    unsigned seed = 12345;
    while (rays < 200) {
      float o[3], target[3], dir[3];
      for (int a = 0; a < 3; a++) {
        seed = seed * 1664525u + 1013904223u;
        o[a] = (float)(seed >> 8) / 16777216.0f * 3.0f - 1.0f;
        seed = seed * 1664525u + 1013904223u;
        target[a] = 0.25f + 0.5f * (float)(seed >> 8) / 16777216.0f;
      }
      double len = 0.0;
      for (int a = 0; a < 3; a++) {
        dir[a] = target[a] - o[a];
        len += dir[a] * dir[a];
      }
      len = sqrt(len);
      for (int a = 0; a < 3; a++) dir[a] = (float)(dir[a] / len);
      /* skip rays that pass within 8 voxels of the varying corner */
      double t = -(o[0] * dir[0] + o[1] * dir[1] + o[2] * dir[2]);
      double q[3] = {o[0] + t * dir[0], o[1] + t * dir[1], o[2] + t * dir[2]};
      if (sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) < 8 * h) continue;
      int count;
      pm_result r;
      REQUIRE(pm_trace_ray(&su, o, dir, pts, MAXP, &count, &r, &err) == BK_OK, "trace: %s", err.msg);
      REQUIRE(count <= MAXP, "path too long");
      REQUIRE(r.fate == PM_FATE_LEFT, "ray %d: fate %u", rays, r.fate);
      worst = fmax(worst, path_deviation(pts, count, o, dir, h));
      most_points = count > most_points ? count : most_points;
      rays++;
    }
    printf("straight, %s: largest deviation %.3e voxel over %d rays (up to %d path points; "
           "limit %.0e)\n",
           names[mode], worst, rays, most_points, limits[mode]);
    REQUIRE(worst < limits[mode], "%s: deviation %.3e voxel", names[mode], worst);
    pm_setup_free(&su);
    tv_free(&v);
  }
  return 0;
}

/* Where the ray o + t d meets the grid's box [0, n] (the march's entry). */
static int enter_grid(bk_grid g, bk_v3 o, bk_v3 d, float *t0, float *t1) {
  return rc_slab(o, d, v3(0, 0, 0), v3((float)g.nx, (float)g.ny, (float)g.nz), t0, t1);
}

/* Where the ray o + t d (unit d, voxel units) leaves the box [0, n]. */
static double exit_t(const bk_grid g, bk_v3 o, bk_v3 d) {
  double t1 = 1e300;
  double ov[3] = {o.x, o.y, o.z}, dv[3] = {d.x, d.y, d.z}, nv[3] = {g.nx, g.ny, g.nz};
  for (int a = 0; a < 3; a++) {
    if (dv[a] == 0.0) continue;
    double ta = -ov[a] / dv[a], tb = (nv[a] - ov[a]) / dv[a];
    t1 = fmin(t1, fmax(ta, tb));
  }
  return t1;
}

/* Energy balance with constant n: Σ over voxels of Φ·ℓ equals
 * Σ over photons of Φ0 (1 - e^{-σt ℓ})/σt, ℓ the photon's in-grid length.
 * `grid_sigma`: the same extinction but read from the grid (non-homogeneous
 * path), with one far corner voxel 1e-4 different. */
static int test_energy(clh_context_t *cl, int grid_sigma) {
  const int N = 48;
  const float h = 2.0f / N;
  volume_t v;
  tv_alloc(&v, N, N, N, h, -1, -1, -1);
  const float ss[3] = {1.0f, 0.5f, 0.25f}, sa[3] = {2.0f, 1.5f, 0.75f}; /* σt = 3, 2, 1 */
  tv_fill(&v, 1.2f, ss, sa);
  if (grid_sigma) v.sigma_t[0] *= 1.0001f; /* σa until tv_summarise */
  tv_summarise(&v);
  scene_light_t lights[3] = {tl_spot(0.2f, 0.1f, -2.0f, 0, 0, 1, 30, 10, 5, 2),
                             tl_point(0.3f, -0.2f, 0.1f, 1, 2, 3),
                             tl_directional(0.3f, -1, 0.4f, 2)};
  scene_t s;
  ts_init(&s, lights, 3, 300000);
  pm_stats_t st;
  float *rad = tm_bake(cl, &s, &v, &st);
  tm_print_stats("energy", &st);
  REQUIRE(st.absorbed == 0 && st.step_limit == 0, "no photon should be absorbed or trapped");
  double got[3] = {0, 0, 0};
  const double V = (double)h * h * h;
  for (size_t i = 0; i < grid_count(&v.dims); i++)
    for (int c = 0; c < 3; c++) got[c] += rad[3 * i + c] * 4.0 * M_PI * V;

  /* the same photons again, on the host: ph_sample and the box */
  pm_setup_t su;
  bk_error_t err;
  REQUIRE(pm_prepare(&s, &v, &su, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
  double want[3] = {0, 0, 0};
  uint64_t missed = 0;
  for (int l = 0; l < su.lights.count; l++) {
    const ph_light *L = &su.lights.lights[l];
    for (bk_uint k = 0; k < L->count; k++) {
      bk_v3 o, d;
      float t0, t1;
      ph_sample(L, k, &o, &d);
      if (!enter_grid(su.params.grid, o, d, &t0, &t1)) {
        missed++;
        continue;
      }
      double len = (exit_t(su.params.grid, o, d) - t0) * h; /* metres */
      for (int c = 0; c < 3; c++) {
        double sig = ss[c] + sa[c];
        want[c] += L->power[c] * (-expm1(-sig * len)) / sig;
      }
    }
  }
  REQUIRE(missed == st.missed_grid, "missed photons: %llu on the host, %llu in the march",
        (unsigned long long)missed, (unsigned long long)st.missed_grid);
  double worst = 0.0;
  for (int c = 0; c < 3; c++) {
    double rel = got[c] / want[c] - 1.0;
    worst = fmax(worst, fabs(rel));
    printf("energy%s: channel %d: deposited %.9g W·m, expected %.9g W·m (%+.2e)\n",
           grid_sigma ? " (σ from the grid)" : "", c, got[c], want[c], rel);
  }
  REQUIRE(worst < 1e-3, "energy balance off by %.3e", worst);
  pm_setup_free(&su);
  free(rad);
  tv_free(&v);
  return 0;
}

/* Light set-up and generation: shares, powers, the cone, the seed. */
static int test_photons(void) {
  const double w[3] = {1, 2, 3};
  uint64_t counts[3];
  ph_share(w, 3, 10, counts);
  printf("photons: 10 shared by 1:2:3 -> %llu %llu %llu\n", (unsigned long long)counts[0],
         (unsigned long long)counts[1], (unsigned long long)counts[2]);
  REQUIRE(counts[0] == 2 && counts[1] == 3 && counts[2] == 5, "largest remainders");
  const double w0[2] = {0, 5};
  ph_share(w0, 2, 7, counts);
  REQUIRE(counts[0] == 0 && counts[1] == 7, "a dark light gets no photons");

  REQUIRE(ph_radical_inverse2(0) == 0.0f && ph_radical_inverse2(1) == 0.5f &&
            ph_radical_inverse2(2) == 0.25f && ph_radical_inverse2(3) == 0.75f &&
            ph_radical_inverse2(6) == 0.375f,
        "radical inverse base 2");

  /* a spot, a point and a directional light over a 32x16x8 grid */
  volume_t v;
  tv_alloc(&v, 32, 16, 8, 0.1f, 0, 0, 0);
  const float zero[3] = {0, 0, 0};
  tv_fill(&v, 1.0f, zero, zero);
  tv_summarise(&v);
  scene_light_t lights[3] = {tl_spot(1, 0.5f, -1, 0.3f, 0.2f, 1, 20, 3, 2, 1),
                             tl_point(1, 1, 1, 1, 1, 1), tl_directional(1, 1, 1, 2)};
  scene_t s;
  ts_init(&s, lights, 3, 100000);
  pm_setup_t a, b;
  bk_error_t err;
  REQUIRE(pm_prepare(&s, &v, &a, NULL, NULL, &err) == BK_OK, "%s", err.msg);
  double omega = 2.0 * M_PI * (1.0 - cos(20.0 * M_PI / 180.0));
  /* the directional rectangle: the box's projection across (1,1,1)/√3 */
  double want_power[3] = {6.0 * omega, 3.0 * 4.0 * M_PI, 0.0};
  REQUIRE(a.lights.count == 3 && a.channels == 3, "three lights, three channels");
  uint64_t total = 0;
  for (int l = 0; l < 3; l++) {
    const ph_light *L = &a.lights.lights[l];
    double p = (double)L->count * (L->power[0] + L->power[1] + L->power[2]);
    if (l < 2) REQUIRE(fabs(p / want_power[l] - 1.0) < 1e-5, "light %d power %g, want %g", l, p, want_power[l]);
    total += L->count;
    bk_v3 spot_axis = v3(0.3f, 0.2f, 1.0f);
    spot_axis = v3_normalize(spot_axis);
    for (bk_uint k = 0; k < L->count; k++) {
      bk_v3 o, d;
      ph_sample(L, k, &o, &d);
      REQUIRE(fabs(v3_length(d) - 1.0) < 1e-5, "unit directions");
      if (l == 0) REQUIRE(v3_dot(d, spot_axis) >= cos(20.0 * M_PI / 180.0) - 1e-6, "inside the cone");
      if (l == 2) {
        float t, t1;
        /* the rectangle starts before the grid: a photon that hits it enters at t > 0 */
        if (enter_grid(a.params.grid, o, d, &t, &t1)) REQUIRE(t > 0.0f, "directional photons start outside");
      }
    }
    printf("photons: light %d: %u photons of %.4g W (sum of RGB)\n", l, L->count,
           (double)(L->power[0] + L->power[1] + L->power[2]));
  }
  REQUIRE(total == 100000, "shares add up to the photon count");
  /* shares follow power: the counts' ratio is the powers' ratio */
  double r01 = (double)a.lights.lights[0].count / a.lights.lights[1].count;
  REQUIRE(fabs(r01 / (want_power[0] / want_power[1]) - 1.0) < 1e-3, "share ratio %g", r01);
  /* another seed: the same counts and powers, a different rotation */
  s.seed = 2;
  REQUIRE(pm_prepare(&s, &v, &b, NULL, NULL, &err) == BK_OK, "%s", err.msg);
  REQUIRE(b.lights.lights[0].count == a.lights.lights[0].count &&
            (b.lights.lights[0].rot_u != a.lights.lights[0].rot_u ||
             b.lights.lights[0].rot_v != a.lights.lights[0].rot_v),
        "the seed rotates the point set");
  pm_setup_free(&a);
  pm_setup_free(&b);
  tv_free(&v);
  return 0;
}

/* The launch order (light_sample.h): a permutation of every light's
 * photons, whose work-groups are compact patches of the light's domain. */
static int test_launch_order(void) {
  const uint32_t sizes[] = {1, 2, 255, 256, 1023, 1024, 3750, 4096, 62500, 65536, 100003, 1u << 20};
  for (size_t t = 0; t < sizeof sizes / sizeof sizes[0]; t++) {
    const uint32_t n = sizes[t];
    unsigned char *seen = calloc(n, 1);
    REQUIRE(seen != NULL, "memory");
    float worst = 0.0f;
    uint32_t rows, stride;
    ph_launch_plan(n, &rows, &stride);
    for (uint32_t g = 0; g < n; g += PH_TILE) { /* one work-group */
      float lo = 1.0f, hi = 0.0f;
      for (uint32_t k = g; k < n && k < g + PH_TILE; k++) {
        uint32_t p = ph_launch_order(k, n, rows, stride);
        REQUIRE(p < n && !seen[p], "n %u: slot %u gives photon %u twice or out of range", n, k, p);
        seen[p] = 1;
        float u = (float)p / (float)n;
        lo = u < lo ? u : lo, hi = u > hi ? u : hi;
      }
      worst = hi - lo > worst ? hi - lo : worst;
    }
    free(seen);
    /* a whole stripe's tile spans PH_TILE Q / n of u, Q^2 <= n / PH_TILE;
     * the remainder keeps index order (at most a stripe) */
    float bound = n >= 4 * PH_TILE ? 2.0f * sqrtf((float)PH_TILE / (float)n) : 1.0f;
    printf("launch order: n %u, widest work-group spans %.4f of u (bound %.4f)\n", n, worst, bound);
    REQUIRE(worst <= bound, "n %u: a work-group spans %g of u", n, worst);
  }
  return 0;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: test_march TEST [host|cl]\n");
    return 2;
  }
  bk_verbosity = 0;
  const char *t = argv[1];
  clh_context_t *cl = tm_path(argc > 2 ? argv[2] : "host");
  int rc;
  if (!strcmp(t, "beer_lambert")) rc = test_beer_lambert(cl);
  else if (!strcmp(t, "inverse_square")) rc = test_inverse_square(cl, 0);
  else if (!strcmp(t, "inverse_square_spot")) rc = test_inverse_square(cl, 1);
  else if (!strcmp(t, "photons")) rc = test_photons();
  else if (!strcmp(t, "launch_order")) rc = test_launch_order();
  else if (!strcmp(t, "straight")) rc = test_straight();
  else if (!strcmp(t, "energy")) rc = test_energy(cl, 0);
  else if (!strcmp(t, "energy_grid")) rc = test_energy(cl, 1);
  else {
    fprintf(stderr, "unknown test %s\n", t);
    rc = 2;
  }
  if (cl) clh_release(cl);
  return rc;
}
