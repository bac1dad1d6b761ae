/* test_view_render.c: `baker view` end to end on OpenCL (PoCL), through view_main.
 *
 *   cube DIR          a homogeneous cube of medium (vdbio_write, grey σ, a
 *                     corner block of other σ that the checked rays avoid, n = 1)
 *                     renders to σs L̄ (1 − e^(−σt D))/σt for the analytic path
 *                     length D: the centre pixel (D = the cube's side), an
 *                     off-axis pixel leaving through a side face, a pixel that
 *                     misses (0, alpha 0); tolerance 1%. Header attributes too.
 *   cube_rgb DIR      RGB extinction, no scattering grid (σs = σt), an ior grid
 *                     with a refracting blob away from the checked rays, RK4:
 *                     the curved-ray kernel gives the same closed form.
 *   sequence DIR      --frames 1-3x2 with #### / $F4 patterns: two EXRs with
 *                     their frame attribute, PNG previews at 2^EV exposure with
 *                     the sRGB curve, no image for frame 2.
 *   pyfile VDB DIR NAME ARGS  a fog volume written by pyopenvdb
 *                     (tests/view_pyfile.py, same ARGS) with its own voxel size,
 *                     translation and rotation renders to the closed form (the
 *                     path length measured in the file's own frame).
 *   host_device DIR   a refracting ball in a varying RGB medium rendered by the
 *                     OpenCL kernel and by the same code compiled for the host
 *                     (--device host), Euler and RK4: the images agree (99.5% of
 *                     pixels within 0.2%; grazing rays may part ways).
 *   lens DIR          a slab of light behind a ball of n = 1.5, above the line of
 *                     sight: seen without the ball it lies in the upper half of
 *                     the ball's disc, through the ball in the lower half (a
 *                     ball lens inverts; brightness-weighted row, > 2 px each way).
 *   lens_steps DIR    the same ball's image with RK4 at step 0.5 against 1/32
 *                     voxel: relative mean absolute difference < 0.003.
 *   bad CASE DIR      bad input exits 2, names the file, writes no image. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <png.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/common.h"
#include "exr.h"
#include "png_io.h"
#include "vdbio.h"
#include "view.h"
#include "test_util.h"

static char log_path[4096];

/* Runs view_main with the NULL-terminated arguments; stderr goes to log_path. */
static int run_view(const char *first, ...) {
  char *argv[64];
  int argc = 0;
  argv[argc++] = (char *)"view";
  va_list ap;
  va_start(ap, first);
  for (const char *a = first; a && argc < 63; a = va_arg(ap, const char *))
    argv[argc++] = (char *)a;
  va_end(ap);
  argv[argc] = NULL;
  fflush(stderr);
  int saved = dup(2);
  int fd = open(log_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) dup2(fd, 2);
  int rc = view_main(argc, argv);
  fflush(stderr);
  if (fd >= 0) close(fd);
  dup2(saved, 2);
  close(saved);
  return rc;
}

static char *read_log(void) {
  char *text = NULL;
  size_t len;
  bk_error_t err;
  if (bk_read_file(log_path, &text, &len, &err) != BK_OK) return strdup("");
  return text;
}

static int exists(const char *p) {
  struct stat st;
  return stat(p, &st) == 0;
}

/* --- analytic reference ----------------------------------------------------- */

typedef struct cam {
  double pos[3], look[3], up[3], fov;
  int w, h;
} cam_t;

/* The pinhole ray through pixel (px, py) (centres at +0.5, y down). */
static void pixel_dir(const cam_t *c, int px, int py, double d[3]) {
  double f[3], r[3], u[3], l;
  for (int k = 0; k < 3; k++) f[k] = c->look[k] - c->pos[k];
  l = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  for (int k = 0; k < 3; k++) f[k] /= l;
  r[0] = f[1] * c->up[2] - f[2] * c->up[1];
  r[1] = f[2] * c->up[0] - f[0] * c->up[2];
  r[2] = f[0] * c->up[1] - f[1] * c->up[0];
  l = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  for (int k = 0; k < 3; k++) r[k] /= l;
  u[0] = r[1] * f[2] - r[2] * f[1];
  u[1] = r[2] * f[0] - r[0] * f[2];
  u[2] = r[0] * f[1] - r[1] * f[0];
  double th = tan(0.5 * c->fov * 3.14159265358979323846 / 180.0), asp = (double)c->w / c->h;
  double sx = 2.0 * (px + 0.5) / c->w - 1.0, sy = 1.0 - 2.0 * (py + 0.5) / c->h;
  for (int k = 0; k < 3; k++) d[k] = f[k] + sx * th * asp * r[k] + sy * th * u[k];
  l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  for (int k = 0; k < 3; k++) d[k] /= l;
}

/* A box [lo, hi] in its own frame, world = scale · Rz(rot_deg) · local + shift. */
typedef struct box {
  double lo[3], hi[3];
  double scale, rot_deg, shift[3];
} box_t;

