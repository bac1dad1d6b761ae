/* view_fields.c: the fields the view kernel reads besides the medium: ∇n
 * with n, the distance to refraction (flat), the padded 4-float layout and
 * the per-brick flags (kernels/view.h). */
#include "view_fields.h"

#include <math.h>
#include <string.h>

#include "kernels/ior.h"
#include "kernels/view.h"

/* 1 when the `ch` floats of every voxel of [lo, hi] (clamped) equal the first one's
 * (within tol). */
static int box_is_constant(const view_volume_t *v, const float *a, int ch, int lo[3], int hi[3],
                           float tol) {
  int l[3], h[3], n[3] = {v->nx, v->ny, v->nz};
  for (int k = 0; k < 3; k++) {
    l[k] = lo[k] < 0 ? 0 : lo[k];
    h[k] = hi[k] > n[k] - 1 ? n[k] - 1 : hi[k];
  }
  const float *a0 = a + ((size_t)l[0] + (size_t)v->nx * ((size_t)l[1] + (size_t)v->ny * l[2])) * ch;
  for (int k = l[2]; k <= h[2]; k++)
    for (int j = l[1]; j <= h[1]; j++) {
      const float *row = a + (size_t)v->nx * ((size_t)j + (size_t)v->ny * k) * ch;
      for (int i = l[0] * ch; i < (h[0] + 1) * ch; i++)
        if (fabsf(row[i] - a0[i % ch]) > tol) return 0;
    }
  return 1;
}

/* Per 8³ brick: VIEW_BRICK_N_CONST when n is one value over the brick and
 * VIEW_BRICK_MARGIN voxels around (the curved march walks straight there),
 * VIEW_BRICK_MEDIUM_CONST when S = σs L̄ and σt are over the brick and the
 * one voxel around that trilinear sampling reads (one step crosses it). */
int build_bricks(view_volume_t *v, bk_error_t *err) {
  const int B = 1 << VIEW_BRICK_SHIFT;
  v->bx = (v->nx + B - 1) / B;
  v->by = (v->ny + B - 1) / B;
  v->bz = (v->nz + B - 1) / B;
  v->bricks = bk_calloc((size_t)v->bx * v->by * v->bz, 1, "view: brick flags", err);
  if (!v->bricks) return BK_ERR_RUNTIME;
  for (int k = 0; k < v->bz; k++)
    for (int j = 0; j < v->by; j++)
      for (int i = 0; i < v->bx; i++) {
        int b[3] = {i * B, j * B, k * B}, lo[3], hi[3];
        unsigned char f = 0;
        for (int a = 0; a < 3; a++)
          lo[a] = b[a] - VIEW_BRICK_MARGIN, hi[a] = b[a] + B - 1 + VIEW_BRICK_MARGIN;
        if (!v->ior || box_is_constant(v, v->ior, 1, lo, hi, VIEW_N_EPS)) f |= VIEW_BRICK_N_CONST;
        for (int a = 0; a < 3; a++) lo[a] = b[a] - 1, hi[a] = b[a] + B;
        if (box_is_constant(v, v->medium, 4, lo, hi, 0.0f) &&
            (!v->sigma_t4 || box_is_constant(v, v->sigma_t4, 4, lo, hi, 0.0f)))
          f |= VIEW_BRICK_MEDIUM_CONST;
        v->bricks[i + (size_t)v->bx * (j + (size_t)v->by * k)] = f;
      }
  return BK_OK;
}

void view_ng_field(int nx, int ny, int nz, const float *ior, float *ng) {
  const bk_grid g = {nx, ny, nz, 0, 0.0f, 0.0f, 0.0f, 1.0f}; /* voxel units */
  for (int k = 0; k < nz; k++)
    for (int j = 0; j < ny; j++)
      for (int i = 0; i < nx; i++) {
        size_t v = (size_t)i + (size_t)nx * ((size_t)j + (size_t)ny * k);
        bk_v3 d = ior_gradient_at(ior, g, i, j, k);
        ng[4 * v] = d.x;
        ng[4 * v + 1] = d.y;
        ng[4 * v + 2] = d.z;
        ng[4 * v + 3] = ior[v];
      }
}

/* 1D pass of the Chebyshev distance transform along one axis (stride st,
 * length len, capped at VIEW_FLAT_MAX): out(i) = min over |r| < cap of
 * max(|r|, in(i + r)). Three passes give min over voxels j of
 * max(|i − j|∞, in(j)). */
