/* field.c: the {∇n, n} field of the ray core (see field.h). */
#include "field.h"

#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "kernels/ray_core.h"

size_t fld_padded_count(int nx, int ny, int nz) {
  return ((size_t)nx + 2) * ((size_t)ny + 2) * ((size_t)nz + 2);
}

/* Fills the outer layer of a padded field of w floats per voxel from its
 * edge voxels: x faces per row, then whole y rows, then whole z planes, so
 * edges and corners copy what the previous pass put there. */
void fld_pad_faces(int nx, int ny, int nz, int w, float *f) {
  const size_t px = (size_t)nx + 2, py = (size_t)ny + 2, row = (size_t)w * px, plane = row * py;
  for (size_t K = 1; K <= (size_t)nz; K++)
    for (size_t J = 1; J <= (size_t)ny; J++) {
      float *r = f + K * plane + J * row;
      memcpy(r, r + w, (size_t)w * sizeof(float));
      memcpy(r + (size_t)w * (px - 1), r + (size_t)w * (px - 2), (size_t)w * sizeof(float));
    }
  for (size_t K = 1; K <= (size_t)nz; K++) {
    float *p = f + K * plane;
    memcpy(p, p + row, row * sizeof(float));
    memcpy(p + (py - 1) * row, p + (py - 2) * row, row * sizeof(float));
  }
  memcpy(f, f + plane, plane * sizeof(float));
  memcpy(f + ((size_t)nz + 1) * plane, f + (size_t)nz * plane, plane * sizeof(float));
}

void fld_pad4_faces(int nx, int ny, int nz, float *f) { fld_pad_faces(nx, ny, nz, 4, f); }

/* The sparse field of one n (kernels/ray_core.h rc_field_gather): brick
 * by brick, each brick's (RC_BRICK + 1)³ corners computed, kept when any
 * is not (∇n = 0, the brick's first n). */
typedef struct fld_job {
  rc_dims d;
  double h;
  float inv_h;
  const float *ior;
  int bx, by, bz;
  int *slot;     /* per brick: 1 to keep (pass 1), then its slot or -1 */
  float *konst;  /* per brick: its n when not kept */
  float *bricks; /* pass 2: the kept bricks */
} fld_job_t;

/* The field at padded corner (X, Y, Z): the voxel's, the edge voxel's on
 * the padding (as the padded layout replicates it). */
static void corner(const fld_job_t *x, int X, int Y, int Z, float q[4]) {
  const rc_dims d = x->d;
  const int i = bk_clampi(X - 1, 0, d.nx - 1), j = bk_clampi(Y - 1, 0, d.ny - 1),
            k = bk_clampi(Z - 1, 0, d.nz - 1);
  bk_v3 g = rc_gradient_at(d, x->inv_h, x->ior, i, j, k); /* 1/m -> 1/voxel */
  q[0] = (float)(g.x * x->h);
  q[1] = (float)(g.y * x->h);
  q[2] = (float)(g.z * x->h);
  q[3] = x->ior[(size_t)i + (size_t)d.nx * ((size_t)j + (size_t)d.ny * k)];
}

/* Brick b's first padded corner. */
static void brick_origin(const fld_job_t *x, size_t b, int o[3]) {
  o[0] = RC_BRICK * (int)(b % (size_t)x->bx);
  o[1] = RC_BRICK * (int)(b / (size_t)x->bx % (size_t)x->by);
  o[2] = RC_BRICK * (int)(b / ((size_t)x->bx * (size_t)x->by));
}

/* Brick b's corners into out (RC_BRICK_FLOATS floats); whether all of them
 * are (0, 0, 0, n0), n0 the first corner's n. */
static int brick(const fld_job_t *x, size_t b, float *out) {
  int o[3];
  brick_origin(x, b, o);
  int flat = 1;
  float *q = out;
  for (int z = 0; z < RC_BRICK_SIDE; z++)
    for (int y = 0; y < RC_BRICK_SIDE; y++)
      for (int c = 0; c < RC_BRICK_SIDE; c++, q += 4) {
        corner(x, o[0] + c, o[1] + y, o[2] + z, q);
        flat &= q[0] == 0.0f && q[1] == 0.0f && q[2] == 0.0f && q[3] == out[3];
      }
  return flat;
}

/* Whether n is one value over the voxels brick b's corners and their
 * neighbours read (clamped to the grid): then every corner is (0, 0, 0, n)
 * and the brick need not be computed. */
static int brick_uniform(const fld_job_t *x, size_t b, float *n) {
  const rc_dims d = x->d;
  int lo[3], hi[3], o[3];
  const int N[3] = {d.nx, d.ny, d.nz};
  brick_origin(x, b, o);
  for (int a = 0; a < 3; a++) { /* corners X0..X0+RC_BRICK are voxels X-1, then ±1 */
    lo[a] = bk_clampi(o[a] - 2, 0, N[a] - 1);
    hi[a] = bk_clampi(o[a] + RC_BRICK, 0, N[a] - 1);
  }
  const float *v = x->ior;
  *n = v[(size_t)lo[0] + (size_t)d.nx * ((size_t)lo[1] + (size_t)d.ny * lo[2])];
  for (int k = lo[2]; k <= hi[2]; k++)
    for (int j = lo[1]; j <= hi[1]; j++) {
      const float *row = v + (size_t)d.nx * ((size_t)j + (size_t)d.ny * k);
      for (int i = lo[0]; i <= hi[0]; i++)
        if (row[i] != *n) return 0;
    }
  return 1;
}