/* World length of the ray of pixel (px, py) inside the box. */
static double path_length(const cam_t *c, int px, int py, const box_t *b) {
  double d[3], o[3], dl[3], ol[3], tn = 0.0, tf = 1e300;
  pixel_dir(c, px, py, d);
  double th = -b->rot_deg * 3.14159265358979323846 / 180.0, cs = cos(th), sn = sin(th);
  for (int k = 0; k < 3; k++) o[k] = c->pos[k] - b->shift[k];
  /* into the local frame: rotate by -rot, divide by scale (t stays world length / scale) */
  ol[0] = (cs * o[0] - sn * o[1]) / b->scale, ol[1] = (sn * o[0] + cs * o[1]) / b->scale;
  ol[2] = o[2] / b->scale;
  dl[0] = cs * d[0] - sn * d[1], dl[1] = sn * d[0] + cs * d[1], dl[2] = d[2];
  for (int k = 0; k < 3; k++) {
    if (fabs(dl[k]) < 1e-15) {
      if (ol[k] < b->lo[k] || ol[k] > b->hi[k]) return 0.0;
      continue;
    }
    double a = (b->lo[k] - ol[k]) / dl[k], e = (b->hi[k] - ol[k]) / dl[k];
    tn = fmax(tn, fmin(a, e));
    tf = fmin(tf, fmax(a, e));
  }
  return tf > tn ? (tf - tn) * b->scale : 0.0;
}

/* Checks pixel (px, py) of an EXR against σs L̄ (1 − e^(−σt D))/σt. */
static void check_pixel(const char *exr, const cam_t *c, int px, int py, const box_t *box,
                        const double sig_t[3], const double sig_s[3], const double Lb[3],
                        double *D_out) {
  int w, h;
  float *img = NULL;
  bk_error_t err;
  if (exr_read_rgba(exr, &w, &h, &img, &err) != BK_OK) {
    EXPECT(0, "%s", err.msg);
    return;
  }
  EXPECT(w == c->w && h == c->h, "%s is %dx%d, want %dx%d", exr, w, h, c->w, c->h);
  double D = path_length(c, px, py, box);
  const float *p = img + 4 * ((size_t)py * w + px);
  double tmean = 0.0;
  for (int k = 0; k < 3; k++) {
    double T = exp(-sig_t[k] * D);
    double want = sig_s[k] * Lb[k] * (1.0 - T) / sig_t[k];
    tmean += T / 3.0;
    EXPECT(fabs(p[k] - want) <= 0.01 * want + 1e-4,
          "%s pixel (%d,%d) channel %d: %.6g, want %.6g (D %.5g)", exr, px, py, k, p[k], want, D);
  }
  EXPECT(fabs(p[3] - (1.0 - tmean)) <= 0.01 * (1.0 - tmean) + 1e-3,
        "%s pixel (%d,%d) alpha %.5g, want %.5g", exr, px, py, p[3], 1.0 - tmean);
  printf("%s pixel (%d,%d): D %.5f, rgb %.5f %.5f %.5f, alpha %.5f\n", exr, px, py, D, p[0], p[1],
         p[2], p[3]);
  if (D_out) *D_out = D;
  free(img);
}

/* --- the cube files ------------------------------------------------------------ */

enum { CN = 32 };
static const double CUBE_LB[3] = {1.0, 0.5, 0.25};

/* [-1,1]³ in 32³ voxels. kind 0: grey σt 1.5, σs 1 (σt 3, σs 0.5 in the
 * x,y >= 28 corner block), n = 1. kind 1: RGB σt (1.5, 0.8, 0.3), no
 * scattering grid, n = 1 with a 1.3 blob in the x,y,z <= 3 corner. */
static int write_cube(const char *path, int kind) {
  grid_dims_t d = {CN, CN, CN, 2.0f / CN, {-1.0f, -1.0f, -1.0f}};
  size_t n = grid_count(&d);
  float *rad = calloc(n * 3, sizeof(float)), *st = calloc(n * 3, sizeof(float));
  float *ss = calloc(n, sizeof(float)), *ior = calloc(n, sizeof(float));
  for (int k = 0; k < CN; k++)
    for (int j = 0; j < CN; j++)
      for (int i = 0; i < CN; i++) {
        size_t v = grid_index(&d, i, j, k);
        for (int c = 0; c < 3; c++) rad[3 * v + c] = (float)CUBE_LB[c];
        ior[v] = 1.0f;
        if (kind == 0) {
          int corner = i >= 28 && j >= 28;
          st[v] = corner ? 3.0f : 1.5f;
          ss[v] = corner ? 0.5f : 1.0f;
        } else {
          st[3 * v] = 1.5f, st[3 * v + 1] = 0.8f, st[3 * v + 2] = 0.3f;
          if (i <= 3 && j <= 3 && k <= 3) ior[v] = 1.3f;
        }
      }
  vdbio_grid_t g[4];
  int ng = 0;
  g[ng++] = (vdbio_grid_t){"radiance", VDBIO_VEC3, rad, 1, 0.0f, NULL, NULL, 0};
  g[ng++] = (vdbio_grid_t){"ior", VDBIO_FLOAT, ior, 0, 0.0f, NULL, NULL, 0};
  if (kind == 0) {
    g[ng++] = (vdbio_grid_t){"extinction", VDBIO_FLOAT, st, 0, 0.0f, NULL, NULL, 0};
    g[ng++] = (vdbio_grid_t){"scattering", VDBIO_FLOAT, ss, 0, 0.0f, NULL, NULL, 0};
  } else {
    g[ng++] = (vdbio_grid_t){"extinction", VDBIO_VEC3, st, 0, 0.0f, NULL, NULL, 0};
  }
  vdbio_meta_t meta[] = {{"frame", VDBIO_META_INT, NULL, 17, 0}};
  vdbio_write_opts_t wo = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
  bk_error_t err;
  int rc = vdbio_write(path, &d, g, ng, meta, 1, &wo, &err);
  if (rc) fprintf(stderr, "%s\n", err.msg);
  free(rad), free(st), free(ss), free(ior);
  return rc;
}

