/* test_ray_core.c: the ray core (kernels/ray_core.h) that the photon march
 * and the view share, with the field builder (baker/field.c) and the
 * constant-block pyramid (baker/octree.c), on the host against analytic
 * truths. The same functions run on the device; the march and view tests
 * compare host and OpenCL results.
 *
 *   field     {∇n, n} of a smooth n = 1 + A e^(-|x-c|²): central differences
 *             within h²/6 max|f'''| inside, one-sided within h/2 max|f''| on
 *             the faces, second order when h halves; trilinear between
 *             centres within the interpolation bound; an axis one voxel thick
 *             has no gradient along it
 *   sampler   the padded sampler equals trilinear sampling clamped to the
 *             edge voxels, bit for bit, inside and far outside the grid
 *   step      n² linear in y bends rays into parabolas: RK4 within 0.002
 *             voxel after ~52 voxels, Euler within 0.15 and converging
 *   atten     (1 - e^-τ)/τ and e^-τ across the series/exp switch
 *   slab      ray-box entry and exit, misses, starts inside
 *   pyramid   oct_build_fields over several channels and halos equals a
 *             brute-force search for constant blocks, level by level
 *   cells     oct_add_cells flags exactly the asked cells whose 8 corners
 *             hold one {∇n, n}, and the field is that value inside them */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/grid.h"
#include "field.h"
#include "kernels/ray_core.h"
#include "octree.h"
#include "test_util.h"

/* --- field ------------------------------------------------------------------ */

#define AMP 0.3
static const double centre[3] = {-0.1, 0.2, 0.15};

static double n_exact(const double x[3]) {
  double r2 = 0;
  for (int a = 0; a < 3; a++) r2 += (x[a] - centre[a]) * (x[a] - centre[a]);
  return 1.0 + AMP * exp(-r2);
}
static void grad_exact(const double x[3], double g[3]) {
  double e = n_exact(x) - 1.0;
  for (int a = 0; a < 3; a++) g[a] = -2.0 * (x[a] - centre[a]) * e;
}

static float *make_n(const grid_dims_t *d) {
  float *n = malloc(grid_count(d) * sizeof(float));
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        float c[3];
        grid_voxel_center(d, i, j, k, c);
        double x[3] = {c[0], c[1], c[2]};
        n[grid_index(d, i, j, k)] = (float)n_exact(x);
      }
  return n;
}

/* Bounds on the truncation error, from the 1D factor f(t) = A exp(-t^2)
 * (the other factors are <= 1): central differences err <= h^2/6 max|f'''|,
 * one-sided err <= h/2 max|f''|. max|f'''| = 3.9036 A (at t = 0.5247),
 * max|f''| = 2A (at t = 0), and max|f'| = 0.8578 A (at t = 0.7071). */
#define F3MAX (AMP * 3.9036)
#define F2MAX (AMP * 2.0)

typedef struct grad_err {
  double interior, face, max_grad;
} grad_err_t;

/* The field's ∇n at voxel centres (1/voxel, so divided by h) against the
 * analytic gradient in 1/m. */
static grad_err_t compare_analytic(const grid_dims_t *d, const float *ng) {
  grad_err_t e = {0, 0, 0};
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        float c[3];
        grid_voxel_center(d, i, j, k, c);
        double x[3] = {c[0], c[1], c[2]}, g[3];
        grad_exact(x, g);
        int idx[3] = {i, j, k}, cnt[3] = {d->nx, d->ny, d->nz};
        float q[4];
        fld_voxel(ng, i, j, k, q);
        for (int a = 0; a < 3; a++) {
          double diff = fabs(q[a] / d->voxel_size - g[a]);
          int face = idx[a] == 0 || idx[a] == cnt[a] - 1;
          if (face && diff > e.face) e.face = diff;
          if (!face && diff > e.interior) e.interior = diff;
          if (fabs(g[a]) > e.max_grad) e.max_grad = fabs(g[a]);
        }
      }
  return e;
}

/* Between voxel centres the sampled field is within the difference error
 * plus the trilinear error h^2/8 sum|d2 g/dx_a^2|; at a centre it is the
 * centre's value. */
