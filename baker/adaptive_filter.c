/* adaptive_filter.c: the reconstruction filter of the adaptive pipeline on
 * the host (threads over z slices) and on the OpenCL device
 * (kernels/filter.cl); both run the slice functions of kernels/adaptive_filter.h. */
#define _POSIX_C_SOURCE 200809L
#include "adaptive.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"

#include "adaptive_internal.h"
#include "error_est.h"

/* The 1D Gaussian weights (kernels/adaptive_filter.h): row q (level), column |d|. */
#define AD_WEIGHT_COUNT (AD_WROW * AD_WROW)
static void filter_weights(float *w) {
  for (int i = 0; i < AD_WEIGHT_COUNT; i++) w[i] = 0.0f;
  for (int q = 1; q <= AD_FILTER_MAX_LEVEL; q++) {
    double sigma = (double)AD_FILTER_SIGMA * q;
    for (int d = 0; d <= q; d++) w[q * AD_WROW + d] = (float)exp(-(double)(d * d) / (2.0 * sigma * sigma));
  }
}

/* The filter's arguments: the grid, the channel count, alpha, levels in
 * 0..AD_FILTER_MAX_LEVEL (half voxels), the arrays, and the size of the
 * means (`levels` grids of `channels` floats). */
static int check_filter_args(const grid_dims_t *d, int channels, const float *radiance,
                             const float *count, const float *mean_weight, float alpha,
                             int levels, const float *out_radiance, size_t *voxels,
                             bk_error_t *err) {
  int rc = ad_grid_voxels(d, 3 * sizeof(float), "adaptive filter", voxels, err);
  if (rc != BK_OK) return rc;
  if (channels != 1 && channels != 3)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive filter: %d channels: expected 1 or 3", channels);
  if (!(alpha >= 0.0f) || isinf(alpha))
    return bk_fail(err, BK_ERR_INPUT, "adaptive.alpha: expected a finite number >= 0, got %g",
                   (double)alpha);
  if (levels < 0 || levels > AD_FILTER_MAX_LEVEL)
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive filter: largest radius %g voxels: expected 0..%g in half voxels",
                   0.5 * levels, 0.5 * AD_FILTER_MAX_LEVEL);
  if (!radiance || !count || !mean_weight || !out_radiance)
    return bk_fail(err, BK_ERR_RUNTIME, "adaptive filter: missing input or output array");
  if (out_radiance == radiance)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "adaptive filter: the output must not alias the input radiance");
  size_t bytes;
  if (!bk_mul3_size(*voxels, (size_t)channels * (levels > 0 ? (size_t)levels : 1),
                    sizeof(float), &bytes))
    return bk_fail(err, BK_ERR_INPUT, "adaptive filter: grid %dx%dx%d overflows the address space",
                   d->nx, d->ny, d->nz);
  return BK_OK;
}

/* One pass of the host filter over a range of z slices, with scratch for
 * one slice (AD_SLICE_SCRATCH) per range. Every slice writes its scratch
 * before reading it, so the result does not depend on how bk_parallel cuts
 * the slices. */
typedef struct filter_pass {
  int pass; /* 0: means into M, 1: differences and the choice */
  const float *f, *count, *mean_weight, *weights;
  float *M; /* M, then DQ (kernels/adaptive_filter.h) */
  bk_grid g;
  int C, Q;
  float alpha, noise_k;
  float *out, *radius;
  size_t scratch_floats;
  atomic_int no_memory; /* a range that could not get its scratch */
} filter_pass_t;

static void filter_slices(void *arg, size_t lo, size_t hi) {
  filter_pass_t *p = arg;
  float *scratch = calloc(p->scratch_floats, sizeof(float));
  if (!scratch) {
    atomic_store(&p->no_memory, 1);
    return;
  }
  const bk_long dq = (bk_long)p->g.nx * p->g.ny * p->g.nz * p->C * p->Q;
  for (int k = (int)lo; k < (int)hi; k++) {
    if (p->pass == 0)
      ad_means_slice(p->f, p->weights, scratch, p->M, p->M + dq, p->g, k, p->Q, p->C);
    else
      ad_select_slice(p->f, p->M, p->M + dq, p->count, p->mean_weight, scratch, p->g, k,
                      p->alpha, p->noise_k, p->Q, p->C, p->out, p->radius);
  }
  free(scratch);
}

