/* test_march_optics.c: curved paths against geometric optics.
 *   ball_lens PATH: collimated light through a smoothed ball of n = 1.5; the
 *     brightest voxel on the axis behind it against the paraxial focus
 *     EFL = nD/(4(n-1)) from the centre, at 64, 128 and 256 voxels.
 *   grin PATH BUILD_DIR: n² linear in y, written as a VDB and loaded through
 *     the voxelizer's ior_vdb; a thin beam follows the parabola
 *     x(t) = x0 + v0 t + ¼∇(n²) t² (dt = ds/n).
 * Usage: test_march_optics TEST host|cl [BUILD_DIR] */
#include "test_march_util.h"
#include "vdbio.h"

/* One ball-lens bake at `res` voxels along the axis: returns the distance
 * (voxels, signed) of the brightest on-axis voxel from the paraxial focus. */
static double ball_lens_error(clh_context_t *cl, int res, integrator_t integ, double *focus_vox,
                              double *peak_vox, double *march_ms) {
  /* the grid is res voxels along z (1 m) and a narrow W x W voxels across:
   * a thin beam of near-axis (paraxial) rays, W/D ~ 1/4 */
  int W = res / 16;
  if (W % 2 == 0) W++;
  const float h = 1.0f / res;
  volume_t v;
  tv_alloc(&v, W, W, res, h, 0, 0, 0);
  const float zero[3] = {0, 0, 0};
  tv_fill(&v, 1.0f, zero, zero);
  const float n = 1.5f, R = 0.125f; /* D = res/4 voxels */
  const float c[3] = {0.5f * W * h, 0.5f * W * h, 0.3f};
  tv_ball(&v, c, R, n, 2.0f, NULL, NULL);
  tv_summarise(&v);
  scene_light_t light = tl_directional(0, 0, 1, 1);
  scene_t s;
  ts_init(&s, &light, 1, 300LL * W * W); /* 300 photons per voxel column */
  s.integrator = integ;
  pm_stats_t st;
  float *rad = tm_bake(cl, &s, &v, &st);
  *march_ms = st.ms_march;
  if (getenv("MARCH_VERBOSE")) tm_print_stats("ball lens", &st);
  const double efl = n * (2.0 * R) / (4.0 * (n - 1.0));
  const double focus = c[2] + efl; /* metres along z */
  const int axis = (W - 1) / 2;
  int best = -1;
  float best_l = -1.0f;
  for (int k = (int)((c[2] + R) / h) + 2; k < res; k++) {
    float l = rad[3 * grid_index(&v.dims, axis, axis, k)];
    if (l > best_l) {
      best_l = l;
      best = k;
    }
  }
  REQUIRE(best >= 0 && best + 1 < res, "no light on the axis");
  double z = (best + 0.5) * h;
  /* the peak between voxels, from a parabola through the brightest three */
  float lm = rad[3 * grid_index(&v.dims, axis, axis, best - 1)],
        lp = rad[3 * grid_index(&v.dims, axis, axis, best + 1)];
  double den = lm - 2.0 * best_l + lp;
  *peak_vox = best + 0.5 + (den < 0.0 ? 0.5 * (lm - lp) / den : 0.0) - focus / h;
  *focus_vox = focus / h;
  free(rad);
  tv_free(&v);
  return (z - focus) / h;
}