static void flat_pass(const unsigned char *in, unsigned char *out, size_t st, int len) {
  int lo = VIEW_FLAT_MAX;
  for (int i = 0; i < len && lo == VIEW_FLAT_MAX; i++) lo = in[(size_t)i * st];
  if (lo == VIEW_FLAT_MAX) { /* nothing near this line (most lines) */
    for (int i = 0; i < len; i++) out[(size_t)i * st] = VIEW_FLAT_MAX;
    return;
  }
  for (int i = 0; i < len; i++) {
    int best = in[(size_t)i * st];
    for (int r = 1; r < best; r++) {
      int a = i - r >= 0 ? in[(size_t)(i - r) * st] : VIEW_FLAT_MAX;
      int b = i + r < len ? in[(size_t)(i + r) * st] : VIEW_FLAT_MAX;
      int m = a < b ? a : b;
      if (m < r) m = r;
      if (m < best) best = m;
    }
    out[(size_t)i * st] = (unsigned char)best;
  }
}

void view_flat_field(int nx, int ny, int nz, const float *ng, unsigned char *flat,
                     unsigned char *scratch) {
  const size_t sy = (size_t)nx, sz = (size_t)nx * ny;
  /* "zero" as the bricks see it: n steps below VIEW_N_EPS bend nothing */
  const float eps = 0.5f * VIEW_N_EPS;
  int lo[3] = {nx, ny, nz}, hi[3] = {-1, -1, -1};
  for (int k = 0; k < nz; k++)
    for (int j = 0; j < ny; j++)
      for (int i = 0; i < nx; i++) {
        size_t v = (size_t)i + sy * j + sz * k;
        int zero = fabsf(ng[4 * v]) <= eps && fabsf(ng[4 * v + 1]) <= eps &&
                   fabsf(ng[4 * v + 2]) <= eps;
        flat[v] = zero ? VIEW_FLAT_MAX : 0;
        if (!zero) {
          int c[3] = {i, j, k};
          for (int a = 0; a < 3; a++) {
            if (c[a] < lo[a]) lo[a] = c[a];
            if (c[a] > hi[a]) hi[a] = c[a];
          }
        }
      }
  if (hi[0] < 0) return; /* ∇n = 0 everywhere */
  /* distances below the cap only occur within VIEW_FLAT_MAX of a nonzero
   * voxel: the passes cover that box alone */
  const int n[3] = {nx, ny, nz};
  for (int a = 0; a < 3; a++) {
    lo[a] = lo[a] - VIEW_FLAT_MAX < 0 ? 0 : lo[a] - VIEW_FLAT_MAX;
    hi[a] = hi[a] + VIEW_FLAT_MAX > n[a] - 1 ? n[a] - 1 : hi[a] + VIEW_FLAT_MAX;
  }
  const int len[3] = {hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
#define AT(i, j, k) ((size_t)(i) + sy * (size_t)(j) + sz * (size_t)(k))
  for (int k = lo[2]; k <= hi[2]; k++)
    for (int j = lo[1]; j <= hi[1]; j++)
      flat_pass(flat + AT(lo[0], j, k), scratch + AT(lo[0], j, k), 1, len[0]);
  for (int k = lo[2]; k <= hi[2]; k++)
    for (int i = lo[0]; i <= hi[0]; i++)
      flat_pass(scratch + AT(i, lo[1], k), flat + AT(i, lo[1], k), sy, len[1]);
  for (int k = lo[2]; k <= hi[2]; k++)
    for (int j = lo[1]; j <= hi[1]; j++)
      memcpy(scratch + AT(lo[0], j, k), flat + AT(lo[0], j, k), (size_t)len[0]);
  for (int j = lo[1]; j <= hi[1]; j++)
    for (int i = lo[0]; i <= hi[0]; i++)
      flat_pass(scratch + AT(i, j, lo[2]), flat + AT(i, j, lo[2]), sz, len[2]);
#undef AT
}

void view_pad4(int nx, int ny, int nz, const float *src, float *dst) {
  const size_t px = (size_t)nx + 2, py = (size_t)ny + 2;
  for (size_t K = 0; K < (size_t)nz + 2; K++) {
    size_t k = K == 0 ? 0 : K > (size_t)nz ? (size_t)nz - 1 : K - 1;
    for (size_t J = 0; J < py; J++) {
      size_t j = J == 0 ? 0 : J > (size_t)ny ? (size_t)ny - 1 : J - 1;
      const float *row = src + 4 * (size_t)nx * (j + (size_t)ny * k);
      float *out = dst + 4 * px * (J + py * K);
      memcpy(out + 4, row, 4 * sizeof(float) * (size_t)nx);
      memcpy(out, row, 4 * sizeof(float));
      memcpy(out + 4 * ((size_t)nx + 1), row + 4 * ((size_t)nx - 1), 4 * sizeof(float));
    }
  }
}