int ad_filter_host(const grid_dims_t *d, int channels, const float *radiance, const float *count,
                   const float *mean_weight, float alpha, float noise_k, int levels,
                   float *out_radiance, float *out_radius, bk_error_t *err) {
  size_t voxels, scratch_bytes;
  float weights[AD_WEIGHT_COUNT];
  int rc = check_filter_args(d, channels, radiance, count, mean_weight, alpha, levels,
                             out_radiance, &voxels, err);
  if (rc != BK_OK) return rc;
  if (levels == 0 || alpha == 0.0f) { /* nothing to filter */
    memcpy(out_radiance, radiance, voxels * channels * sizeof(float));
    if (out_radius) memset(out_radius, 0, voxels * sizeof(float));
    return BK_OK;
  }
  filter_weights(weights);
  filter_pass_t p = {0, radiance, count, mean_weight, weights, NULL, pm_kernel_grid(d), channels,
                     levels, alpha, noise_k, out_radiance, out_radius,
                     (size_t)AD_SLICE_SCRATCH(d->nx, d->ny, channels, levels), 0};
  if (!bk_mul_size(p.scratch_floats, sizeof(float), &scratch_bytes))
    return bk_fail(err, BK_ERR_RUNTIME, "filter scratch: size overflows (%zu floats)",
                   p.scratch_floats);
  p.M = bk_calloc(voxels, (size_t)AD_MEANS_FLOATS(channels, levels) * sizeof(float),
                  "filter means", err);
  if (!p.M) return BK_ERR_RUNTIME;
  /* pass 1 reads the means of neighbouring slices: every slice of pass 0 first */
  for (p.pass = 0; p.pass < 2 && !atomic_load(&p.no_memory); p.pass++)
    bk_parallel((size_t)d->nz, 1, filter_slices, &p);
  free(p.M);
  if (atomic_load(&p.no_memory)) {
    char b[32];
    return bk_fail(err, BK_ERR_RUNTIME, "filter scratch: out of memory allocating %s",
                   bk_format_bytes((double)scratch_bytes, b, sizeof b));
  }
  return BK_OK;
}

/* The filter on device buffers (rgb, out_rgb: channels floats per voxel;
 * count, mean_weight, out_radius: a float per voxel, out_radius may be NULL):
 * builds kernels/filter.cl for these channels and levels (>= 1), enqueues its
 * two launches and waits. */
