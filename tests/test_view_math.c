/* test_view_math.c: the viewing pass's host-side truths, no OpenCL needed.
 *
 *   frames  frame ranges and patterns (####, $F4, $F), errors for bad ranges
 *   srgb    the sRGB OETF at its break point and known values
 *   camera  pinhole directions: centre pixel = forward, corners at the
 *           vertical/horizontal half-angles
 *   march   kernels/view_march.h run on the host through a homogeneous cube equals
 *           σs L̄ (1 − e^(−σt D))/σt for the analytic path length D (straight
 *           and curved code paths, grey and RGB, Euler and RK4, every kind
 *           of constant block)
 * The ray core itself (field, step, attenuation, pyramid) is
 * tests/test_ray_core.c's. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/common.h"
#include "base/frames.h"
#include "field.h"
#include "kernels/view_march.h"
#include "png_io.h"
#include "view.h"
#include "test_util.h"

static void expect_expand(const char *pat, int frame, const char *want) {
  char out[256];
  bk_error_t err;
  int rc = frames_expand(pat, frame, out, sizeof out, &err);
  EXPECT(rc == BK_OK && !strcmp(out, want), "expand(%s, %d) = %s, want %s", pat, frame,
        rc ? err.msg : out, want);
}

static void test_frames(void) {
  frames_range_t r;
  bk_error_t err;
  EXPECT(frames_parse("7", "--frames", &r, &err) == BK_OK && r.first == 7 && r.last == 7 &&
            r.step == 1 && frames_count(&r) == 1, "single frame");
  EXPECT(frames_parse("1-100", "--frames", &r, &err) == BK_OK && frames_count(&r) == 100, "1-100");
  EXPECT(frames_parse("1-100x2", "--frames", &r, &err) == BK_OK && frames_count(&r) == 50 &&
            frames_at(&r, 49) == 99, "1-100x2: %d frames, last %d", frames_count(&r),
        frames_at(&r, frames_count(&r) - 1));
  EXPECT(frames_parse("-10--1x3", "--frames", &r, &err) == BK_OK && r.first == -10 &&
            r.last == -1 && frames_count(&r) == 4 && frames_at(&r, 3) == -1, "negative range");
  const char *bad[] = {"", "a", "1-", "-", "5-1", "1-10x0", "1-10x-2", "1-10y2", " 1-2", "1-2 ",
                       "1-99999999", "1.5", "1-10x", "99999999999"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    err.msg[0] = 0;
    int rc = frames_parse(bad[i], "--frames", &r, &err);
    EXPECT(rc == BK_ERR_INPUT && strstr(err.msg, "--frames"), "'%s' should be refused (rc %d: %s)",
          bad[i], rc, err.msg);
  }
  expect_expand("a.####.vdb", 42, "a.0042.vdb");
  expect_expand("a.#.vdb", 42, "a.42.vdb");
  expect_expand("a.######.vdb", 7, "a.000007.vdb");
  expect_expand("a.$F4.vdb", 42, "a.0042.vdb");
  expect_expand("a.$F.vdb", 42, "a.42.vdb");
  expect_expand("a_$F2_##.exr", 5, "a_05_05.exr");
  expect_expand("a.####.vdb", -3, "a.-003.vdb");
  expect_expand("$FPS/$FF.vdb", 3, "$FPS/$FF.vdb"); /* other Houdini variables stay */
  expect_expand("plain.vdb", 3, "plain.vdb");
  EXPECT(frames_has_pattern("x.####.exr") && frames_has_pattern("x.$F4.exr") &&
            frames_has_pattern("x$F.exr") && !frames_has_pattern("x.exr") &&
            !frames_has_pattern("$FPS.exr"), "has_pattern");
  char small[8];
  EXPECT(frames_expand("abcd_####.exr", 1, small, sizeof small, &err) == BK_ERR_INPUT,
        "too long must fail");
}