static const cam_t CUBE_CAM = {{0, 0, -4}, {0, 0, 0}, {0, 1, 0}, 50.0, 65, 49};

static void test_cube(const char *dir, int kind) {
  char vdb[4096], exr[4096];
  snprintf(vdb, sizeof vdb, "%s/view_cube%d.vdb", dir, kind);
  snprintf(exr, sizeof exr, "%s/view_cube%d.exr", dir, kind);
  remove(exr);
  if (write_cube(vdb, kind) != BK_OK) {
    EXPECT(0, "cannot write %s", vdb);
    return;
  }
  int rc = run_view(vdb, "-o", exr, "--camera-pos", "0,0,-4", "--look-at", "0,0,0", "--fov", "50",
                    "--resolution", "65x49", "--integrator", kind ? "rk4" : "euler", "-v", NULL);
  char *log = read_log();
  EXPECT(rc == 0, "view_main returned %d: %s", rc, log);
  fputs(log, stdout);
  free(log);
  const box_t box = {{-1, -1, -1}, {1, 1, 1}, 1.0, 0.0, {0, 0, 0}};
  const double st0[3] = {1.5, 1.5, 1.5}, ss0[3] = {1.0, 1.0, 1.0};
  const double st1[3] = {1.5, 0.8, 0.3};
  const double *st = kind ? st1 : st0, *ss = kind ? st1 : ss0;
  double D;
  check_pixel(exr, &CUBE_CAM, 32, 24, &box, st, ss, CUBE_LB, &D);
  EXPECT(fabs(D - 2.0) < 1e-9, "centre ray should cross the cube's side, D = %g", D);
  check_pixel(exr, &CUBE_CAM, 45, 12, &box, st, ss, CUBE_LB, &D);
  EXPECT(D > 0.3 && D < 1.9, "off-axis ray should leave through a side face, D = %g", D);
  check_pixel(exr, &CUBE_CAM, 0, 0, &box, st, ss, CUBE_LB, &D);
  EXPECT(D == 0.0, "corner ray should miss, D = %g", D);
  if (kind == 0) {
    char text[256];
    bk_error_t err;
    EXPECT(exr_read_attribute(exr, "cameraPosition", text, sizeof text, &err) == 0 &&
              !strcmp(text, "0 0 -4"), "cameraPosition: %s", text);
    EXPECT(exr_read_attribute(exr, "cameraFovYDeg", text, sizeof text, &err) == 0 &&
              !strcmp(text, "50"), "cameraFovYDeg: %s", text);
    EXPECT(exr_read_attribute(exr, "sourceFile", text, sizeof text, &err) == 0 && !strcmp(text, vdb),
          "sourceFile: %s", text);
    EXPECT(exr_read_attribute(exr, "frame", text, sizeof text, &err) == 0 && !strcmp(text, "17"),
          "frame (from the VDB's metadata): %s", text);
  }
}

/* --- a sequence with frame patterns ------------------------------------------ */

static int png_pixel(const char *path, int x, int y, unsigned char rgb[3]) {
  png_image im;
  memset(&im, 0, sizeof im);
  im.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&im, path)) return 0;
  im.format = PNG_FORMAT_RGB;
  unsigned char *buf = malloc(PNG_IMAGE_SIZE(im));
  int ok = buf && png_image_finish_read(&im, NULL, buf, 0, NULL);
  if (ok) memcpy(rgb, buf + 3 * ((size_t)y * im.width + x), 3);
  free(buf);
  png_image_free(&im);
  return ok;
}