static int filter_cl_buffers(clh_context_t *cl, const grid_dims_t *d, size_t voxels, int channels,
                             cl_mem rgb, cl_mem count, cl_mem mean_weight, float alpha,
                             float noise_k, int levels, cl_mem out_rgb, cl_mem out_radius,
                             bk_error_t *err) {
  cl_program program = NULL;
  cl_kernel km = NULL, ks = NULL;
  cl_mem w_buf = NULL, s_buf = NULL, m_buf = NULL;
  cl_int cerr = CL_SUCCESS;
  float weights[AD_WEIGHT_COUNT];
  char opts[64], b1[32], b2[32];
  int rc = BK_ERR_RUNTIME;
  /* work-items, each with a slice of scratch: a few per core on a CPU, one
   * per slice elsewhere */
  size_t items = cl->is_cpu ? (size_t)4 * (cl->compute_units ? cl->compute_units : 1) : (size_t)d->nz;
  if (items > (size_t)d->nz) items = (size_t)d->nz;
  const size_t scratch_bytes =
      (size_t)AD_SLICE_SCRATCH(d->nx, d->ny, channels, levels) * items * sizeof(float);
  const size_t m_bytes = voxels * (size_t)AD_MEANS_FLOATS(channels, levels) * sizeof(float);
  if ((cl_ulong)m_bytes > cl->max_alloc || (cl_ulong)scratch_bytes > cl->max_alloc) {
    bk_fail(err, BK_ERR_RUNTIME,
            "adaptive filter: the %dx%dx%d grid needs %s in one buffer for radii up to %g "
            "voxels; %s allows %s (lower the resolution)",
            d->nx, d->ny, d->nz,
            bk_format_bytes((double)(m_bytes > scratch_bytes ? m_bytes : scratch_bytes), b1,
                            sizeof b1),
            0.5 * levels, cl->device_name, bk_format_bytes((double)cl->max_alloc, b2, sizeof b2));
    goto error;
  }
  snprintf(opts, sizeof opts, "-DAD_CH=%d -DAD_QMAX=%d", channels, levels);
  if (clh_build(cl, "filter.cl", opts, &program, err) != BK_OK) goto error;
  filter_weights(weights);
  w_buf = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof weights,
                         weights, &cerr);
  CLH_CHECK(cerr, err, error);
  s_buf = clCreateBuffer(cl->context, CL_MEM_READ_WRITE, scratch_bytes, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  m_buf = clCreateBuffer(cl->context, CL_MEM_READ_WRITE, m_bytes, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  km = clCreateKernel(program, "ad_means", &cerr);
  CLH_CHECK(cerr, err, error);
  ks = clCreateKernel(program, "ad_select", &cerr);
  CLH_CHECK(cerr, err, error);
  bk_grid g = pm_kernel_grid(d);
  cl_int want = out_radius != NULL;
  CLH_CHECK(clSetKernelArg(km, 0, sizeof(cl_mem), &rgb), err, error);
  CLH_CHECK(clSetKernelArg(km, 1, sizeof(cl_mem), &w_buf), err, error);
  CLH_CHECK(clSetKernelArg(km, 2, sizeof(cl_mem), &s_buf), err, error);
  CLH_CHECK(clSetKernelArg(km, 3, sizeof(cl_mem), &m_buf), err, error);
  CLH_CHECK(clSetKernelArg(km, 4, sizeof(bk_grid), &g), err, error);
  cl_mem sargs[5] = {rgb, m_buf, count, mean_weight, s_buf};
  for (cl_uint a = 0; a < 5; a++)
    CLH_CHECK(clSetKernelArg(ks, a, sizeof(cl_mem), &sargs[a]), err, error);
  CLH_CHECK(clSetKernelArg(ks, 5, sizeof(bk_grid), &g), err, error);
  CLH_CHECK(clSetKernelArg(ks, 6, sizeof(float), &alpha), err, error);
  CLH_CHECK(clSetKernelArg(ks, 7, sizeof(float), &noise_k), err, error);
  CLH_CHECK(clSetKernelArg(ks, 8, sizeof(cl_int), &want), err, error);
  CLH_CHECK(clSetKernelArg(ks, 9, sizeof(cl_mem), &out_rgb), err, error);
  /* a NULL buffer is a NULL pointer in the kernel, which want = 0 never touches */
  CLH_CHECK(clSetKernelArg(ks, 10, sizeof(cl_mem), &out_radius), err, error);
  /* work-groups of one: the work-items spread over the compute units */
  size_t local = 1;
  CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, km, 1, NULL, &items, &local, 0, NULL, NULL), err,
            error);
  CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, ks, 1, NULL, &items, &local, 0, NULL, NULL), err,
            error);
  CLH_CHECK(clFinish(cl->queue), err, error);
  rc = BK_OK;
error:
  if (km) clReleaseKernel(km);
  if (ks) clReleaseKernel(ks);
  if (w_buf) clReleaseMemObject(w_buf);
  if (s_buf) clReleaseMemObject(s_buf);
  if (m_buf) clReleaseMemObject(m_buf);
  if (program) clReleaseProgram(program);
  return rc;
}