static void test_srgb(void) {
  EXPECT(png_srgb_oetf(0.0f) == 0.0f && png_srgb_oetf(1.0f) == 1.0f &&
            png_srgb_oetf(-1.0f) == 0.0f && png_srgb_oetf(7.0f) == 1.0f,
        "ends");
  EXPECT(fabsf(png_srgb_oetf(0.0031308f) - 0.0404500f) < 1e-5f, "break point: %g",
        png_srgb_oetf(0.0031308f));
  EXPECT(fabsf(png_srgb_oetf(0.18f) - 0.4613561f) < 1e-5f, "mid grey: %g", png_srgb_oetf(0.18f));
  EXPECT(fabsf(png_srgb_oetf(0.5f) - 0.7353570f) < 1e-5f, "half: %g", png_srgb_oetf(0.5f));
  EXPECT(fabsf(png_srgb_oetf(0.001f) - 0.01292f) < 1e-6f, "linear part");
}

/* Camera at the origin of voxel space looking +z, up +y. */
static view_params_t cam_params(float fov_deg, int w, int h) {
  view_params_t p;
  memset(&p, 0, sizeof p);
  float th = tanf(0.5f * fov_deg * 3.14159265f / 180.0f), asp = (float)w / (float)h;
  p.cam_forward = v3(0, 0, 1);
  bk_v3 right = v3_cross(p.cam_forward, v3(0, 1, 0)); /* -x */
  p.cam_right = v3_scale(right, th * asp);
  p.cam_up = v3(0, th, 0);
  p.width = w;
  p.height = h;
  return p;
}

static void test_camera(void) {
  view_params_t p = cam_params(40.0f, 81, 61);
  bk_v3 d = view_camera_dir(&p, 40.5f, 30.5f);
  EXPECT(fabsf(d.x) < 1e-6f && fabsf(d.y) < 1e-6f && fabsf(d.z - 1.0f) < 1e-6f, "centre pixel");
  /* the top edge of the image is at the vertical half-angle */
  d = view_camera_dir(&p, 40.5f, 0.0f);
  float ang = atan2f(d.y, d.z) * 180.0f / 3.14159265f;
  EXPECT(fabsf(ang - 20.0f) < 1e-3f && fabsf(d.x) < 1e-6f, "top edge at %g deg", ang);
  /* the right edge: horizontal half-angle atan(tan(20°)·aspect), towards -x */
  d = view_camera_dir(&p, 81.0f, 30.5f);
  float want = atanf(tanf(20.0f * 3.14159265f / 180.0f) * 81.0f / 61.0f) * 180.0f / 3.14159265f;
  ang = atan2f(-d.x, d.z) * 180.0f / 3.14159265f;
  EXPECT(fabsf(ang - want) < 1e-3f, "right edge at %g deg, want %g", ang, want);
}

/* Pyramid levels for a 16³ grid (8³ finest blocks of 2³) from one level
 * per brick (8³ voxels, 4³ finest blocks), bricks numbered b&1, b>>1&1, b>>2. */
static void fill_pyramid(unsigned char pyr[512], const unsigned char brick_level[8]) {
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++) pyr[i + 8 * (j + 8 * k)] = brick_level[(i >> 2) + 2 * (j >> 2) + 4 * (k >> 2)];
}

/* Length of a ray's path through the N³ box. */
static float box_path(bk_v3 o, bk_v3 d, float n) {
  float t0, t1;
  return rc_slab(o, d, v3(0, 0, 0), v3(n, n, n), &t0, &t1) ? t1 - t0 : 0.0f;
}

/* Homogeneous cube of N³ voxels: the host runs the kernel's march, through
 * every code path (straight/curved, Euler/RK4, grey/RGB, lookups/constants,
 * brick-crossing steps, straight chords in fine blocks of n, mixed bricks),
 * against the closed form. Levels: n pyramid 2 = the brick's n is constant,
 * 1 = only its 2³ blocks are (straight chords inside a refracting brick),
 * 0 = curved steps, or in odd variants straight runs across the field's
 * constant cells (all flagged: n is 1 throughout); medium pyramid 2 = one
 * step per brick. */
