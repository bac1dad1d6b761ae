/* test_view_math.c: the viewing pass's host-side truths, no OpenCL needed.
 *
 *   frames  frame ranges and patterns (####, $F4, $F), errors for bad ranges
 *   srgb    the sRGB OETF at its break point and known values
 *   camera  pinhole directions: centre pixel = forward, corners at the
 *           vertical/horizontal half-angles
 *   march   kernels/view_march.h run on the host through a homogeneous cube equals
 *           σs L̄ (1 − e^(−σt D))/σt for the analytic path length D (straight
 *           and curved code paths, grey and RGB, Euler and RK4)
 *   rays    in n² = n0² + 2 a y rays are parabolas x(t) = x0 + v0 t + ½ a ŷ t²
 *           (dt = ds/n): RK4 and Euler against it, RK4 much closer */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/common.h"
#include "base/frames.h"
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
  float t0, t1;
  EXPECT(view_box_hit(v3(-1, 0.5f, 0.5f), v3(1, 0, 0), v3(2, 1, 1), &t0, &t1) &&
            fabsf(t0 - 1) < 1e-6f && fabsf(t1 - 3) < 1e-6f, "box hit %g %g", t0, t1);
  EXPECT(!view_box_hit(v3(-1, 1.5f, 0.5f), v3(1, 0, 0), v3(2, 1, 1), &t0, &t1), "box miss");
  EXPECT(view_box_hit(v3(0.5f, 0.5f, 0.5f), v3(0, 0, -1), v3(2, 1, 1), &t0, &t1) && t0 == 0.0f &&
            fabsf(t1 - 0.5f) < 1e-6f, "inside start");
  EXPECT(fabsf(view_seg_weight(0.0f) - 1.0f) < 1e-7f &&
            fabsf(view_seg_weight(0.029f) - (1.0f - expf(-0.029f)) / 0.029f) < 1e-6f &&
            fabsf(view_seg_weight(1e-5f) - (1.0f - 0.5e-5f)) < 1e-7f &&
            fabsf(view_seg_weight(2.0f) - (1.0f - expf(-2.0f)) / 2.0f) < 1e-6f,
        "segment weight");
}

/* Homogeneous cube of N³ voxels: the host runs the kernel's march, through
 * every code path (straight/curved, Euler/RK4, grey/RGB, lookups/constants,
 * brick-crossing steps, flat chords, mixed bricks), against the closed form. */