int ad_filter_cl(clh_context_t *cl, const grid_dims_t *d, int channels, const float *radiance,
                 const float *count, const float *mean_weight, float alpha, float noise_k,
                 int levels, float *out_radiance, float *out_radius, bk_error_t *err) {
  cl_mem rgb = NULL, cnt = NULL, wm = NULL, out = NULL, rad = NULL;
  cl_int cerr = CL_SUCCESS;
  size_t voxels;
  int rc = check_filter_args(d, channels, radiance, count, mean_weight, alpha, levels,
                             out_radiance, &voxels, err);
  if (rc != BK_OK) return rc;
  if (levels == 0 || alpha == 0.0f) /* nothing to filter: the host copies */
    return ad_filter_host(d, channels, radiance, count, mean_weight, alpha, noise_k, levels,
                          out_radiance, out_radius, err);
  rc = BK_ERR_RUNTIME;
  size_t rgb_bytes = voxels * channels * sizeof(float), one_bytes = voxels * sizeof(float);
  /* a CPU device works in place on the host arrays; a GPU copies */
  const cl_mem_flags in = CL_MEM_READ_ONLY | (cl->is_cpu ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR);
  const cl_mem_flags outf = CL_MEM_WRITE_ONLY | (cl->is_cpu ? CL_MEM_USE_HOST_PTR : 0);
  rgb = clCreateBuffer(cl->context, in, rgb_bytes, (void *)radiance, &cerr);
  CLH_CHECK(cerr, err, error);
  cnt = clCreateBuffer(cl->context, in, one_bytes, (void *)count, &cerr);
  CLH_CHECK(cerr, err, error);
  wm = clCreateBuffer(cl->context, in, one_bytes, (void *)mean_weight, &cerr);
  CLH_CHECK(cerr, err, error);
  out = clCreateBuffer(cl->context, outf, rgb_bytes, cl->is_cpu ? out_radiance : NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  if (out_radius) {
    rad = clCreateBuffer(cl->context, outf, one_bytes, cl->is_cpu ? out_radius : NULL, &cerr);
    CLH_CHECK(cerr, err, error);
  }
  if (filter_cl_buffers(cl, d, voxels, channels, rgb, cnt, wm, alpha, noise_k, levels, out, rad,
                        err) != BK_OK)
    goto error;
  if (cl->is_cpu) {
    /* make the host arrays current (no copy on PoCL) */
    cl_mem both[2] = {out, rad};
    size_t sizes[2] = {rgb_bytes, one_bytes};
    for (int b = 0; b < 2; b++) {
      if (!both[b]) continue;
      void *p = clEnqueueMapBuffer(cl->queue, both[b], CL_TRUE, CL_MAP_READ, 0, sizes[b], 0, NULL,
                                   NULL, &cerr);
      CLH_CHECK(cerr, err, error);
      CLH_CHECK(clEnqueueUnmapMemObject(cl->queue, both[b], p, 0, NULL, NULL), err, error);
    }
    CLH_CHECK(clFinish(cl->queue), err, error);
  } else {
    CLH_CHECK(clEnqueueReadBuffer(cl->queue, out, CL_TRUE, 0, rgb_bytes, out_radiance, 0, NULL,
                                  NULL), err, error);
    if (out_radius)
      CLH_CHECK(clEnqueueReadBuffer(cl->queue, rad, CL_TRUE, 0, one_bytes, out_radius, 0, NULL,
                                    NULL), err, error);
  }
  rc = BK_OK;
error:
  if (rgb) clReleaseMemObject(rgb);
  if (cnt) clReleaseMemObject(cnt);
  if (wm) clReleaseMemObject(wm);
  if (out) clReleaseMemObject(out);
  if (rad) clReleaseMemObject(rad);
  return rc;
}

/* --- the filter at given radii, on the even lattice (the error estimate's halves) --- */

typedef struct fixed_job {
  const grid_dims_t *d;
  int axis, q, mx, my;
  const float *in, *w;
  float *out;
} fixed_job_t;

/* The sum of the level's weights over the taps around c inside [0, n): what
 * each tap's weight is divided by in the y and z passes (the renormalisation
 * at the grid's faces). */
static float tap_sum(const float *w, int c, int q, int n) {
  float ws = 0.0f;
  for (int t = c - q < 0 ? 0 : c - q; t <= c + q && t < n; t++) ws += w[t > c ? t - c : c - t];
  return ws;
}

/* One axis of the level-q Gaussian, evaluated only where the lattice needs
 * it: along x at even x of every row (slices k = z), along y at even y
 * (slices k = z), along z at even z (k = z / 2). The arithmetic of each
 * value is the full-grid filter's (x: Σ w·v / Σ w; y, z: Σ (w / Σ w)·v in
 * tap order), so every lattice value equals that filter's there bit for bit. */
static void fixed_slices(void *arg, size_t lo, size_t hi) {
  const fixed_job_t *j = arg;
  const int nx = j->d->nx, ny = j->d->ny, nz = j->d->nz, q = j->q, mx = j->mx, my = j->my;
  const float *w = j->w + q * AD_WROW;
  for (size_t k = lo; k < hi; k++) {
    if (j->axis == 0) {
      for (int y = 0; y < ny; y++) {
        const float *in = j->in + (k * ny + y) * nx;
        float *out = j->out + (k * ny + y) * mx;
        for (int e = 0; e < mx; e++) {
          const int i = 2 * e;
          float s = 0.0f, ws = 0.0f;
          for (int t = i - q < 0 ? 0 : i - q; t <= i + q && t < nx; t++) {
            float wt = w[t > i ? t - i : i - t];
            s += wt * in[t], ws += wt;
          }
          out[e] = s / ws;
        }
      }
      continue;
    }
    /* y: rows of mx from slice k's ny rows; z: slices of my * mx from nz */
    const int n = j->axis == 1 ? ny : nz, outs = j->axis == 1 ? my : 1;
    const size_t len = j->axis == 1 ? (size_t)mx : (size_t)my * mx;
    for (int r = 0; r < outs; r++) {
      const int c = j->axis == 1 ? 2 * r : 2 * (int)k;
      const float *src = j->axis == 1 ? j->in + k * ny * mx : j->in;
      float *dst = j->out + (j->axis == 1 ? (k * my + r) * mx : k * len);
      const float ws = tap_sum(w, c, q, n);
      for (size_t v = 0; v < len; v++) dst[v] = 0.0f;
      for (int t = c - q < 0 ? 0 : c - q; t <= c + q && t < n; t++) {
        const float wt = w[t > c ? t - c : c - t] / ws, *row = src + (size_t)t * len;
        for (size_t v = 0; v < len; v++) dst[v] += wt * row[v];
      }
    }
  }
}

/* The filter level of a radius (half voxels). */
static int level_of(float radius) { return (int)(2.0f * radius + 0.5f); }

/* Each lattice voxel's filter level, clamped to [0, AD_FILTER_MAX_LEVEL], in
 * lev; used[q] set for each level present. tmp: L floats of scratch. */
static void lattice_levels(const grid_dims_t *d, const float *radius, size_t L, float *tmp,
                           bk_uchar *lev, int used[AD_FILTER_MAX_LEVEL + 1]) {
  ee_lattice_gather(d, radius, 1, tmp);
  for (size_t k = 0; k < L; k++) {
    int q = level_of(tmp[k]);
    lev[k] = (bk_uchar)(q < 0 ? 0 : q > AD_FILTER_MAX_LEVEL ? AD_FILTER_MAX_LEVEL : q);
    used[lev[k]] = 1;
  }
}

int ad_filter_fixed_lattice(const grid_dims_t *d, const float *const *in, int count,
                            const float *radius, int levels, float *const *out,
                            bk_error_t *err) {
  const int mx = (d->nx + 1) / 2, my = (d->ny + 1) / 2, mz = (d->nz + 1) / 2;
  const size_t L = (size_t)mz * my * mx;
  float w[AD_WEIGHT_COUNT];
  filter_weights(w);
  /* one set of pass buffers and one level map for every input */
  float *a = bk_calloc((size_t)d->nz * d->ny * mx, sizeof(float), "filter at given radii", err);
  float *b = bk_calloc((size_t)d->nz * my * mx, sizeof(float), "filter at given radii", err);
  float *c = bk_calloc(L, sizeof(float), "filter at given radii", err);
  bk_uchar *lev = bk_calloc(L, 1, "filter at given radii", err);
  if (!a || !b || !c || !lev) {
    free(a), free(b), free(c), free(lev);
    return BK_ERR_RUNTIME;
  }
  int used[AD_FILTER_MAX_LEVEL + 1] = {0};
  lattice_levels(d, radius, L, c, lev, used);
  for (int i = 0; i < count; i++) {
    ee_lattice_gather(d, in[i], 1, out[i]);
    for (int q = 1; q <= levels && q <= AD_FILTER_MAX_LEVEL; q++) {
      if (!used[q]) continue;
      fixed_job_t j = {d, 0, q, mx, my, in[i], w, a};
      bk_parallel((size_t)d->nz, 1, fixed_slices, &j);
      j.axis = 1, j.in = a, j.out = b;
      bk_parallel((size_t)d->nz, 1, fixed_slices, &j);
      j.axis = 2, j.in = b, j.out = c;
      bk_parallel((size_t)mz, 1, fixed_slices, &j);
      for (size_t k = 0; k < L; k++)
        if (lev[k] == q) out[i][k] = c[k];
    }
  }
  free(a), free(b), free(c), free(lev);
  return BK_OK;
}