static void test_march(void) {
  enum { N = 16, NP = (N + 2) * (N + 2) * (N + 2) };
  static float medium[N * N * N * 4], st4[N * N * N * 4], ior[N * N * N];
  static float medium_p[NP * 4], st4_p[NP * 4];
  const rc_dims dims = {N, N, N};
  enum { CELL_BYTES = 867 }; /* rc_cell_byte(dims, N, N, N) + 1 */
  static unsigned char npyr[512 + CELL_BYTES], mpyr[512];
  const float Lb[3] = {1.0f, 0.5f, 0.25f}, sigs[3] = {0.1f, 0.05f, 0.02f};
  const float rgb_t[3] = {0.12f, 0.05f, 0.3f}, grey_t = 0.12f;
  view_params_t p = cam_params(60.0f, 33, 33);
  p.cam_pos = v3(8.0f, 8.0f, -20.0f);
  p.nx = p.ny = p.nz = N;
  p.step = 0.5f;
  p.straight_step = 1.0f;
  p.max_steps = 10000;
  p.background = v3(0.2f, 0.1f, 0.0f);
  p.sigma_t = v3(rgb_t[0], rgb_t[1], rgb_t[2]);
  enum { CHECKER = 0x80 }; /* the levels alternate brick by brick */
  /* refraction, grey, integrator, homogeneous, dispersion, aniso, grey light;
   * n level, medium level */
  const struct { view_flags fl; int nlev, mlev; } var[] = {
      {{0, 0, VIEW_EULER, 0, 0, 0, 0}, 0, 0},
      {{0, 0, VIEW_EULER, 1, 0, 0, 0}, 0, 2},
      {{0, 1, VIEW_EULER, 0, 0, 0, 0}, 0, 0},
      {{1, 0, VIEW_EULER, 0, 0, 0, 0}, 2, 0},
      {{1, 1, VIEW_RK4, 0, 0, 0, 0}, 0, 0},
      {{1, 0, VIEW_EULER, 1, 0, 0, 0}, 2, 2},
      {{1, 1, VIEW_EULER, 0, 0, 0, 0}, 1, 0},
      {{1, 0, VIEW_RK4, 1, 0, 0, 0}, 1, 2},
      /* CHECKER: chords of varying bricks, single-step bricks, straight fine
       * blocks and curved steps follow one another along a ray */
      {{0, 1, VIEW_EULER, 0, 0, 0, 0}, 0, CHECKER | 2},
      {{1, 1, VIEW_EULER, 0, 0, 0, 0}, CHECKER | 2, CHECKER | 2},
      {{1, 0, VIEW_RK4, 0, 0, 0, 0}, CHECKER | 2, 0},
      {{1, 1, VIEW_EULER, 0, 0, 0, 0}, CHECKER | 1, 0},
      /* grey light: the medium as {S, σt}, two floats */
      {{0, 1, VIEW_EULER, 0, 0, 0, 1}, 0, 0},
      {{1, 1, VIEW_RK4, 0, 0, 0, 1}, 0, 0},
      {{1, 1, VIEW_EULER, 0, 0, 0, 1}, CHECKER | 2, CHECKER | 2},
  };
  bk_error_t err = {0};
  for (int i = 0; i < N * N * N; i++) ior[i] = 1.0f;
  float *ng = fld_build(N, N, N, 1.0, ior, &err);
  REQUIRE(ng, "%s", err.msg);
  for (size_t vi = 0; vi < sizeof var / sizeof var[0]; vi++) {
    const view_flags fl = var[vi].fl;
    float sigt[3], src[3]; /* σt and S = σs L̄ per channel */
    for (int c = 0; c < 3; c++) {
      sigt[c] = fl.grey ? grey_t : rgb_t[c];
      src[c] = fl.grey_light ? sigs[0] * Lb[0] : sigs[c] * Lb[c];
    }
    for (int i = 0; i < N * N * N; i++) {
      for (int c = 0; c < 3; c++) medium[4 * i + c] = src[c], st4[4 * i + c] = rgb_t[c];
      medium[4 * i + 3] = fl.grey ? grey_t : 0.0f;
    }
    unsigned char nb[8], mb[8];
    for (int b = 0; b < 8; b++) {
      int odd = ((b & 1) + (b >> 1 & 1) + (b >> 2)) % 2;
      nb[b] = !(var[vi].nlev & CHECKER) ? var[vi].nlev : odd ? var[vi].nlev & ~CHECKER : 0;
      mb[b] = !(var[vi].mlev & CHECKER) ? var[vi].mlev : odd ? var[vi].mlev & ~CHECKER : 0;
    }
    fill_pyramid(npyr, nb);
    REQUIRE(rc_cell_byte(dims, N, N, N) + 1 == CELL_BYTES, "cell flags' size");
    memset(npyr + 512, vi & 1 ? 0xff : 0, CELL_BYTES);
    fill_pyramid(mpyr, mb);
    fld_pad4(N, N, N, medium, medium_p);
    fld_pad4(N, N, N, st4, st4_p);
    if (fl.grey_light) /* {S, σt}: lanes x and w, in place (the reads run ahead) */
      for (int i = 0; i < NP; i++) {
        medium_p[2 * i] = medium_p[4 * i];
        medium_p[2 * i + 1] = medium_p[4 * i + 3];
      }
    view_fields f = {medium_p, st4_p, ng, npyr, mpyr, NULL, NULL};
    const int px[3] = {16, 25, 0}, py[3] = {16, 9, 32};
    for (int k = 0; k < 3; k++) {
      float rgba[4];
      bk_uint steps;
      view_march_pixel(&p, f, fl, px[k], py[k], rgba, &steps);
      float D = box_path(p.cam_pos, view_camera_dir(&p, px[k] + 0.5f, py[k] + 0.5f), N);
      float bg[3] = {p.background.x, p.background.y, p.background.z};
      for (int c = 0; c < 3; c++) {
        float T = expf(-sigt[c] * D);
        float want = src[c] * (1.0f - T) / sigt[c] + T * bg[c];
        EXPECT(fabsf(rgba[c] - want) <= 1e-4f * fabsf(want) + 1e-6f,
               "variant %zu pixel (%d,%d) ch %d: %g want %g (D %g voxels, %u steps)", vi, px[k],
               py[k], c, rgba[c], want, D, steps);
      }
      if (k == 0) EXPECT(fabsf(D - N) < 1e-4f, "centre ray crosses %g voxels", D);
      if (k == 0 && var[vi].mlev == 2 && (var[vi].nlev == 2 || !fl.refraction))
        EXPECT(steps <= 4, "variant %zu: constant bricks should be crossed in one step each, took %u",
               vi, steps);
      if (k == 2) EXPECT(D == 0.0f && rgba[3] == 0.0f, "corner ray should miss");
    }
    /* from inside, on the brick face y = 8, leaving it at a grazing angle:
     * block-crossing steps must not stall on the face */
    view_params_t q = p;
    q.cam_pos = v3(5.0f, 8.0f, 0.5f);
    q.cam_forward = v3(0.0f, -1e-3f, 1.0f);
    float rgba[4];
    bk_uint steps;
    view_march_pixel(&q, f, fl, 16, 16, rgba, &steps);
    float D = box_path(q.cam_pos, view_camera_dir(&q, 16.5f, 16.5f), N);
    for (int c = 0; c < 3; c++) {
      float T = expf(-sigt[c] * D);
      float want = src[c] * (1.0f - T) / sigt[c] + T * p.background.x * (c == 0) +
                   T * p.background.y * (c == 1);
      EXPECT(fabsf(rgba[c] - want) <= 1e-4f * want + 1e-6f && steps < 60,
             "variant %zu grazing ray ch %d: %g want %g (D %g, %u steps)", vi, c, rgba[c], want, D,
             steps);
    }
  }
  free(ng);
}

int main(int argc, char **argv) {
  const char *what = argc > 1 ? argv[1] : "all";
  int all = !strcmp(what, "all");
  if (all || !strcmp(what, "frames")) test_frames();
  if (all || !strcmp(what, "srgb")) test_srgb();
  if (all || !strcmp(what, "camera")) test_camera();
  if (all || !strcmp(what, "march")) test_march();
  if (tu_failures) fprintf(stderr, "%d check(s) failed\n", tu_failures);
  return tu_failures ? 1 : 0;
}