static void check_interpolation(const grid_dims_t *d, const float *ng, const float *n,
                                double cd_bound) {
  const double h = d->voxel_size;
  const rc_dims dims = {d->nx, d->ny, d->nz};
  double bound = cd_bound + h * h / 8.0 * (F3MAX + 2 * AMP * 0.8578 * 2.0), worst = 0;
  unsigned seed = 12345;
  for (int s = 0; s < 2000; s++) {
    float u[3];
    int cnt[3] = {d->nx, d->ny, d->nz};
    for (int a = 0; a < 3; a++) {
      seed = seed * 1103515245u + 12345u;
      u[a] = 1.5f + (float)((seed >> 8) & 0xffff) / 65536.0f * (float)(cnt[a] - 3);
    }
    bk_v3 g;
    rc_field(dims, ng, v3(u[0], u[1], u[2]), &g);
    double x[3] = {d->origin[0] + u[0] * h, d->origin[1] + u[1] * h, d->origin[2] + u[2] * h};
    double ge[3];
    grad_exact(x, ge);
    for (int a = 0; a < 3; a++) worst = fmax(worst, fabs((&g.x)[a] / h - ge[a]));
  }
  EXPECT(worst <= bound, "interpolated error %.3g > %.3g", worst, bound);
  bk_v3 g;
  float nc = rc_field(dims, ng, v3(7.5f, 5.5f, 3.5f), &g);
  float q[4];
  fld_voxel(ng, 7, 5, 3, q);
  EXPECT(nc == n[grid_index(d, 7, 5, 3)] && g.x == q[0] && g.y == q[1] && g.z == q[2],
         "a centre's sample is its value");
}

static void test_field(void) {
  bk_error_t err = {0};
  /* an off-centre origin, and a lopsided grid to catch axis mix-ups */
  grid_dims_t dims[2] = {{32, 32, 32, 0.14f, {-2.3f, -1.7f, -2.1f}},
                         {20, 28, 12, 0.19f, {-1.9f, -2.6f, -1.05f}}};
  double interior_err = 0;
  for (int t = 0; t < 2; t++) {
    const grid_dims_t *d = &dims[t];
    float *n = make_n(d), *ng = fld_build(d->nx, d->ny, d->nz, d->voxel_size, n, &err);
    REQUIRE(ng, "%s", err.msg);
    double h = d->voxel_size;
    double cd_bound = h * h / 6.0 * F3MAX + 1e-5, face_bound = h / 2.0 * F2MAX + 1e-5;
    grad_err_t e = compare_analytic(d, ng);
    EXPECT(e.interior <= cd_bound, "grid %d: interior error %.3g > bound %.3g", t, e.interior,
           cd_bound);
    EXPECT(e.face <= face_bound, "grid %d: face error %.3g > bound %.3g", t, e.face, face_bound);
    printf("field %dx%dx%d h=%.3f: max |grad n| %.4f /m, interior error %.3g (bound %.3g), "
           "face error %.3g (bound %.3g)\n",
           d->nx, d->ny, d->nz, h, e.max_grad, e.interior, cd_bound, e.face, face_bound);
    if (t == 0) interior_err = e.interior;
    check_interpolation(d, ng, n, cd_bound);
    free(n);
    free(ng);
  }
  /* second order: halving h divides the interior error by ~4 */
  grid_dims_t fine = {64, 64, 64, 0.07f, {-2.3f, -1.7f, -2.1f}};
  float *n = make_n(&fine), *ng = fld_build(64, 64, 64, fine.voxel_size, n, &err);
  REQUIRE(ng, "%s", err.msg);
  double e = compare_analytic(&fine, ng).interior;
  printf("interior error h=0.14: %.3g, h=0.07: %.3g, ratio %.2f\n", interior_err, e,
         interior_err / e);
  EXPECT(interior_err / e > 3.5, "convergence ratio %.2f, expected ~4", interior_err / e);
  free(n);
  free(ng);
  /* a one-voxel-thick axis has no gradient along it */
  float flat[12];
  for (int q = 0; q < 12; q++) flat[q] = 1.0f + 0.1f * (float)q;
  float *gf = fld_build(4, 1, 3, 0.5, flat, &err);
  REQUIRE(gf, "%s", err.msg);
  float q[4];
  fld_voxel(gf, 0, 0, 0, q);
  /* 1/voxel: (n1 - n0) = 0.1 along x, one-sided; (n4 - n0)/... along z */
  EXPECT(q[1] == 0.0f && fabsf(q[0] - 0.1f) < 1e-6f && fabsf(q[2] - 0.4f) < 1e-6f,
         "flat grid %g %g %g", q[0], q[1], q[2]);
  free(gf);
}

