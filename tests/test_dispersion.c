/* test_dispersion.c: n per colour channel (objects[].abbe, "ior": [nR, nG, nB]).
 *   parse DIR: the keys' values (the Abbe number's Cauchy split against its
 *     definition n_F - n_C = (n_d - 1)/V_d and against BK7's catalogue
 *     values) and their errors, each naming the file and the key.
 *   prism host|cl DIR: a 60-degree glass prism with n = 1.4, 1.5, 1.6 in R, G,
 *     B, built from a mesh file through the scene loader and the voxelizer,
 *     lit by a narrow spot beam at G's minimum-deviation incidence. Each
 *     channel's beam behind the prism (the centroid of its radiance per
 *     column of voxels, fitted by a line) must leave at Snell's law's
 *     two-surface deviation for that channel's n. RK4 at the default step
 *     of 0.5 voxel (measured errors -0.04, -0.09, -0.34 degrees); Euler's
 *     first-order error at sharp surfaces grows with n and the exit angle
 *     (-0.6, -1.9, -4.6 degrees at step 0.5, -0.2, -0.6, -1.5 at 0.1), a
 *     property of the integrator that tests/test_march_optics.c covers.
 *   view DIR: `baker view` of a file with an `ior_rgb` grid: a slab whose n
 *     grows along x at 0.2, 0.3, 0.4 per metre in R, G, B (a thin prism)
 *     deflects the camera rays towards +x by k_c L, so the bright block
 *     behind it shows shifted towards world -x, each channel by its own amount:
 *     the shifts against the same file without n (brightness-weighted
 *     column per channel) must be in the ratio of the gradients.
 * Usage: test_dispersion parse|prism [host|cl]|view DIR */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>

#include "test_march_util.h"
#include "exr.h"
#include "vdbio.h"
#include "view.h"
#include "voxelize.h"

#define DEG (3.14159265358979323846 / 180.0)

static const char *write_file(const char *dir, const char *name, const char *text) {
  static char path[2][1024];
  static int which;
  char *p = path[which ^= 1];
  snprintf(p, sizeof path[0], "%s/%s", dir, name);
  FILE *f = fopen(p, "wb");
  REQUIRE(f && fwrite(text, 1, strlen(text), f) == strlen(text) && fclose(f) == 0,
          "cannot write %s: %s", p, strerror(errno));
  return p;
}

/* --- parse ---------------------------------------------------------------- */

static const char *k_head =
    "{\"grid\": {\"bounds\": [[0,0,0],[1,1,1]], \"resolution\": 8},\n\"objects\": [";