static void test_march(void) {
  enum { N = 16 };
  static float medium[N * N * N * 4], st4[N * N * N * 4], ng[N * N * N * 4];
  enum { CHECKER = 0x80 }; /* a pattern flag of the variants below, not a brick flag */
  static unsigned char bricks[8], flat[N * N * N], scratch[N * N * N];
  enum { NP = (N + 2) * (N + 2) * (N + 2) }; /* the padded layout the march reads */
  static float medium_p[NP * 4], st4_p[NP * 4], ng_p[NP * 4];
  const float Lb[3] = {1.0f, 0.5f, 0.25f}, sigs[3] = {0.1f, 0.05f, 0.02f};
  const float rgb_t[3] = {0.12f, 0.05f, 0.3f}, grey_t = 0.12f;
  view_params_t p = cam_params(60.0f, 33, 33);
  p.cam_pos = v3(8.0f, 8.0f, -20.0f);
  p.nx = p.ny = p.nz = N;
  p.bx = p.by = p.bz = 2;
  p.step = 0.5f;
  p.straight_step = 1.0f;
  p.max_steps = 10000;
  p.background = v3(0.2f, 0.1f, 0.0f);
  p.sigma_t = v3(rgb_t[0], rgb_t[1], rgb_t[2]);
  /* refraction, grey, integrator, homogeneous; brick flags; flat distances
   * from view_flat_field (straight chords inside refracting bricks), else 0
   * (curved steps everywhere) */
  const struct { view_flags fl; unsigned char bricks; int flat; } var[] = {
      {{0, 0, VIEW_EULER, 0}, 0, 0},
      {{0, 0, VIEW_EULER, 1}, VIEW_BRICK_MEDIUM_CONST, 0},
      {{0, 1, VIEW_EULER, 0}, 0, 0},
      {{1, 0, VIEW_EULER, 0}, VIEW_BRICK_N_CONST, 0},
      {{1, 1, VIEW_RK4, 0}, 0, 0},
      {{1, 0, VIEW_EULER, 1}, VIEW_BRICK_N_CONST | VIEW_BRICK_MEDIUM_CONST, 0},
      {{1, 1, VIEW_EULER, 0}, 0, 1},
      {{1, 0, VIEW_RK4, 1}, VIEW_BRICK_MEDIUM_CONST, 1},
      /* CHECKER: the flags alternate brick by brick (the medium is constant
       * either way), so chords of varying bricks, single-step bricks, flat
       * chords and curved steps follow one another along a ray */
      {{0, 1, VIEW_EULER, 0}, CHECKER | VIEW_BRICK_MEDIUM_CONST, 0},
      {{1, 1, VIEW_EULER, 0}, CHECKER | VIEW_BRICK_MEDIUM_CONST | VIEW_BRICK_N_CONST, 1},
      {{1, 0, VIEW_RK4, 0}, CHECKER | VIEW_BRICK_N_CONST, 1},
      {{1, 1, VIEW_EULER, 0}, CHECKER | VIEW_BRICK_N_CONST, 0},
  };
  for (size_t vi = 0; vi < sizeof var / sizeof var[0]; vi++) {
    const view_flags fl = var[vi].fl;
    float sigt[3];
    for (int c = 0; c < 3; c++) sigt[c] = fl.grey ? grey_t : rgb_t[c];
    for (int i = 0; i < N * N * N; i++) {
      for (int c = 0; c < 3; c++) medium[4 * i + c] = sigs[c] * Lb[c], st4[4 * i + c] = rgb_t[c];
      medium[4 * i + 3] = fl.grey ? grey_t : 0.0f;
      ng[4 * i] = ng[4 * i + 1] = ng[4 * i + 2] = 0.0f;
      ng[4 * i + 3] = 1.0f;
    }
    for (int b = 0; b < 8; b++) /* bricks (b&1, b>>1&1, b>>2): checker by parity */
      bricks[b] = !(var[vi].bricks & CHECKER) ? var[vi].bricks
                  : ((b & 1) + (b >> 1 & 1) + (b >> 2)) % 2 ? (var[vi].bricks & ~CHECKER) : 0;
    if (var[vi].flat) {
      view_flat_field(N, N, N, ng, flat, scratch);
      EXPECT(flat[0] == VIEW_FLAT_MAX && flat[N * N * N / 2] == VIEW_FLAT_MAX,
            "constant n: flat distances %d %d, want %d", flat[0], flat[N * N * N / 2],
            VIEW_FLAT_MAX);
    } else {
      memset(flat, 0, sizeof flat);
    }
    view_pad4(N, N, N, medium, medium_p);
    view_pad4(N, N, N, st4, st4_p);
    view_pad4(N, N, N, ng, ng_p);
    view_fields f = {medium_p, st4_p, ng_p, bricks, flat};
    const int px[3] = {16, 25, 0}, py[3] = {16, 9, 32};
    for (int k = 0; k < 3; k++) {
      float rgba[4];
      bk_uint steps;
      view_march_pixel(&p, f, fl, px[k], py[k], rgba, &steps);
      bk_v3 d = view_camera_dir(&p, px[k] + 0.5f, py[k] + 0.5f);
      float t0, t1;
      float D = view_box_hit(p.cam_pos, d, v3(N, N, N), &t0, &t1) ? t1 - t0 : 0.0f;
      float bg[3] = {p.background.x, p.background.y, p.background.z};
      for (int c = 0; c < 3; c++) {
        float T = expf(-sigt[c] * D);
        float want = sigs[c] * Lb[c] * (1.0f - T) / sigt[c] + T * bg[c];
        EXPECT(fabsf(rgba[c] - want) <= 1e-4f * fabsf(want) + 1e-6f,
              "variant %zu pixel (%d,%d) ch %d: %g want %g (D %g voxels, %u steps)", vi, px[k],
              py[k], c, rgba[c], want, D, steps);
      }
      if (k == 0) EXPECT(fabsf(D - N) < 1e-4f, "centre ray crosses %g voxels", D);
      if (k == 0 && (var[vi].bricks & VIEW_BRICK_MEDIUM_CONST) && !(var[vi].bricks & CHECKER))
        EXPECT(steps <= 4,
              "variant %zu: constant bricks should be crossed in one step each, took %u", vi,
              steps);
      if (k == 2) EXPECT(D == 0.0f && rgba[3] == 0.0f, "corner ray should miss");
    }
    /* from inside, on the brick face y = 8, leaving it at a grazing angle:
     * brick-crossing steps must not stall on the face */
    view_params_t q = p;
    q.cam_pos = v3(5.0f, 8.0f, 0.5f);
    q.cam_forward = v3(0.0f, -1e-3f, 1.0f);
    float rgba[4], t0, t1;
    bk_uint steps;
    view_march_pixel(&q, f, fl, 16, 16, rgba, &steps);
    bk_v3 d = view_camera_dir(&q, 16.5f, 16.5f);
    float D = view_box_hit(q.cam_pos, d, v3(N, N, N), &t0, &t1) ? t1 - t0 : 0.0f;
    for (int c = 0; c < 3; c++) {
      float T = expf(-sigt[c] * D);
      float want = sigs[c] * Lb[c] * (1.0f - T) / sigt[c] + T * p.background.x * (c == 0) +
                   T * p.background.y * (c == 1);
      EXPECT(fabsf(rgba[c] - want) <= 1e-4f * want + 1e-6f && steps < 40,
            "variant %zu grazing ray ch %d: %g want %g (D %g, %u steps)", vi, c, rgba[c], want, D,
            steps);
    }
  }
}