/* --- sampler ------------------------------------------------------------------ */

/* Trilinear with every corner clamped to the edge voxels, on unpadded data:
 * what the march did before the ray core padded its fields. */
static float clamped_sample(const float *f, int nx, int ny, int nz, bk_v3 u, int c) {
  float fx = u.x - 0.5f, fy = u.y - 0.5f, fz = u.z - 0.5f;
  float flx = floorf(fx), fly = floorf(fy), flz = floorf(fz);
  int i0 = (int)flx, j0 = (int)fly, k0 = (int)flz;
  float tx = fx - flx, ty = fy - fly, tz = fz - flz;
  int i[2] = {bk_clampi(i0, 0, nx - 1), bk_clampi(i0 + 1, 0, nx - 1)};
  int j[2] = {bk_clampi(j0, 0, ny - 1), bk_clampi(j0 + 1, 0, ny - 1)};
  int k[2] = {bk_clampi(k0, 0, nz - 1), bk_clampi(k0 + 1, 0, nz - 1)};
#define AT(a, b, d) f[4 * ((size_t)i[a] + (size_t)nx * ((size_t)j[b] + (size_t)ny * k[d])) + c]
  float c00 = AT(0, 0, 0) + tx * (AT(1, 0, 0) - AT(0, 0, 0));
  float c10 = AT(0, 1, 0) + tx * (AT(1, 1, 0) - AT(0, 1, 0));
  float c01 = AT(0, 0, 1) + tx * (AT(1, 0, 1) - AT(0, 0, 1));
  float c11 = AT(0, 1, 1) + tx * (AT(1, 1, 1) - AT(0, 1, 1));
#undef AT
  float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
  return c0 + tz * (c1 - c0);
}

static void test_sampler(void) {
  enum { NX = 7, NY = 5, NZ = 6 };
  static float f[4 * NX * NY * NZ], p[4 * (NX + 2) * (NY + 2) * (NZ + 2)];
  unsigned seed = 99;
  for (int q = 0; q < 4 * NX * NY * NZ; q++) {
    seed = seed * 1103515245u + 12345u;
    f[q] = (float)((seed >> 8) & 0xffff) / 4096.0f;
  }
  fld_pad4(NX, NY, NZ, f, p);
  const rc_dims d = {NX, NY, NZ};
  int bad = 0;
  for (int s = 0; s < 20000; s++) {
    float u[3];
    for (int a = 0; a < 3; a++) {
      seed = seed * 1103515245u + 12345u;
      u[a] = -4.0f + (float)((seed >> 8) & 0xffff) / 65536.0f * 16.0f; /* far outside too */
    }
    rc_tri t = rc_tri_at(d, v3(u[0], u[1], u[2]));
    rc_f4 r = rc_gather4(d, p, &t);
    for (int c = 0; c < 4; c++)
      if ((&r.x)[c] != clamped_sample(f, NX, NY, NZ, v3(u[0], u[1], u[2]), c) && bad++ < 3)
        EXPECT(0, "padded sample at (%g %g %g) ch %d differs", u[0], u[1], u[2], c);
  }
  EXPECT(bad == 0, "%d padded samples differ from clamped trilinear", bad);
}

/* n over an nx x ny x nz grid: 1.5 in a ball of radius 6 voxels about
 * (20, 13, 11), 1 beyond 8, linear between; plus `bump` on the voxels of
 * the face x = 0 with y < 4 (a face voxel unlike its inner neighbour). */