static int load_object(const char *dir, const char *name, const char *object, scene_t *s,
                       bk_error_t *err) {
  char text[1024];
  snprintf(text, sizeof text, "%s{\"mesh\": \"m.obj\", %s}]}\n", k_head, object);
  write_file(dir, "m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  memset(err, 0, sizeof *err);
  return scene_load(write_file(dir, name, text), s, err);
}

static void expect_bad(const char *dir, const char *name, const char *object, const char *key,
                       const char *what) {
  scene_t s;
  bk_error_t err;
  int rc = load_object(dir, name, object, &s, &err);
  printf("%s -> %s\n", name, err.msg);
  EXPECT(rc == BK_ERR_INPUT, "%s: rc %d", name, rc);
  EXPECT(strstr(err.msg, name) && strstr(err.msg, key) && strstr(err.msg, what),
         "%s: message lacks the file, \"%s\" or \"%s\"", name, key, what);
  scene_free(&s);
}

static int test_parse(const char *dir) {
  scene_t s;
  bk_error_t err;
  /* BK7: n_d 1.5168, V_d 64.17; catalogue n_C 1.51432, n_F 1.52238 */
  REQUIRE(load_object(dir, "abbe.json", "\"ior\": 1.5168, \"abbe\": 64.17", &s, &err) == BK_OK,
          "%s", err.msg);
  const scene_object_t *o = &s.objects[0];
  printf("BK7 from abbe: n = %.5f %.5f %.5f\n", o->ior_rgb[0], o->ior_rgb[1], o->ior_rgb[2]);
  EXPECT(scene_has_dispersion(&s));
  EXPECT(o->ior == 1.5168f && scene_object_n(o, 1) == 1.5168f);
  EXPECT_NEAR(o->ior_rgb[2] - o->ior_rgb[0], 0.5168 / 64.17, 1e-6);
  EXPECT_NEAR(o->ior_rgb[0], 1.51432, 1e-4);
  EXPECT_NEAR(o->ior_rgb[2], 1.52238, 1e-4);
  scene_free(&s);
  REQUIRE(load_object(dir, "rgb.json", "\"ior\": [1.4, 1.5, 1.6]", &s, &err) == BK_OK, "%s",
          err.msg);
  EXPECT(scene_has_dispersion(&s) && s.objects[0].ior == 1.5f);
  EXPECT(scene_object_n(&s.objects[0], 0) == 1.4f && scene_object_n(&s.objects[0], 2) == 1.6f);
  scene_free(&s);
  /* no dispersion: a number, or three equal numbers */
  REQUIRE(load_object(dir, "plain.json", "\"ior\": 1.33", &s, &err) == BK_OK, "%s", err.msg);
  EXPECT(!scene_has_dispersion(&s) && scene_object_n(&s.objects[0], 2) == 1.33f);
  scene_free(&s);
  REQUIRE(load_object(dir, "grey.json", "\"ior\": [1.5, 1.5, 1.5]", &s, &err) == BK_OK, "%s",
          err.msg);
  EXPECT(!scene_has_dispersion(&s));
  scene_free(&s);
  expect_bad(dir, "abbe_zero.json", "\"abbe\": 0", "objects[0].abbe", "> 0");
  expect_bad(dir, "abbe_text.json", "\"abbe\": \"flint\"", "objects[0].abbe", "a number");
  expect_bad(dir, "abbe_small.json", "\"ior\": 1.5, \"abbe\": 0.1", "objects[0].abbe",
             "larger Abbe number");
  expect_bad(dir, "ior_text.json", "\"ior\": \"glass\"", "objects[0].ior", "a number or an array");
  expect_bad(dir, "rgb_two.json", "\"ior\": [1.5, 1.6]", "objects[0].ior", "array of 3");
  expect_bad(dir, "rgb_low.json", "\"ior\": [1.5, 0.9, 1.6]", "objects[0].ior[1]", "[1, 10]");
  expect_bad(dir, "rgb_and_abbe.json", "\"ior\": [1.5, 1.5, 1.6], \"abbe\": 40",
             "objects[0].abbe", "not both");
  return tu_failures ? 1 : 0;
}

/* --- prism ---------------------------------------------------------------- */

/* Deviation (radians) of a ray through a prism of apex angle A entering the
 * first face at incidence t1: Snell's law at both faces. */
static double prism_deviation(double n, double A, double t1) {
  double t2 = asin(sin(t1) / n), t3 = A - t2, t4 = asin(n * sin(t3));
  return t1 + t4 - A;
}

/* The prism: base y = 0.15 m from x = 0.2 to 0.6, apex up, 60 degrees,
 * extruded along z beyond the grid. */
static const char *k_prism_obj =
    "v 0.2 0.15 -0.1\nv 0.6 0.15 -0.1\nv 0.4 0.4964102 -0.1\n"
    "v 0.2 0.15 0.2\nv 0.6 0.15 0.2\nv 0.4 0.4964102 0.2\n"
    "f 1 3 2\nf 4 5 6\nf 1 2 5\nf 1 5 4\nf 2 3 6\nf 2 6 5\nf 3 1 4\nf 3 4 6\n";

static int test_prism(clh_context_t *cl, const char *dir) {
  const double A = 60.0 * DEG, n[3] = {1.4, 1.5, 1.6};
  const double t1 = asin(n[1] * sin(A / 2.0)); /* G at minimum deviation */
  const double dir_in = t1 - A / 2.0;         /* the beam's angle above +x */
  /* a 1-degree spot 0.25 m before the middle of the left face */
  const double mx = 0.3, my = 0.15 + 0.5 * 0.3464102;
  const double px = mx - 0.25 * cos(dir_in), py = my - 0.25 * sin(dir_in);
  char text[2048];
  write_file(dir, "prism.obj", k_prism_obj);
  snprintf(text, sizeof text,
           /* the whole grid: the beams are measured in the vacuum behind the prism */
           "{\"grid\": {\"bounds\": [[0,0,0],[1,0.8,0.1]], \"resolution\": 200,\n"
           "           \"crop_to_objects\": false},\n"
           " \"objects\": [{\"mesh\": \"prism.obj\", \"ior\": [%g, %g, %g]}],\n"
           " \"lights\": [{\"type\": \"spot\", \"position\": [%.7f, %.7f, 0.05],\n"
           "   \"direction\": [%.7f, %.7f, 0], \"angle_deg\": 1, \"intensity\": [1, 1, 1]}],\n"
           " \"photons\": {\"count\": 30000, \"integrator\": \"rk4\"}}\n",
           n[0], n[1], n[2], px, py, cos(dir_in), sin(dir_in));
  scene_t s;
  volume_t v;
  bk_error_t err = {0};
  REQUIRE(scene_load(write_file(dir, "prism.json", text), &s, &err) == BK_OK, "%s", err.msg);
  REQUIRE(vox_build(&s, &v, NULL, &err) == BK_OK, "%s", err.msg);
  REQUIRE(v.ior_rb, "a dispersive scene without n per channel");
  pm_stats_t st;
  float *rad = tm_bake(cl, &s, &v, &st);
  if (getenv("MARCH_VERBOSE")) tm_print_stats("prism", &st);
  /* each channel's beam centroid per column x in [135, 185) voxels, behind
   * the prism (it ends at x = 120), fitted by a line y = a + b x */
  const grid_dims_t *d = &v.dims;
  const int i0 = 135, i1 = 185;
  const double tol = 1.0; /* degrees: half a voxel at each end of the 50-voxel baseline */
  double dev[3];
  for (int c = 0; c < 3; c++) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int m = 0;
    for (int i = i0; i < i1; i++) {
      double sum = 0, syl = 0;
      for (int k = 0; k < d->nz; k++)
        for (int j = 0; j < d->ny; j++) {
          double l = rad[3 * grid_index(d, i, j, k) + c];
          sum += l;
          syl += l * (j + 0.5);
        }
      if (!(sum > 0)) continue;
      double x = i + 0.5, y = syl / sum;
      sx += x, sy += y, sxx += x * x, sxy += x * y, m++;
    }
    REQUIRE(m == i1 - i0, "channel %d: light in only %d of %d columns", c, m, i1 - i0);
    double b = (m * sxy - sx * sy) / (m * sxx - sx * sx);
    dev[c] = (dir_in - atan(b)) / DEG;
    double want = prism_deviation(n[c], A, t1) / DEG;
    printf("prism (%s) channel %c, n = %.2f: deviation %.3f deg, Snell %.3f deg, error %+.3f "
           "(limit %.1f)\n",
           cl ? "OpenCL" : "host", "RGB"[c], n[c], dev[c], want, dev[c] - want, tol);
    EXPECT(fabs(dev[c] - want) < tol, "channel %d off by %.3f deg", c, dev[c] - want);
  }
  free(rad);
  vox_free(&v);
  scene_free(&s);
  return tu_failures ? 1 : 0;
}