static int test_ball_lens(clh_context_t *cl) {
  const int res[3] = {64, 128, 256};
  const char *names[2] = {"Euler", "RK4"};
  double err[2][3];
  for (int m = 0; m < 2; m++)
    for (int r = 0; r < 3; r++) {
      double f, peak, ms;
      err[m][r] = ball_lens_error(cl, res[r], m ? INTEGRATOR_RK4 : INTEGRATOR_EULER, &f, &peak, &ms);
      printf("ball lens %-5s %3d voxels: D = %3d voxels, focus at %6.1f voxels, brightest axis "
             "voxel %+5.1f voxels from it (%+.4f D; interpolated peak %+6.2f voxels) [%.0f ms]\n",
             names[m], res[r], res[r] / 4, f, err[m][r], err[m][r] / (res[r] / 4.0), peak, ms);
    }
  for (int m = 0; m < 2; m++) {
    REQUIRE(fabs(err[m][2]) <= 2.0, "%s at 256: focus %.1f voxels off (limit 2)", names[m], err[m][2]);
    /* in units of the ball's diameter, the error falls as the grid is refined */
    REQUIRE(fabs(err[m][2]) / 64.0 < fabs(err[m][0]) / 16.0 + 1e-9,
          "%s: error does not shrink from 64 to 256 voxels (%.3f D -> %.3f D)", names[m],
          fabs(err[m][0]) / 16.0, fabs(err[m][2]) / 64.0);
  }
  return 0;
}

/* n² = n0² + G y over the unit cube. */
#define GRIN_RES 128
#define GRIN_N0 1.2
#define GRIN_G 0.896 /* per metre: 0.007 per voxel at 128 */

static double grin_y(double y0, double x) {
  double n = sqrt(GRIN_N0 * GRIN_N0 + GRIN_G * y0);
  double t = x / n; /* the beam enters at x = 0 */
  return y0 + 0.25 * GRIN_G * t * t;
}