/* Flat distances: one voxel of n = 1.2 in n = 1 makes ∇n nonzero on its six
 * face neighbours; every voxel's distance must be the brute-force Chebyshev
 * distance to those, capped at VIEW_FLAT_MAX. */
static void test_flat(void) {
  enum { NX = 20, NY = 17, NZ = 23 };
  static float ior[NX * NY * NZ], ng[4 * NX * NY * NZ];
  static unsigned char flat[NX * NY * NZ], scratch[NX * NY * NZ];
  for (int i = 0; i < NX * NY * NZ; i++) ior[i] = 1.0f;
  ior[5 + NX * (6 + NY * 7)] = 1.2f;
  ior[19 + NX * (0 + NY * 22)] = 1.1f; /* a corner: one-sided differences */
  view_ng_field(NX, NY, NZ, ior, ng);
  view_flat_field(NX, NY, NZ, ng, flat, scratch);
  int bad = 0, nonzero = 0;
  for (int k = 0; k < NZ; k++)
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++) {
        int want = VIEW_FLAT_MAX;
        for (int c = 0; c < NX * NY * NZ; c++) {
          if (ng[4 * c] == 0.0f && ng[4 * c + 1] == 0.0f && ng[4 * c + 2] == 0.0f) continue;
          int ci = c % NX, cj = (c / NX) % NY, ck = c / (NX * NY);
          int dd = abs(ci - i);
          if (abs(cj - j) > dd) dd = abs(cj - j);
          if (abs(ck - k) > dd) dd = abs(ck - k);
          if (dd < want) want = dd;
        }
        int got = flat[i + NX * (j + NY * k)];
        nonzero += want == 0;
        if (got != want && bad++ < 5)
          EXPECT(0, "flat (%d,%d,%d) = %d, want %d", i, j, k, got, want);
      }
  /* six around the interior voxel; the corner itself (one-sided) and three more */
  EXPECT(nonzero == 6 + 4, "%d voxels with nonzero grad n, want 10", nonzero);
  EXPECT(bad == 0, "%d flat distances wrong", bad);
}

/* n(u) = sqrt(n0² + 2 a u_y) on a 64³ grid; march from u0 until x passes 56. */
static float ray_error(int integrator, float h) {
  enum { N = 64 };
  static float ior[N * N * N], ng[4 * N * N * N], ng_p[4 * (N + 2) * (N + 2) * (N + 2)];
  const float n0 = 1.2f, a = 0.01f;
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) ior[i + N * (j + N * k)] = sqrtf(n0 * n0 + 2.0f * a * (j + 0.5f));
  view_ng_field(N, N, N, ior, ng);
  view_pad4(N, N, N, ng, ng_p);
  view_params_t p;
  memset(&p, 0, sizeof p);
  p.nx = p.ny = p.nz = N;
  bk_v3 u0 = v3(4.0f, 10.0f, 32.0f), d0 = v3_normalize(v3(1.0f, 0.3f, 0.0f));
  float nu0 = sqrtf(n0 * n0 + 2.0f * a * u0.y);
  bk_v3 x = u0, v = v3_scale(d0, nu0);
  const bk_v3 v0 = v;
  for (int s = 0; s < 100000 && x.x < 56.0f; s++) {
    if (integrator == VIEW_RK4)
      view_step_rk4(&p, ng_p, h, &x, &v);
    else
      view_step_euler(&p, ng_p, h, &x, &v);
  }
  float t = (x.x - u0.x) / v0.x;
  float y = u0.y + v0.y * t + 0.5f * a * t * t;
  EXPECT(fabsf(x.z - 32.0f) < 1e-4f, "ray left its plane: z = %g", x.z);
  return fabsf(x.y - y);
}

static void test_rays(void) {
  float e_rk4 = ray_error(VIEW_RK4, 0.5f), e_euler = ray_error(VIEW_EULER, 0.5f);
  float e_euler_fine = ray_error(VIEW_EULER, 0.125f);
  printf(
      "parabola: |y error| after ~52 voxels: rk4 %.5f, euler %.5f (h 0.5), euler %.5f (h 0.125)\n",
      e_rk4, e_euler, e_euler_fine);
  EXPECT(e_rk4 < 0.002f, "rk4 error %g voxels", e_rk4);
  EXPECT(e_euler < 0.15f, "euler error %g voxels", e_euler);
  EXPECT(e_euler_fine < 0.5f * e_euler, "euler should converge: %g -> %g", e_euler, e_euler_fine);
}

int main(int argc, char **argv) {
  const char *what = argc > 1 ? argv[1] : "all";
  int all = !strcmp(what, "all");
  if (all || !strcmp(what, "frames")) test_frames();
  if (all || !strcmp(what, "srgb")) test_srgb();
  if (all || !strcmp(what, "camera")) test_camera();
  if (all || !strcmp(what, "march")) test_march();
  if (all || !strcmp(what, "rays")) test_rays();
  if (all || !strcmp(what, "flat")) test_flat();
  if (tu_failures) fprintf(stderr, "%d check(s) failed\n", tu_failures);
  return tu_failures ? 1 : 0;
}