static void test_sequence(const char *dir) {
  char a[4096], b[4096], in[4096], out[4096], png[4096], p[4096];
  snprintf(a, sizeof a, "%s/view_seq.0001.vdb", dir);
  snprintf(b, sizeof b, "%s/view_seq.0003.vdb", dir);
  snprintf(in, sizeof in, "%s/view_seq.####.vdb", dir);
  snprintf(out, sizeof out, "%s/view_seq_img.$F4.exr", dir);
  snprintf(png, sizeof png, "%s/view_seq_prev.####.png", dir);
  for (int f = 1; f <= 3; f++) {
    snprintf(p, sizeof p, "%s/view_seq_img.%04d.exr", dir, f);
    remove(p);
  }
  if (write_cube(a, 0) || write_cube(b, 0)) {
    EXPECT(0, "cannot write the frames");
    return;
  }
  int rc = run_view(in, "-o", out, "--png", png, "--exposure", "1", "--frames", "1-3x2",
                    "--camera-pos", "0,0,-4", "--look-at", "0,0,0", "--fov", "50", "--resolution",
                    "65x49", "-q", NULL);
  char *log = read_log();
  EXPECT(rc == 0, "view_main returned %d: %s", rc, log);
  free(log);
  snprintf(p, sizeof p, "%s/view_seq_img.0002.exr", dir);
  EXPECT(!exists(p), "frame 2 is not in 1-3x2 but %s exists", p);
  snprintf(p, sizeof p, "%s/view_seq_img.0001.exr", dir);
  EXPECT(exists(p), "%s missing", p);
  snprintf(p, sizeof p, "%s/view_seq_img.0003.exr", dir);
  char text[64] = "";
  bk_error_t err;
  EXPECT(exr_read_attribute(p, "frame", text, sizeof text, &err) == 0 && !strcmp(text, "3"),
        "%s frame attribute %s", p, text);
  /* the preview: 8-bit sRGB of 2 · L */
  int w, h;
  float *img = NULL;
  if (exr_read_rgba(p, &w, &h, &img, &err) == 0) {
    unsigned char rgb[3];
    snprintf(p, sizeof p, "%s/view_seq_prev.0003.png", dir);
    EXPECT(png_pixel(p, 32, 24, rgb), "cannot read %s", p);
    const float *px = img + 4 * (24 * w + 32);
    for (int c = 0; c < 3; c++) {
      int want = (int)lrintf(255.0f * png_srgb_oetf(2.0f * px[c]));
      EXPECT(abs(rgb[c] - want) <= 1, "%s centre channel %d: %d, want %d", p, c, rgb[c], want);
    }
    free(img);
  }
}

/* --- host C against the OpenCL kernel ---------------------------------------- */

static void test_host_device(const char *dir) {
  enum { N = 40 };
  grid_dims_t d = {N, N, N, 2.0f / N, {-1.0f, -1.0f, -1.0f}};
  size_t n = grid_count(&d);
  float *rad = calloc(n * 3, sizeof(float)), *st = calloc(n * 3, sizeof(float));
  float *ss = calloc(n, sizeof(float)), *ior = calloc(n, sizeof(float));
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) {
        size_t v = grid_index(&d, i, j, k);
        float c[3];
        grid_voxel_center(&d, i, j, k, c);
        float r = sqrtf((c[0] - 0.1f) * (c[0] - 0.1f) + c[1] * c[1] + c[2] * c[2]);
        float w = fminf(fmaxf(0.5f - (r - 0.5f) / (2.0f * d.voxel_size), 0.0f), 1.0f);
        ior[v] = 1.0f + 0.4f * w * w * (3.0f - 2.0f * w); /* a ball of n = 1.4 */
        float mod = 1.0f + 0.5f * sinf(3.0f * c[1]);
        for (int q = 0; q < 3; q++) {
          rad[3 * v + q] = c[0] < -0.6f ? 0.0f : 0.5f * (1.5f + c[q]);
          st[3 * v + q] = (0.8f + 0.2f * q) * mod;
        }
        ss[v] = 0.6f * mod;
      }
  vdbio_grid_t g[4] = {{"radiance", VDBIO_VEC3, rad, 1, 0.0f, NULL, NULL, 0}, {"ior", VDBIO_FLOAT, ior, 0, 0.0f, NULL, NULL, 0},
                       {"extinction", VDBIO_VEC3, st, 0, 0.0f, NULL, NULL, 0}, {"scattering", VDBIO_FLOAT, ss, 0, 0.0f, NULL, NULL, 0}};
  vdbio_write_opts_t wo = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
  bk_error_t err;
  char vdb[4096], a[4096], b[4096];
  snprintf(vdb, sizeof vdb, "%s/view_hd.vdb", dir);
  int rc = vdbio_write(vdb, &d, g, 4, NULL, 0, &wo, &err);
  free(rad), free(st), free(ss), free(ior);
  if (rc) {
    EXPECT(0, "%s", err.msg);
    return;
  }
  const char *integ[2] = {"euler", "rk4"};
  for (int t = 0; t < 2; t++) {
    snprintf(a, sizeof a, "%s/view_hd_cl_%s.exr", dir, integ[t]);
    snprintf(b, sizeof b, "%s/view_hd_host_%s.exr", dir, integ[t]);
    const char *common[] = {"--camera-pos", "0.2,0.3,-3", "--look-at", "0,0,0", "--fov", "40",
                            "--resolution", "64x48", "--integrator", integ[t], "-q"};
    rc = run_view(vdb, "-o", a, common[0], common[1], common[2], common[3], common[4], common[5],
                  common[6], common[7], common[8], common[9], common[10], NULL);
    EXPECT(rc == 0, "OpenCL render failed (%d)", rc);
    rc = run_view(vdb, "-o", b, "--device", "host", common[0], common[1], common[2], common[3],
                  common[4], common[5], common[6], common[7], common[8], common[9], common[10],
                  NULL);
    EXPECT(rc == 0, "host render failed (%d)", rc);
    int wa, ha, wb, hb;
    float *ia = NULL, *ib = NULL;
    if (exr_read_rgba(a, &wa, &ha, &ia, &err) || exr_read_rgba(b, &wb, &hb, &ib, &err)) {
      EXPECT(0, "%s", err.msg);
      free(ia);
      continue;
    }
    int off = 0, lit = 0;
    double worst = 0.0;
    for (int i = 0; i < wa * ha; i++) {
      int bad = 0;
      for (int c = 0; c < 4; c++) {
        double x = ia[4 * i + c], y = ib[4 * i + c], diff = fabs(x - y);
        double tol = 2e-3 * fmax(fabs(x), fabs(y)) + 1e-4;
        if (diff > tol) bad = 1;
        worst = fmax(worst, diff / (fmax(fabs(x), fabs(y)) + 1e-6));
      }
      off += bad;
      lit += ia[4 * i + 3] > 0.01f;
    }
    printf("%s: %d of %d pixels differ by more than 0.2%% (worst relative %.3g); %d pixels see the "
           "medium\n",
           integ[t], off, wa * ha, worst, lit);
    EXPECT(wa == wb && ha == hb, "sizes differ");
    EXPECT(off * 200 <= wa * ha, "%s: %d of %d pixels differ between OpenCL and host", integ[t], off,
          wa * ha);
    EXPECT(lit > wa * ha / 4, "%s: the medium should fill much of the image (%d pixels)", integ[t],
          lit);
    free(ia);
    free(ib);
  }
}