/* --- view ----------------------------------------------------------------- */

/* Writes the wedge file (dispersive: with `ior` and `ior_rgb`; else neither)
 * and views it; the brightness-weighted column of each channel, from the
 * image centre (pixels). */
static void view_centroids(const char *dir, int wedge, double col[3]) {
  enum { N = 48, W = 96, H = 48 };
  const float k[3] = {0.2f, 0.3f, 0.4f};
  grid_dims_t d = {N, N, N, 2.0f / N, {-1.0f, -1.0f, -1.0f}};
  size_t n = grid_count(&d);
  float *rad = calloc(3 * n, sizeof(float)), *rgb = calloc(3 * n, sizeof(float));
  float *ior = calloc(n, sizeof(float)), *st = calloc(n, sizeof(float));
  REQUIRE(rad && rgb && ior && st, "out of memory");
  for (int kk = 0; kk < N; kk++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) {
        size_t v = grid_index(&d, i, j, kk);
        float c[3];
        grid_voxel_center(&d, i, j, kk, c);
        /* the slab z in [-0.6, -0.2], its faces smoothed over 2 voxels */
        float dz = (fabsf(c[2] + 0.4f) - 0.2f) / d.voxel_size;
        float w = tv_weight(dz, 2.0f);
        for (int q = 0; q < 3; q++) rgb[3 * v + q] = 1.0f + w * k[q] * (c[0] + 1.0f);
        ior[v] = rgb[3 * v + 1];
        int block = fabsf(c[0]) < 0.1f && fabsf(c[1]) < 0.3f && c[2] > 0.3f && c[2] < 0.7f;
        for (int q = 0; q < 3; q++) rad[3 * v + q] = block ? 1.0f : 0.0f;
        st[v] = 0.2f;
      }
  vdbio_grid_t g[4] = {{"radiance", VDBIO_VEC3, rad, 1, 0.0f, NULL, NULL, 0},
                       {"extinction", VDBIO_FLOAT, st, 0, 0.0f, NULL, NULL, 0},
                       {"ior", VDBIO_FLOAT, ior, 0, 1.0f, NULL, NULL, 0},
                       {"ior_rgb", VDBIO_VEC3, rgb, 0, 1.0f, NULL, NULL, 0}};
  vdbio_write_opts_t wo = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
  bk_error_t err;
  char vdb[1024], exr[1024];
  snprintf(vdb, sizeof vdb, "%s/wedge%d.vdb", dir, wedge);
  snprintf(exr, sizeof exr, "%s/wedge%d.exr", dir, wedge);
  REQUIRE(vdbio_write(vdb, &d, g, wedge ? 4 : 2, NULL, 0, &wo, &err) == BK_OK, "%s", err.msg);
  free(rad), free(rgb), free(ior), free(st);
  char *argv[] = {"view", vdb, "-o", exr, "--camera-pos", "0,0,-4", "--look-at", "0,0,0",
                  "--fov", "10", "--resolution", "96x48", "-q", NULL};
  REQUIRE(view_main(13, argv) == 0, "baker view %s failed", vdb);
  int w, h;
  float *img = NULL;
  REQUIRE(exr_read_rgba(exr, &w, &h, &img, &err) == BK_OK, "%s", err.msg);
  for (int q = 0; q < 3; q++) {
    double sum = 0.0, sx = 0.0;
    for (int y = 0; y < h; y++)
      for (int x = 0; x < w; x++) {
        double b = img[4 * ((size_t)y * w + x) + q];
        sum += b;
        sx += b * (x + 0.5 - 0.5 * w);
      }
    REQUIRE(sum > 0.0, "%s: channel %d is black", exr, q);
    col[q] = sx / sum;
  }
  free(img);
}