static void ball_band(float *n, int nx, int ny, int nz, float bump) {
  for (int k = 0; k < nz; k++)
    for (int j = 0; j < ny; j++)
      for (int i = 0; i < nx; i++) {
        float r = sqrtf((i - 20.0f) * (i - 20.0f) + (j - 13.0f) * (j - 13.0f) +
                        (k - 11.0f) * (k - 11.0f));
        float w = r < 6.0f ? 1.0f : r > 8.0f ? 0.0f : (8.0f - r) / 2.0f;
        n[i + nx * (j + ny * k)] = 1.0f + 0.5f * w + (i == 0 && j < 4 ? bump : 0.0f);
      }
}

/* The sparse {∇n, n} field samples exactly as the dense padded layout of
 * the same values would: a ball of glass (n constant inside and out, a
 * smooth band between, so bricks stored and left out side by side) on a
 * grid that is not a whole number of bricks, sampled everywhere, outside
 * the grid too. */
static void test_sparse_field(void) {
  enum { NX = 37, NY = 29, NZ = 23 };
  static float n[NX * NY * NZ], dense[4 * NX * NY * NZ], p[4 * (NX + 2) * (NY + 2) * (NZ + 2)];
  ball_band(n, NX, NY, NZ, 0.0f);
  bk_error_t err = {0};
  float *ng = fld_build(NX, NY, NZ, 0.1, n, &err);
  REQUIRE(ng, "%s", err.msg);
  int head[4];
  memcpy(head, ng, sizeof head);
  const int bricks = head[0] * head[1] * head[2];
  EXPECT(head[3] > 0 && head[3] < bricks, "%d of %d bricks stored: expected some, not all",
         head[3], bricks);
  for (int k = 0; k < NZ; k++)
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++)
        fld_voxel(ng, i, j, k, dense + 4 * (i + NX * (j + NY * k)));
  fld_pad4(NX, NY, NZ, dense, p);
  const rc_dims d = {NX, NY, NZ};
  unsigned seed = 7;
  int bad = 0;
  for (int s = 0; s < 200000; s++) {
    float u[3];
    for (int a = 0; a < 3; a++) {
      seed = seed * 1103515245u + 12345u;
      u[a] = -3.0f + (float)((seed >> 8) & 0xffff) / 65536.0f * 46.0f;
    }
    rc_tri t = rc_tri_at(d, v3(u[0], u[1], u[2]));
    rc_f4 a = rc_field_gather(ng, &t), b = rc_gather4(d, p, &t);
    if ((a.x != b.x || a.y != b.y || a.z != b.z || a.w != b.w) && bad++ < 3)
      EXPECT(0, "sparse sample at (%g %g %g): %g %g %g %g, dense %g %g %g %g", u[0], u[1], u[2],
             a.x, a.y, a.z, a.w, b.x, b.y, b.z, b.w);
  }
  EXPECT(bad == 0, "%d sparse samples differ from the dense layout's", bad);
  /* and the values are the field's: the gradient of the band, n inside */
  float q[4];
  fld_voxel(ng, 20, 13, 11, q);
  EXPECT(q[3] == 1.5f && q[0] == 0.0f, "centre of the ball: n %g, dn/dx %g", q[3], q[0]);
  fld_voxel(ng, 27, 13, 11, q);
  EXPECT(q[0] < 0.0f, "band: dn/dx %g, expected < 0", q[0]);
  free(ng);
}

/* --- cells: the march's constant cells (oct_add_cells) ------------------------------ */

/* Every flagged cell's 8 corners hold one {∇n, n} bit for bit with ∇n = 0,
 * so a sample anywhere in it is that value and a ray there is straight; and
 * every such cell with a corner in a varying block (the cells the march
 * asks about) is flagged. A face voxel that differs from its inner
 * neighbour alone makes a cell of one {∇n, n} whose ∇n is not 0. */