/* --- a ball lens inverts what lies behind it --------------------------------- */

/* A ball of n = 1.5 (radius 0.3 at z = -0.4) in a clear medium (σt = 0.2)
 * whose only light is a horizontal slab behind it and above the line of
 * sight (y in [0.12, 0.32], z in [0.3, 0.9]: beyond the focal length
 * nD/(4(n−1)) = 0.45 from the centre). Without the ball (n = 1) the slab
 * shows in the upper half of the ball's disc; through the ball its image is
 * real and inverted, in the lower half. Measured: the brightness-weighted
 * row of the pixels inside the disc, relative to the disc's centre row. */
static double lens_centroid(const char *dir, int lens, int *ok) {
  enum { N = 48 };
  grid_dims_t d = {N, N, N, 2.0f / N, {-1.0f, -1.0f, -1.0f}};
  size_t n = grid_count(&d);
  float *rad = calloc(n * 3, sizeof(float)), *st = calloc(n, sizeof(float));
  float *ior = calloc(n, sizeof(float));
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) {
        size_t v = grid_index(&d, i, j, k);
        float c[3];
        grid_voxel_center(&d, i, j, k, c);
        float r = sqrtf(c[0] * c[0] + c[1] * c[1] + (c[2] + 0.4f) * (c[2] + 0.4f));
        float w = fminf(fmaxf(0.5f - (r - 0.3f) / (2.0f * d.voxel_size), 0.0f), 1.0f);
        ior[v] = lens ? 1.0f + 0.5f * w * w * (3.0f - 2.0f * w) : 1.0f;
        int slab = c[1] >= 0.12f && c[1] <= 0.32f && c[2] >= 0.3f && c[2] <= 0.9f;
        for (int q = 0; q < 3; q++) rad[3 * v + q] = slab ? 1.0f : 0.0f;
        st[v] = 0.2f;
      }
  vdbio_grid_t g[3] = {{"radiance", VDBIO_VEC3, rad, 1, 0.0f, NULL, NULL, 0}, {"ior", VDBIO_FLOAT, ior, 0, 0.0f, NULL, NULL, 0},
                       {"extinction", VDBIO_FLOAT, st, 0, 0.0f, NULL, NULL, 0}};
  vdbio_write_opts_t wo = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
  bk_error_t err;
  char vdb[4096], exr[4096];
  snprintf(vdb, sizeof vdb, "%s/view_lens%d.vdb", dir, lens);
  snprintf(exr, sizeof exr, "%s/view_lens%d.exr", dir, lens);
  int rc = vdbio_write(vdb, &d, g, 3, NULL, 0, &wo, &err);
  free(rad), free(st), free(ior);
  *ok = 0;
  if (rc) {
    EXPECT(0, "%s", err.msg);
    return 0.0;
  }
  /* camera on the axis through the ball's centre; the disc's angular radius
   * is asin(0.3 / 3.6) = 4.8 deg, 11 px at this fov and height */
  const cam_t c = {{0, 0, -4}, {0, 0, -0.4}, {0, 1, 0}, 24.0, 64, 48};
  rc = run_view(vdb, "-o", exr, "--camera-pos", "0,0,-4", "--look-at", "0,0,-0.4", "--fov", "24",
                "--resolution", "64x48", "-q", NULL);
  EXPECT(rc == 0, "view of %s failed (%d)", vdb, rc);
  int w, h;
  float *img = NULL;
  if (rc || exr_read_rgba(exr, &w, &h, &img, &err) != BK_OK) return 0.0;
  double disc = asin(0.3 / 3.6), px_per_tan = 0.5 * h / tan(0.5 * c.fov * 3.14159265358979 / 180);
  double rdisc = tan(disc) * px_per_tan, sum = 0.0, wy = 0.0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double dx = x + 0.5 - 0.5 * w, dy = y + 0.5 - 0.5 * h;
      if (dx * dx + dy * dy > 0.8 * 0.8 * rdisc * rdisc) continue; /* inside the disc */
      double b = img[4 * ((size_t)y * w + x)];
      sum += b;
      wy += b * dy;
    }
  free(img);
  EXPECT(sum > 0.0, "%s: nothing bright inside the disc", exr);
  *ok = sum > 0.0;
  return sum > 0.0 ? wy / sum : 0.0;
}