static int test_view(const char *dir) {
  double plain[3], wedge[3], shift[3];
  const double k[3] = {0.2, 0.3, 0.4};
  view_centroids(dir, 0, plain);
  view_centroids(dir, 1, wedge);
  for (int c = 0; c < 3; c++) shift[c] = wedge[c] - plain[c];
  printf("view: the block's column shift through the wedge, R %+.2f G %+.2f B %+.2f px "
         "(plain %+.2f %+.2f %+.2f)\n",
         shift[0], shift[1], shift[2], plain[0], plain[1], plain[2]);
  /* rays bend towards +x, so the block appears towards world -x, which is
   * image +x for this camera (looking along +z, up +y); each channel's shift
   * follows its gradient (small angles: deflection k L), to 10% of G's */
  EXPECT(shift[1] > 2.0, "the wedge should shift the block by more than 2 px: %+.2f", shift[1]);
  for (int c = 0; c < 3; c += 2)
    EXPECT(fabs(shift[c] - shift[1] * k[c] / k[1]) < 0.1 * fabs(shift[1]),
           "channel %d shifted %+.2f px, expected %+.2f", c, shift[c], shift[1] * k[c] / k[1]);
  return tu_failures ? 1 : 0;
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: test_dispersion parse|view DIR | prism host|cl DIR\n");
    return 2;
  }
  bk_verbosity = 0;
  if (!strcmp(argv[1], "parse")) return test_parse(argv[2]);
  if (!strcmp(argv[1], "view")) return test_view(argv[2]);
  if (!strcmp(argv[1], "prism") && argc > 3) {
    clh_context_t *cl = tm_path(argv[2]);
    int rc = test_prism(cl, argv[3]);
    if (cl) clh_release(cl);
    return rc;
  }
  fprintf(stderr, "unknown test %s\n", argv[1]);
  return 2;
}