static void test_cells(void) {
  enum { NX = 37, NY = 29, NZ = 23 };
  static float n[NX * NY * NZ];
  ball_band(n, NX, NY, NZ, 0.25f);
  bk_error_t err = {0};
  oct_pyramid_t pyr;
  const oct_source_t src = {n, 1, 1, 0};
  REQUIRE(oct_build_fields(NX, NY, NZ, &src, 1, OCT_HALO, &pyr, &err) == BK_OK, "%s", err.msg);
  REQUIRE(oct_add_cells(NX, NY, NZ, &src, 1, &pyr, &err) == BK_OK, "%s", err.msg);
  float *ng = fld_build(NX, NY, NZ, 0.1, n, &err);
  REQUIRE(ng, "%s", err.msg);
  const rc_dims d = {NX, NY, NZ};
  int flagged = 0, unsound = 0, missed = 0;
  for (int pz = 0; pz <= NZ; pz++)
    for (int py = 0; py <= NY; py++)
      for (int px = 0; px <= NX; px++) {
        const int p[3] = {px, py, pz}, nn[3] = {NX, NY, NZ};
        float c0[4], q[4];
        int same = 1, asked = 0;
        for (int v = 0; v < 8; v++) {
          int c[3];
          for (int a = 0; a < 3; a++) {
            c[a] = p[a] - 1 + (v >> a & 1);
            c[a] = c[a] < 0 ? 0 : c[a] >= nn[a] ? nn[a] - 1 : c[a];
          }
          fld_voxel(ng, c[0], c[1], c[2], v ? q : c0);
          if (v && memcmp(q, c0, sizeof q)) same = 0;
          asked |= rc_block_level(pyr.level, d, c) == 0;
        }
        same = same && c0[0] == 0.0f && c0[1] == 0.0f && c0[2] == 0.0f; /* and straight */
        const int flag = rc_cell_flag(pyr.level, d, px, py, pz);
        flagged += flag;
        if (flag && !same && unsound++ < 3) EXPECT(0, "cell %d %d %d flagged, not constant", px, py, pz);
        if (asked && same && !flag && missed++ < 3) EXPECT(0, "cell %d %d %d constant, not flagged", px, py, pz);
        if (flag) { /* a point inside: rc_cell_constant finds the flag, the field is c0 */
          const bk_v3 u = v3(px - 0.5f + 0.37f, py - 0.5f + 0.61f, pz - 0.5f + 0.13f);
          bk_v3 g;
          const float nu = rc_field(d, ng, u, &g);
          if (u.x >= 0 && u.y >= 0 && u.z >= 0 && u.x < NX && u.y < NY && u.z < NZ)
            EXPECT(rc_cell_constant(pyr.level, d, u) && nu == c0[3] && g.x == 0.0f && g.y == 0.0f &&
                       g.z == 0.0f,
                   "cell %d %d %d: n %g grad %g %g %g", px, py, pz, nu, g.x, g.y, g.z);
        }
      }
  printf("cells: %d of %d flagged constant\n", flagged, (NX + 1) * (NY + 1) * (NZ + 1));
  EXPECT(flagged > 0 && unsound == 0 && missed == 0, "%d flagged, %d unsound, %d missed", flagged,
         unsound, missed);
  free(ng);
  oct_free(&pyr);
}

/* --- step ------------------------------------------------------------------------ */

/* n(u) = sqrt(n0² + 2 a u_y) on a 64³ grid; march from u0 until x passes 56:
 * the exact path is the parabola y = y0 + vy t + a t²/2 in the parameter t
 * with dx/dt = v/... (x linear in t). Returns |y error| in voxels. */
static float ray_error(int integrator, float h) {
  enum { N = 64 };
  static float ior[N * N * N];
  const float n0 = 1.2f, a = 0.01f;
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) ior[i + N * (j + N * k)] = sqrtf(n0 * n0 + 2.0f * a * (j + 0.5f));
  bk_error_t err = {0};
  float *ng = fld_build(N, N, N, 1.0, ior, &err);
  REQUIRE(ng, "%s", err.msg);
  const rc_dims d = {N, N, N};
  bk_v3 u0 = v3(4.0f, 10.0f, 32.0f), d0 = v3_normalize(v3(1.0f, 0.3f, 0.0f));
  float nu0 = sqrtf(n0 * n0 + 2.0f * a * u0.y);
  bk_v3 x = u0, v = v3_scale(d0, nu0);
  const bk_v3 v0 = v;
  for (int s = 0; s < 100000 && x.x < 56.0f; s++) rc_step(d, ng, integrator, h, x, v, &x, &v);
  free(ng);
  float t = (x.x - u0.x) / v0.x;
  float y = u0.y + v0.y * t + 0.5f * a * t * t;
  EXPECT(fabsf(x.z - 32.0f) < 1e-4f, "ray left its plane: z = %g", x.z);
  return fabsf(x.y - y);
}