static void test_lens(const char *dir) {
  int ok0, ok1;
  double plain = lens_centroid(dir, 0, &ok0), lens = lens_centroid(dir, 1, &ok1);
  printf("slab behind the disc: brightness-weighted row %+.2f px without the ball, %+.2f px "
         "through it (rows grow downwards; disc radius ~11 px)\n", plain, lens);
  if (!ok0 || !ok1) return;
  EXPECT(plain < -2.0, "without the ball the slab should show above the centre: %+.2f px", plain);
  EXPECT(lens > 2.0, "through the ball the slab should be inverted, below the centre: %+.2f px",
        lens);
}

/* The ball lens's image at the default step against one at 1/32 voxel
 * (RK4 both): the curved rays' path through the ball, where they cross the
 * field's constant cells straight (rc_cell_run) and step elsewhere. The
 * relative mean absolute difference over the image. */
#define LENS_STEP_TOLERANCE 0.003 /* measured 0.0013; 0.0058 with runs walked 1.5x too far */

static void test_lens_steps(const char *dir) {
  int ok;
  lens_centroid(dir, 1, &ok); /* writes view_lens1.vdb */
  if (!ok) return;
  char vdb[4096], exr[2][4096];
  snprintf(vdb, sizeof vdb, "%s/view_lens1.vdb", dir);
  const char *steps[2] = {"0.5", "0.03125"};
  float *img[2] = {NULL, NULL};
  int w = 0, h = 0;
  for (int i = 0; i < 2; i++) {
    snprintf(exr[i], sizeof exr[i], "%s/view_lens_step%d.exr", dir, i);
    int rc = run_view(vdb, "-o", exr[i], "--camera-pos", "0,0,-4", "--look-at", "0,0,-0.4",
                      "--fov", "24", "--resolution", "64x48", "--integrator", "rk4", "--step",
                      steps[i], "-q", NULL);
    bk_error_t err;
    EXPECT(rc == 0 && exr_read_rgba(exr[i], &w, &h, &img[i], &err) == BK_OK,
           "view of %s at step %s failed (%d)", vdb, steps[i], rc);
  }
  if (img[0] && img[1]) {
    double d = 0.0, r = 0.0;
    for (size_t p = 0; p < (size_t)w * h; p++)
      for (int c = 0; c < 3; c++)
        d += fabs(img[0][4 * p + c] - img[1][4 * p + c]), r += fabs(img[1][4 * p + c]);
    printf("ball lens, RK4 at step 0.5 against 1/32 voxel: relative mean absolute difference "
           "%.5f\n", d / r);
    EXPECT(d / r < LENS_STEP_TOLERANCE, "step 0.5 is %.5f off the converged image (at most %g)",
           d / r, LENS_STEP_TOLERANCE);
  }
  free(img[0]), free(img[1]);
}

/* --- a file from pyopenvdb ---------------------------------------------------- */

static int parse3(const char *s, double v[3]) {
  int n = sscanf(s, "%lf,%lf,%lf", &v[0], &v[1], &v[2]);
  if (n == 1) v[1] = v[2] = v[0];
  return n == 1 || n == 3;
}