static void classify(void *ctx, size_t lo, size_t hi) {
  fld_job_t *x = ctx;
  float tmp[RC_BRICK_FLOATS];
  for (size_t b = lo; b < hi; b++) {
    if (brick_uniform(x, b, &x->konst[b])) {
      x->slot[b] = 0;
      continue;
    }
    x->slot[b] = !brick(x, b, tmp);
    x->konst[b] = tmp[3];
  }
}

static void fill(void *ctx, size_t lo, size_t hi) {
  fld_job_t *x = ctx;
  for (size_t b = lo; b < hi; b++)
    if (x->slot[b] >= 0) brick(x, b, x->bricks + (size_t)x->slot[b] * RC_BRICK_FLOATS);
}

/* One n's sparse field (caller frees; *floats its size). */
static float *build_one(rc_dims d, double h, const float *ior, size_t *floats, bk_error_t *err) {
  fld_job_t x = {d, h, 1.0f / (float)h, ior, d.nx / RC_BRICK + 1, d.ny / RC_BRICK + 1,
                 d.nz / RC_BRICK + 1, NULL, NULL, NULL};
  const size_t bricks = (size_t)x.bx * x.by * x.bz;
  float *f = NULL;
  x.slot = bk_calloc(bricks, sizeof(int), "field: brick table", err);
  x.konst = bk_calloc(bricks, sizeof(float), "field: brick values", err);
  if (!x.slot || !x.konst) goto done;
  bk_parallel(bricks, 16, classify, &x);
  int stored = 0;
  for (size_t b = 0; b < bricks; b++) x.slot[b] = x.slot[b] ? stored++ : -1;
  *floats = (size_t)rc_field_floats(d, stored);
  if (!(f = bk_calloc(*floats, sizeof(float), "field: n and grad n", err))) goto done;
  const int head[4] = {x.bx, x.by, x.bz, stored};
  memcpy(f, head, sizeof head);
  memcpy(f + 4, x.slot, bricks * sizeof(int));
  memcpy(f + 4 + bricks, x.konst, bricks * sizeof(float));
  x.bricks = f + 4 + 2 * bricks;
  bk_parallel(bricks, 16, fill, &x);
done:
  free(x.slot);
  free(x.konst);
  return f;
}

/* The fields of `count` n grids one after the other. */
static float *build(int nx, int ny, int nz, double h, const float *const *ior, int count,
                    bk_error_t *err) {
  const rc_dims d = {nx, ny, nz};
  float *part[3] = {NULL, NULL, NULL}, *f = NULL;
  size_t floats[3] = {0, 0, 0}, total = 0;
  for (int c = 0; c < count; c++) {
    if (!(part[c] = build_one(d, h, ior[c], &floats[c], err))) goto done;
    total += floats[c];
  }
  if (count == 1) return part[0];
  if (!(f = bk_calloc(total, sizeof(float), "field: n and grad n per channel", err))) goto done;
  size_t at = 0;
  for (int c = 0; c < count; at += floats[c], c++)
    memcpy(f + at, part[c], floats[c] * sizeof(float));
done:
  for (int c = 0; c < count && count > 1; c++) free(part[c]);
  return f;
}

size_t fld_floats(int nx, int ny, int nz, const float *ng, int fields) {
  const rc_dims d = {nx, ny, nz};
  size_t total = 0;
  for (int c = 0; c < fields; c++) total += (size_t)rc_field_floats(d, RC_AS_INT(ng[total + 3]));
  return total;
}

float *fld_build(int nx, int ny, int nz, double h, const float *ior, bk_error_t *err) {
  const float *n[1] = {ior};
  return build(nx, ny, nz, h, n, 1, err);
}

float *fld_build_rgb(int nx, int ny, int nz, double h, const float *ior, const float *ior_rb,
                     bk_error_t *err) {
  const size_t count = (size_t)nx * ny * nz;
  const float *n[3] = {ior_rb, ior, ior_rb + count};
  return build(nx, ny, nz, h, n, 3, err);
}

typedef struct pad_ctx {
  rc_dims d;
  const float *src;
  float *dst;
} pad_ctx_t;

/* The rows of z slices [k0, k1) into the padded layout. */
static void pad_slices(void *arg, size_t k0, size_t k1) {
  const pad_ctx_t *x = arg;
  const int nx = x->d.nx, ny = x->d.ny;
  for (int k = (int)k0; k < (int)k1; k++)
    for (int j = 0; j < ny; j++)
      memcpy(x->dst + 4 * rc_pad_index(x->d, 0, j, k),
             x->src + 4 * (size_t)nx * ((size_t)j + (size_t)ny * k), 4 * sizeof(float) * (size_t)nx);
}

void fld_pad4(int nx, int ny, int nz, const float *src, float *dst) {
  pad_ctx_t x = {{nx, ny, nz}, src, dst};
  bk_parallel((size_t)nz, 1, pad_slices, &x);
  fld_pad4_faces(nx, ny, nz, dst);
}

void fld_voxel(const float *ng, int i, int j, int k, float q[4]) {
  /* the sampler's stencil at the voxel's own padded corner: a mix with
   * weight 0 of the next corners gives this one's value exactly */
  rc_tri t;
  t.ix = i + 1, t.iy = j + 1, t.iz = k + 1;
  t.base = 0;
  t.tx = t.ty = t.tz = 0.0f;
  rc_f4 v = rc_field_gather(ng, &t);
  q[0] = v.x, q[1] = v.y, q[2] = v.z, q[3] = v.w;
}