static void test_step(void) {
  float e_rk4 = ray_error(RC_RK4, 0.5f), e_euler = ray_error(RC_EULER, 0.5f);
  float e_euler_fine = ray_error(RC_EULER, 0.125f);
  printf("parabola: |y error| after ~52 voxels: rk4 %.5f, euler %.5f (h 0.5), euler %.5f "
         "(h 0.125)\n", e_rk4, e_euler, e_euler_fine);
  EXPECT(e_rk4 < 0.002f, "rk4 error %g voxels", e_rk4);
  EXPECT(e_euler < 0.15f, "euler error %g voxels", e_euler);
  EXPECT(e_euler_fine < 0.5f * e_euler, "euler should converge: %g -> %g", e_euler, e_euler_fine);
}

/* --- attenuation and slab ---------------------------------------------------------- */

static void test_atten_slab(void) {
  const float taus[] = {0.0f, 1e-5f, 0.01f, 0.029f, 0.0301f, 0.5f, 2.0f, 40.0f};
  for (size_t q = 0; q < sizeof taus / sizeof taus[0]; q++) {
    double t = taus[q], want_r = t > 0 ? -expm1(-t) / t : 1.0, want_T = exp(-t);
    float T, r = rc_atten((float)t, &T);
    EXPECT(fabs(r - want_r) <= 2e-6 * want_r && fabs(T - want_T) <= 2e-6,
           "tau %g: r %.8g want %.8g, T %.8g want %.8g", t, r, want_r, T, want_T);
  }
  float t0, t1;
  const bk_v3 lo = v3(0, 0, 0), hi = v3(2, 1, 1);
  EXPECT(rc_slab(v3(-1, 0.5f, 0.5f), v3(1, 0, 0), lo, hi, &t0, &t1) && fabsf(t0 - 1) < 1e-6f &&
             fabsf(t1 - 3) < 1e-6f, "box hit %g %g", t0, t1);
  EXPECT(!rc_slab(v3(-1, 1.5f, 0.5f), v3(1, 0, 0), lo, hi, &t0, &t1), "box miss");
  EXPECT(!rc_slab(v3(-1, 0.5f, 0.5f), v3(-1, 0, 0), lo, hi, &t0, &t1), "box behind");
  EXPECT(rc_slab(v3(0.5f, 0.5f, 0.5f), v3(0, 0, -1), lo, hi, &t0, &t1) && t0 == 0.0f &&
             fabsf(t1 - 0.5f) < 1e-6f, "inside start %g %g", t0, t1);
  EXPECT(rc_slab(v3(1, 1, -2), v3(0, 0, 1), v3(1, 1, 0), v3(3, 3, 3), &t0, &t1) &&
             fabsf(t0 - 2) < 1e-6f, "a ray along a face enters");
}

/* --- pyramid --------------------------------------------------------------------- */

/* 1 when every channel of every source is one value over block b (voxels
 * [lo, lo + size)) and halo voxels around, clipped to the grid. */
static int brute_constant(int n[3], const oct_source_t *src, int nsrc, int halo,
                          const int lo[3], int size) {
  int a[3], b[3];
  for (int q = 0; q < 3; q++) {
    a[q] = lo[q] - halo < 0 ? 0 : lo[q] - halo;
    b[q] = lo[q] + size + halo > n[q] ? n[q] : lo[q] + size + halo;
  }
  for (int s = 0; s < nsrc; s++)
    for (int c = 0; c < src[s].channels; c++) {
      float mn = 1e30f, mx = -1e30f;
      for (int k = a[2]; k < b[2]; k++)
        for (int j = a[1]; j < b[1]; j++)
          for (int i = a[0]; i < b[0]; i++) {
            float v = src[s].values[(size_t)src[s].stride * (i + (size_t)n[0] * (j + (size_t)n[1] * k)) + c];
            mn = v < mn ? v : mn;
            mx = v > mx ? v : mx;
          }
      if (mx != mn) return 0;
    }
  return 1;
}