static void test_pyfile(const char *vdb, const char *dir, const char *name, int argc, char **argv) {
  double vs = 0, tr[3] = {0, 0, 0}, Lb[3], st[3], ss[3], rot = 0.0;
  int imin = 0, imax = 0;
  for (int i = 0; i + 1 < argc; i += 2) {
    const char *k = argv[i], *v = argv[i + 1];
    if (!strcmp(k, "--voxel")) vs = atof(v);
    else if (!strcmp(k, "--translate")) parse3(v, tr);
    else if (!strcmp(k, "--imin")) imin = atoi(v);
    else if (!strcmp(k, "--imax")) imax = atoi(v);
    else if (!strcmp(k, "--rotate-z")) rot = atof(v);
    else if (!strcmp(k, "--radiance")) parse3(v, Lb);
    else if (!strcmp(k, "--extinction")) parse3(v, st);
    else if (!strcmp(k, "--scattering")) parse3(v, ss);
  }
  /* voxel i covers [i - 0.5, i + 0.5] in index space (cell-centred) */
  box_t box = {{imin - 0.5, imin - 0.5, imin - 0.5}, {imax + 0.5, imax + 0.5, imax + 0.5}, vs, rot,
               {tr[0], tr[1], tr[2]}};
  double mid = 0.5 * (imin + imax) * vs, side = (imax - imin + 1) * vs, ctr[3];
  double th = rot * 3.14159265358979323846 / 180.0;
  ctr[0] = cos(th) * mid - sin(th) * mid + tr[0];
  ctr[1] = sin(th) * mid + cos(th) * mid + tr[1];
  ctr[2] = mid + tr[2];
  cam_t c = {
      {ctr[0], ctr[1], ctr[2] - 2.5 * side}, {ctr[0], ctr[1], ctr[2]}, {0, 1, 0}, 45.0, 41, 31};
  char pos[128], look[128], exr[4096];
  snprintf(pos, sizeof pos, "%.9g,%.9g,%.9g", c.pos[0], c.pos[1], c.pos[2]);
  snprintf(look, sizeof look, "%.9g,%.9g,%.9g", c.look[0], c.look[1], c.look[2]);
  snprintf(exr, sizeof exr, "%s/%s.exr", dir, name);
  remove(exr);
  int rc = run_view(vdb, "-o", exr, "--camera-pos", pos, "--look-at", look, "--fov", "45",
                    "--resolution", "41x31", "-v", NULL);
  char *log = read_log();
  EXPECT(rc == 0, "view_main returned %d: %s", rc, log);
  fputs(log, stdout);
  free(log);
  double D;
  check_pixel(exr, &c, 20, 15, &box, st, ss, Lb, &D);
  EXPECT(fabs(D - side) < 1e-9, "centre ray D = %g, want the side %g", D, side);
  check_pixel(exr, &c, 28, 12, &box, st, ss, Lb, &D);
  EXPECT(D > 0.05 * side && D < 1.5 * side && fabs(D - side) > 0.02 * side, "off-axis ray D = %g",
        D);
  check_pixel(exr, &c, 0, 30, &box, st, ss, Lb, &D);
  EXPECT(D == 0.0, "corner ray should miss");
}

/* --- bad input ------------------------------------------------------------------- */

static void expect_refusal(const char *what, const char *exr, const char *png, const char *needle1,
                           const char *needle2, int rc) {
  char *log = read_log();
  printf("%s: exit %d: %s", what, rc, log);
  EXPECT(rc == BK_ERR_INPUT, "%s: exit %d, want 2", what, rc);
  EXPECT(!exists(exr), "%s: %s was written", what, exr);
  if (png) EXPECT(!exists(png), "%s: %s was written", what, png);
  EXPECT(!needle1 || strstr(log, needle1), "%s: message should name '%s': %s", what, needle1, log);
  EXPECT(!needle2 || strstr(log, needle2), "%s: message should mention '%s': %s", what, needle2,
        log);
  free(log);
}

