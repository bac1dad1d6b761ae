/* field.c: the {∇n, n} field of the ray core (see field.h). */
#include "field.h"

#include <string.h>

#include "base/parallel.h"
#include "kernels/ray_core.h"

size_t fld_padded_count(int nx, int ny, int nz) {
  return ((size_t)nx + 2) * ((size_t)ny + 2) * ((size_t)nz + 2);
}

/* Fills the outer layer of a padded float4 field from its edge voxels: x
 * faces per row, then whole y rows, then whole z planes, so edges and
 * corners copy what the previous pass put there. */
static void pad_faces(int nx, int ny, int nz, float *f) {
  const size_t px = (size_t)nx + 2, py = (size_t)ny + 2, row = 4 * px, plane = row * py;
  for (size_t K = 1; K <= (size_t)nz; K++)
    for (size_t J = 1; J <= (size_t)ny; J++) {
      float *r = f + K * plane + J * row;
      memcpy(r, r + 4, 4 * sizeof(float));
      memcpy(r + 4 * (px - 1), r + 4 * (px - 2), 4 * sizeof(float));
    }
  for (size_t K = 1; K <= (size_t)nz; K++) {
    float *p = f + K * plane;
    memcpy(p, p + row, row * sizeof(float));
    memcpy(p + (py - 1) * row, p + (py - 2) * row, row * sizeof(float));
  }
  memcpy(f, f + plane, plane * sizeof(float));
  memcpy(f + ((size_t)nz + 1) * plane, f + (size_t)nz * plane, plane * sizeof(float));
}

/* One thread's z-slices of the field. */
typedef struct fld_job {
  rc_dims d;
  double h;
  const float *ior;
  float *f;
} fld_job_t;

static void fld_slices(void *ctx, size_t k0, size_t k1) {
  const fld_job_t *job = ctx;
  const rc_dims d = job->d;
  const double h = job->h;
  const float inv_h = 1.0f / (float)h;
  for (int k = (int)k0; k < (int)k1; k++)
    for (int j = 0; j < d.ny; j++)
      for (int i = 0; i < d.nx; i++) {
        bk_v3 g = rc_gradient_at(d, inv_h, job->ior, i, j, k); /* 1/m -> 1/voxel */
        float *q = job->f + 4 * rc_pad_index(d, i, j, k);
        q[0] = (float)(g.x * h);
        q[1] = (float)(g.y * h);
        q[2] = (float)(g.z * h);
        q[3] = job->ior[(size_t)i + (size_t)d.nx * ((size_t)j + (size_t)d.ny * k)];
      }
}

float *fld_build(int nx, int ny, int nz, double h, const float *ior, bk_error_t *err) {
  float *f = bk_calloc(fld_padded_count(nx, ny, nz), 4 * sizeof(float), "field: n and grad n", err);
  if (!f) return NULL;
  fld_job_t job = {{nx, ny, nz}, h, ior, f};
  bk_parallel((size_t)nz, 4, fld_slices, &job);
  pad_faces(nx, ny, nz, f);
  return f;
}

float *fld_build_rgb(int nx, int ny, int nz, double h, const float *ior, const float *ior_rb,
                     bk_error_t *err) {
  const size_t pad = fld_padded_count(nx, ny, nz), count = (size_t)nx * ny * nz;
  float *f = bk_calloc(3 * pad, 4 * sizeof(float), "field: n and grad n per channel", err);
  if (!f) return NULL;
  const float *n[3] = {ior_rb, ior, ior_rb + count};
  for (int c = 0; c < 3; c++) {
    fld_job_t job = {{nx, ny, nz}, h, n[c], f + 4 * pad * c};
    bk_parallel((size_t)nz, 4, fld_slices, &job);
    pad_faces(nx, ny, nz, job.f);
  }
  return f;
}

void fld_pad4(int nx, int ny, int nz, const float *src, float *dst) {
  const rc_dims d = {nx, ny, nz};
  for (int k = 0; k < nz; k++)
    for (int j = 0; j < ny; j++)
      memcpy(dst + 4 * rc_pad_index(d, 0, j, k), src + 4 * (size_t)nx * ((size_t)j + (size_t)ny * k),
             4 * sizeof(float) * (size_t)nx);
  pad_faces(nx, ny, nz, dst);
}