static void check_pyramid(int n[3], const oct_source_t *src, int nsrc, int halo) {
  oct_pyramid_t p;
  bk_error_t err = {0};
  REQUIRE(oct_build_fields(n[0], n[1], n[2], src, nsrc, halo, &p, &err) == BK_OK, "%s",
          err.msg);
  /* each finest block by brute force, once; a level-l block is constant
   * when all its finest blocks are */
  unsigned char *fine = calloc((size_t)p.bx * p.by * p.bz, 1);
  REQUIRE(fine != NULL, "out of memory");
  for (int k = 0; k < p.bz; k++)
    for (int j = 0; j < p.by; j++)
      for (int i = 0; i < p.bx; i++)
        fine[i + (size_t)p.bx * (j + (size_t)p.by * k)] =
            (unsigned char)brute_constant(n, src, nsrc, halo, (int[3]){2 * i, 2 * j, 2 * k}, 2);
  int bad = 0;
  for (int k = 0; k < p.bz; k++)
    for (int j = 0; j < p.by; j++)
      for (int i = 0; i < p.bx; i++) {
        int want = 0, c[3] = {2 * i, 2 * j, 2 * k};
        for (int l = RC_LEVELS; l >= 1 && !want; l--) {
          int lo[3], hi[3];
          rc_block_bounds((rc_dims){n[0], n[1], n[2]}, l, c, lo, hi);
          int all = 1;
          for (int z = lo[2] / 2; z < (hi[2] + 1) / 2 && all; z++)
            for (int y = lo[1] / 2; y < (hi[1] + 1) / 2 && all; y++)
              for (int x = lo[0] / 2; x < (hi[0] + 1) / 2 && all; x++)
                all = fine[x + (size_t)p.bx * (y + (size_t)p.by * z)];
          if (all) want = l;
        }
        int got = rc_block_level(p.level, (rc_dims){n[0], n[1], n[2]}, c);
        if (got != want && bad++ < 3)
          EXPECT(0, "halo %d block (%d,%d,%d): level %d, want %d", halo, i, j, k, got, want);
      }
  EXPECT(bad == 0, "halo %d: %d blocks wrong", halo, bad);
  free(fine);
  oct_free(&p);
}

/* src (w floats per voxel over n) into dst in field.h's padded layout,
 * the padding another value (7), which a scan must not read. */
static void pad_copy(float *dst, const float *src, int w, const int n[3]) {
  const size_t px = (size_t)n[0] + 2, py = (size_t)n[1] + 2;
  for (size_t q = 0; q < (size_t)w * px * py * ((size_t)n[2] + 2); q++) dst[q] = 7.0f;
  for (int k = 0; k < n[2]; k++)
    for (int j = 0; j < n[1]; j++)
      memcpy(dst + (size_t)w * (1 + px * ((size_t)j + 1 + py * ((size_t)k + 1))),
             src + (size_t)w * n[0] * (j + (size_t)n[1] * k), (size_t)w * sizeof(float) * n[0]);
}