static void test_bad(const char *which, const char *dir, const char *extra) {
  char vdb[4096], exr[4096], png[4096];
  snprintf(exr, sizeof exr, "%s/view_bad_%s.exr", dir, which);
  snprintf(png, sizeof png, "%s/view_bad_%s.png", dir, which);
  remove(exr);
  remove(png);
  snprintf(vdb, sizeof vdb, "%s/view_bad_%s.vdb", dir, which);
  grid_dims_t d = {8, 8, 8, 0.25f, {0, 0, 0}};
  static float data[8 * 8 * 8 * 3];
  for (size_t i = 0; i < sizeof data / sizeof data[0]; i++) data[i] = 0.5f;
  vdbio_write_opts_t wo = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
  bk_error_t err;
  int rc;
  if (!strcmp(which, "no_radiance")) {
    vdbio_grid_t g[2] = {{"density", VDBIO_FLOAT, data, 0, 0.0f, NULL, NULL, 0}, {"temperature", VDBIO_FLOAT, data, 0, 0.0f, NULL, NULL, 0}};
    EXPECT(vdbio_write(vdb, &d, g, 2, NULL, 0, &wo, &err) == 0, "%s", err.msg);
    rc = run_view(vdb, "-o", exr, "--png", png, NULL);
    expect_refusal(which, exr, png, vdb, "\"density\" (float)", rc);
  } else if (!strcmp(which, "radiance_float")) {
    vdbio_grid_t g[1] = {{"radiance", VDBIO_FLOAT, data, 0, 0.0f, NULL, NULL, 0}};
    EXPECT(vdbio_write(vdb, &d, g, 1, NULL, 0, &wo, &err) == 0, "%s", err.msg);
    rc = run_view(vdb, "-o", exr, "--png", png, NULL);
    expect_refusal(which, exr, png, vdb, "holds float values", rc);
  } else if (!strcmp(which, "radiance_bool")) { /* written by tests/view_pyfile.py */
    rc = run_view(extra, "-o", exr, NULL);
    expect_refusal(which, exr, NULL, extra, "holds bool values", rc);
  } else if (!strcmp(which, "nonuniform_transform")) { /* written by tests/view_pyfile.py */
    rc = run_view(extra, "-o", exr, NULL);
    expect_refusal(which, exr, NULL, extra, "non-uniform scale", rc);
  } else if (!strcmp(which, "look_at_equals_position")) {
    vdbio_grid_t g[1] = {{"radiance", VDBIO_VEC3, data, 1, 0.0f, NULL, NULL, 0}};
    EXPECT(vdbio_write(vdb, &d, g, 1, NULL, 0, &wo, &err) == 0, "%s", err.msg);
    rc = run_view(vdb, "-o", exr, "--camera-pos", "1,2,3", "--look-at", "1,2,3", NULL);
    expect_refusal(which, exr, NULL, "--look-at", "equals the camera position", rc);
  } else if (!strcmp(which, "zero_resolution")) {
    vdbio_grid_t g[1] = {{"radiance", VDBIO_VEC3, data, 1, 0.0f, NULL, NULL, 0}};
    EXPECT(vdbio_write(vdb, &d, g, 1, NULL, 0, &wo, &err) == 0, "%s", err.msg);
    rc = run_view(vdb, "-o", exr, "--resolution", "0x600", NULL);
    expect_refusal(which, exr, NULL, "--resolution", "0x600", rc);
  } else if (!strcmp(which, "truncated")) {
    vdbio_grid_t g[2] = {{"radiance", VDBIO_VEC3, data, 1, 0.0f, NULL, NULL, 0}, {"extinction", VDBIO_FLOAT, data, 0, 0.0f, NULL, NULL, 0}};
    EXPECT(vdbio_write(vdb, &d, g, 2, NULL, 0, &wo, &err) == 0, "%s", err.msg);
    struct stat st;
    EXPECT(stat(vdb, &st) == 0 && truncate(vdb, st.st_size / 2) == 0, "cannot truncate %s", vdb);
    rc = run_view(vdb, "-o", exr, "--png", png, NULL);
    expect_refusal(which, exr, png, vdb, NULL, rc);
  } else if (!strcmp(which, "missing_input")) {
    snprintf(vdb, sizeof vdb, "%s/view_no_such_file.vdb", dir);
    rc = run_view(vdb, "-o", exr, NULL);
    expect_refusal(which, exr, NULL, vdb, "No such file", rc);
  } else if (!strcmp(which, "missing_output_dir")) {
    vdbio_grid_t g[1] = {{"radiance", VDBIO_VEC3, data, 1, 0.0f, NULL, NULL, 0}};
    EXPECT(vdbio_write(vdb, &d, g, 1, NULL, 0, &wo, &err) == 0, "%s", err.msg);
    snprintf(exr, sizeof exr, "%s/view_no_such_dir/out.exr", dir);
    rc = run_view(vdb, "-o", exr, NULL);
    expect_refusal(which, exr, NULL, "view_no_such_dir", "does not exist", rc);
  } else if (!strcmp(which, "bad_frames")) {
    vdbio_grid_t g[1] = {{"radiance", VDBIO_VEC3, data, 1, 0.0f, NULL, NULL, 0}};
    EXPECT(vdbio_write(vdb, &d, g, 1, NULL, 0, &wo, &err) == 0, "%s", err.msg);
    char out[4096];
    snprintf(out, sizeof out, "%s/view_bad_frames.####.exr", dir);
    rc = run_view(vdb, "-o", out, "--frames", "9-3", NULL);
    expect_refusal(which, exr, NULL, "--frames", "9-3", rc);
  } else {
    EXPECT(0, "unknown bad-input case %s", which);
  }
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(
        stderr,
        "usage: test_view_render cube|cube_rgb|sequence|host_device|lens|lens_steps DIR | pyfile VDB DIR NAME "
        "ARGS | bad CASE DIR [FILE]\n");
    return 2;
  }
  const char *what = argv[1];
  const char *dir = !strcmp(what, "pyfile") || !strcmp(what, "bad") ? argv[3] : argv[2];
  snprintf(log_path, sizeof log_path, "%s/view_test_%s_%s.log", dir, what,
           !strcmp(what, "bad") ? argv[2] : !strcmp(what, "pyfile") && argc > 4 ? argv[4] : "run");
  if (!strcmp(what, "cube"))
    test_cube(dir, 0);
  else if (!strcmp(what, "cube_rgb"))
    test_cube(dir, 1);
  else if (!strcmp(what, "sequence"))
    test_sequence(dir);
  else if (!strcmp(what, "host_device"))
    test_host_device(dir);
  else if (!strcmp(what, "lens"))
    test_lens(dir);
  else if (!strcmp(what, "lens_steps"))
    test_lens_steps(dir);
  else if (!strcmp(what, "pyfile"))
    test_pyfile(argv[2], dir, argv[4], argc - 5, argv + 5);
  else if (!strcmp(what, "bad"))
    test_bad(argv[2], dir, argc > 4 ? argv[4] : NULL);
  else
    EXPECT(0, "unknown test %s", what);
  if (tu_failures) fprintf(stderr, "%d check(s) failed\n", tu_failures);
  return tu_failures ? 1 : 0;
}