static int test_grin(clh_context_t *cl, const char *dir) {
  char path[4096];
  snprintf(path, sizeof path, "%s/march_grin_field_%s.vdb", dir, cl ? "cl" : "host");
  bk_error_t err;
  memset(&err, 0, sizeof err);

  /* the field, written as the VDB a user would bring */
  scene_t s;
  scene_light_t lights[3];
  const double y0s[3] = {0.1, 0.3, 0.5};
  const float zmid = 0.5f + 0.3f / GRIN_RES; /* off the voxel faces */
  for (int b = 0; b < 3; b++)
    lights[b] = tl_spot(-0.005f, (float)y0s[b], zmid, 1, 0, 0, 0.3f, 1, 1, 1);
  ts_init(&s, lights, 3, 30000);
  for (int a = 0; a < 3; a++) s.bounds_min[a] = 0.0f, s.bounds_max[a] = 1.0f;
  s.resolution = GRIN_RES;
  s.ior_smoothing = 2.0f;
  grid_dims_t d;
  REQUIRE(grid_dims_from_bounds(s.bounds_min, s.bounds_max, s.resolution, "test", &d, &err) == BK_OK,
        "%s", err.msg);
  float *field = malloc(grid_count(&d) * sizeof(float));
  REQUIRE(field, "out of memory");
  for (int k = 0; k < d.nz; k++)
    for (int j = 0; j < d.ny; j++)
      for (int i = 0; i < d.nx; i++) {
        float p[3];
        grid_voxel_center(&d, i, j, k, p);
        field[grid_index(&d, i, j, k)] = (float)sqrt(GRIN_N0 * GRIN_N0 + GRIN_G * p[1]);
      }
  vdbio_grid_t g = {"ior", VDBIO_FLOAT, field, 0, 0.0f, NULL, NULL, 0};
  REQUIRE(vdbio_write(path, &d, &g, 1, NULL, 0, NULL, &err) == BK_OK, "vdbio_write: %s", err.msg);
  free(field);
  s.ior_vdb.present = 1;
  snprintf(s.ior_vdb.file, sizeof s.ior_vdb.file, "%s", path);
  snprintf(s.ior_vdb.grid, sizeof s.ior_vdb.grid, "ior");
  snprintf(s.ior_vdb.where, sizeof s.ior_vdb.where, "test: medium.ior_vdb");

  volume_t v;
  REQUIRE(vox_build(&s, &v, NULL, &err) == BK_OK, "vox_build: %s", err.msg);
  remove(path);
  REQUIRE(v.has_refraction, "the ior_vdb field should make n vary");
  const float h = v.dims.voxel_size;
  const char *names[2] = {"Euler", "RK4"};

  for (int m = 0; m < 2; m++) {
    s.integrator = m ? INTEGRATOR_RK4 : INTEGRATOR_EULER;
    double worst_path = 0.0;
    if (!cl) {
      /* the central rays, traced point by point */
      pm_setup_t su;
      REQUIRE(pm_prepare(&s, &v, &su, NULL, NULL, &err) == BK_OK, "pm_prepare: %s", err.msg);
      enum { MAXP = 8192 };
      static float pts[3 * MAXP];
      for (int b = 0; b < 3; b++) {
        const float o[3] = {-0.005f, (float)y0s[b], zmid}, dirv[3] = {1, 0, 0};
        int count;
        pm_result r;
        REQUIRE(pm_trace_ray(&su, o, dirv, pts, MAXP, &count, &r, &err) == BK_OK, "%s", err.msg);
        REQUIRE(count <= MAXP && r.fate == PM_FATE_LEFT, "ray %d: %d points, fate %u", b, count,
              r.fate);
        for (int p = 1; p < count; p++)
          worst_path = fmax(worst_path, fabs(pts[3 * p + 1] - grin_y(y0s[b], pts[3 * p])) / h);
        printf("grin %-5s ray y0 = %.1f m: leaves at x = %.3f m, y = %.4f m (parabola %.4f m)\n",
               names[m], y0s[b], pts[3 * (count - 1)], pts[3 * (count - 1) + 1],
               grin_y(y0s[b], pts[3 * (count - 1)]));
      }
      pm_setup_free(&su);
      printf("grin %-5s traced paths: largest distance from the parabola %.2e voxel (limit 1)\n",
             names[m], worst_path);
      REQUIRE(worst_path < 1.0, "%s: path %.3f voxels off the parabola", names[m], worst_path);
    }
    /* the beams' deposits: the centroid of each beam in every x slice */
    pm_stats_t st;
    float *rad = tm_bake(cl, &s, &v, &st);
    double worst_beam = 0.0;
    int slices = 0;
    for (int b = 0; b < 3; b++) {
      double lo = y0s[b] - 0.02, hi = y0s[b] + 0.17; /* each beam's own band of y */
      for (int i = 0; i < v.dims.nx; i++) {
        double sum = 0.0, sy = 0.0;
        for (int k = 0; k < v.dims.nz; k++)
          for (int j = 0; j < v.dims.ny; j++) {
            double y = (j + 0.5) * h;
            if (y < lo || y > hi) continue;
            double l = rad[3 * grid_index(&v.dims, i, j, k)];
            sum += l;
            sy += l * y;
          }
        if (!(sum > 0.0)) continue;
        double x = (i + 0.5) * h;
        worst_beam = fmax(worst_beam, fabs(sy / sum - grin_y(y0s[b], x)) / h);
        slices++;
      }
    }
    printf("grin %-5s beams (%s): largest centroid distance from the parabola %.3f voxel over %d "
           "slices (limit 1)\n",
           names[m], cl ? "OpenCL" : "host", worst_beam, slices);
    REQUIRE(slices >= 3 * v.dims.nx - 3, "beams missing from %d slices", 3 * v.dims.nx - slices);
    REQUIRE(worst_beam < 1.0, "%s: beam %.3f voxels off the parabola", names[m], worst_beam);
    free(rad);
  }
  vox_free(&v);
  return 0;
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: test_march_optics ball_lens|grin host|cl [BUILD_DIR]\n");
    return 2;
  }
  bk_verbosity = 0;
  clh_context_t *cl = tm_path(argv[2]);
  int rc = 2;
  if (!strcmp(argv[1], "ball_lens")) rc = test_ball_lens(cl);
  else if (!strcmp(argv[1], "grin")) rc = test_grin(cl, argc > 3 ? argv[3] : ".");
  else fprintf(stderr, "unknown test %s\n", argv[1]);
  if (cl) clh_release(cl);
  return rc;
}