static void test_pyramid(void) {
  /* tall enough (35 block rows) for the build to split it between two
   * threads; the second ball and slab straddle the split (row 17, z = 34), a box
   * ends in its halo */
  enum { NX = 37, NY = 20, NZ = 70 };
  static float a[NX * NY * NZ], b[4 * NX * NY * NZ];
  int n[3] = {NX, NY, NZ};
  for (int k = 0; k < NZ; k++)
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++) {
        size_t v = i + (size_t)NX * (j + (size_t)NY * k);
        /* a ball of another value, and in b a slab where only channel 2 varies */
        a[v] = (i - 20) * (i - 20) + (j - 6) * (j - 6) + (k - 9) * (k - 9) < 16 ? 1.5f : 1.0f;
        if ((i - 9) * (i - 9) + (j - 12) * (j - 12) + (k - 34) * (k - 34) < 9) a[v] = 1.25f;
        /* seen by row 17 only through its halo */
        if (i >= 25 && i < 29 && j >= 3 && j < 7 && k >= 30 && k <= 32) a[v] = 1.125f;
        for (int c = 0; c < 4; c++) b[4 * v + c] = 0.25f;
        if ((k >= 18 && k < 20) || k == 35) b[4 * v + 2] = 0.25f + 1e-3f * (float)i;
      }
  /* {S, σt} pairs (the view's grey-light medium): S varies in a ball */
  static float c[2 * NX * NY * NZ];
  for (int k = 0; k < NZ; k++)
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++) {
        size_t v = i + (size_t)NX * (j + (size_t)NY * k);
        c[2 * v] = (i - 30) * (i - 30) + (j - 10) * (j - 10) + (k - 24) * (k - 24) < 25
                       ? 0.5f + 1e-3f * (float)k : 0.5f;
        c[2 * v + 1] = 0.75f;
      }
  const oct_source_t one = {a, 1, 1, 0}, two[2] = {{a, 1, 1, 0}, {b, 4, 3, 0}};
  /* every float of a voxel a channel: the view's pairs, four-lane fields */
  const oct_source_t whole[2] = {{c, 2, 2, 0}, {b, 4, 4, 0}};
  for (int halo = 1; halo <= OCT_MAX_HALO; halo++) {
    check_pyramid(n, &one, 1, halo);
    check_pyramid(n, two, 2, halo);
  }
  for (int halo = 1; halo <= OCT_MAX_HALO; halo++) check_pyramid(n, whole, 2, halo);
  /* b stored padded (field.h's layout, the view's medium) with another
   * value in the padding, which the scan must not read: the same pyramid */
  static float bp[4 * (NX + 2) * (NY + 2) * (NZ + 2)];
  pad_copy(bp, b, 4, n);
  const oct_source_t padded[2] = {{a, 1, 1, 0}, {bp, 4, 3, 1}};
  oct_pyramid_t p0, p1;
  bk_error_t err = {0};
  REQUIRE(oct_build_fields(NX, NY, NZ, two, 2, 1, &p0, &err) == BK_OK &&
              oct_build_fields(NX, NY, NZ, padded, 2, 1, &p1, &err) == BK_OK,
          "%s", err.msg);
  EXPECT(!memcmp(p0.level, p1.level, (size_t)p0.bx * p0.by * p0.bz),
         "a padded source gives another pyramid");
  oct_free(&p0);
  oct_free(&p1);
  /* the same for the pairs, compared whole */
  static float cp[2 * (NX + 2) * (NY + 2) * (NZ + 2)];
  pad_copy(cp, c, 2, n);
  const oct_source_t pairs = {c, 2, 2, 0}, pairs_padded = {cp, 2, 2, 1};
  REQUIRE(oct_build_fields(NX, NY, NZ, &pairs, 1, 2, &p0, &err) == BK_OK &&
              oct_build_fields(NX, NY, NZ, &pairs_padded, 1, 2, &p1, &err) == BK_OK,
          "%s", err.msg);
  EXPECT(!memcmp(p0.level, p1.level, (size_t)p0.bx * p0.by * p0.bz),
         "a padded source of pairs gives another pyramid");
  oct_free(&p0);
  oct_free(&p1);
}

int main(int argc, char **argv) {
  const char *t = argc > 1 ? argv[1] : "all";
  int all = !strcmp(t, "all");
  if (all || !strcmp(t, "field")) test_field();
  if (all || !strcmp(t, "sampler")) test_sampler();
  if (all || !strcmp(t, "sparse")) test_sparse_field();
  if (all || !strcmp(t, "step")) test_step();
  if (all || !strcmp(t, "atten_slab")) test_atten_slab();
  if (all || !strcmp(t, "pyramid")) test_pyramid();
  if (all || !strcmp(t, "cells")) test_cells();
  if (tu_failures) fprintf(stderr, "%s: %d check(s) failed\n", t, tu_failures);
  else printf("%s: ok\n", t);
  return tu_failures ? 1 : 0;
}
