/* march.c: photon marching on OpenCL or on the host (see march.h). */
#define _DEFAULT_SOURCE /* sysconf, and M_PI from math.h */
#include "march.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "field.h"

double pm_fixed_scale(double power_max, double path_bound) {
  if (!(power_max > 0.0) || !(path_bound > 0.0)) return 1.0;
  double s = ldexp(1.0, 62) / (power_max * path_bound);
  /* the deposit is computed in float: keep S and Φ·ℓ·S finite */
  return s < 1e30 ? s : 1e30;
}

bk_grid pm_kernel_grid(const grid_dims_t *d) {
  bk_grid g;
  g.nx = d->nx, g.ny = d->ny, g.nz = d->nz, g.pad0 = 0;
  g.origin_x = (float)d->origin[0], g.origin_y = (float)d->origin[1], g.origin_z = (float)d->origin[2];
  g.voxel_size = (float)d->voxel_size;
  return g;
}

static void add_result(pm_stats_t *st, const pm_result *r) {
  st->photons++;
  switch (r->fate) {
  case PM_FATE_MISSED: st->missed_grid++; break;
  case PM_FATE_LEFT: st->left_grid++; break;
  case PM_FATE_ABSORBED: st->absorbed++; break;
  default: st->step_limit++; break;
  }
  st->steps += r->steps;
  st->voxels += r->voxels;
  st->path_voxels += r->path;
}

/* n, then σt: which specialisations the volume allows. */
static void scan_volume(const volume_t *vol, size_t count, int *has_refraction, int *homogeneous,
                        int *grey) {
  *has_refraction = 0;
  for (size_t i = 1; i < count; i++)
    if (vol->ior[i] != vol->ior[0]) {
      *has_refraction = 1;
      break;
    }
  *homogeneous = 1;
  *grey = 1;
  float t0[3];
  for (int c = 0; c < 3; c++) t0[c] = vol->sigma_s[c] + vol->sigma_a[c];
  for (size_t i = 0; i < count && (*homogeneous || *grey); i++) {
    float t[3];
    for (int c = 0; c < 3; c++) t[c] = vol->sigma_s[3 * i + c] + vol->sigma_a[3 * i + c];
    if (t[0] != t0[0] || t[1] != t0[1] || t[2] != t0[2]) *homogeneous = 0;
    if (t[0] != t[1] || t[0] != t[2]) *grey = 0;
  }
}

/* The fixed-point scale and the conversion to radiance for the setup's
 * lights, when no photon carries more than w_max times its light's power per
 * photon (the weighted march, march.h): the bound of march.h's scale rule
 * grows by w_max. */
static void set_scale(pm_setup_t *s, double w_max) {
  pm_params *P = &s->params;
  const grid_dims_t *d = &s->dims;
  const double h = d->voxel_size;
  double diag = sqrt((double)d->nx * d->nx + (double)d->ny * d->ny + (double)d->nz * d->nz);
  double pmax = 0.0;
  if (s->channels == 1) pmax = s->lights.power[0] + s->lights.power[1] + s->lights.power[2];
  else
    for (int c = 0; c < 3; c++) pmax = s->lights.power[c] > pmax ? s->lights.power[c] : pmax;
  P->fixed_scale = (float)pm_fixed_scale(pmax * w_max, P->path_cap + diag);
  P->photon_total = (bk_uint)s->lights.photons;
  P->light_count = (bk_uint)s->lights.count;
  /* quanta -> W·voxel -> W·m / (4π V) */
  for (int c = 0; c < 3; c++)
    s->to_radiance[c] = (s->channels == 1 ? s->lights.chroma[c] : 1.0) /
                        ((double)P->fixed_scale * 4.0 * M_PI * h * h);
}

int pm_prepare(const scene_t *scene, const volume_t *vol, pm_setup_t *s, bk_timings_t *timings,
               pm_stats_t *stats, bk_error_t *err) {
  memset(s, 0, sizeof *s);
  s->dims = vol->dims;
  s->voxels = grid_count(&vol->dims);
  const grid_dims_t *d = &s->dims;
  const double h = d->voxel_size;
  if (s->voxels == 0 || !(h > 0.0))
    return bk_fail(err, BK_ERR_INPUT, "%s: march: empty grid %dx%dx%d", scene->path, d->nx, d->ny,
                   d->nz);
  if (!(scene->step > 0.0f) || !isfinite(scene->step))
    return bk_fail(err, BK_ERR_INPUT, "%s: photons.step: expected a positive number of voxels, got %g",
                   scene->path, (double)scene->step);
  if (scene->photon_count < 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: photons.count: expected a count >= 0, got %lld",
                   scene->path, scene->photon_count);

  /* what the volume allows the kernel to skip: part of the octree stage */
  double t0 = bk_now_ms();
  scan_volume(vol, s->voxels, &s->has_refraction, &s->homogeneous, &s->grey);
  double ms_scan = bk_now_ms() - t0;
  t0 = bk_now_ms();
  int rc = ph_prepare(scene, d, (uint64_t)scene->photon_count, scene->seed, &s->lights, err);
  if (rc != BK_OK) return rc;
  s->channels = (s->grey && s->lights.one_colour) ? 1 : 3;
  if (s->channels == 1) ph_make_grey(&s->lights);
  s->seed = scene->seed;
  /* what the march holds per voxel: n/∇n, the pyramid, σt, the counters */
  size_t per_voxel = (s->has_refraction ? 4 * sizeof(float) + 1 : 0) +
                     (s->homogeneous ? 0 : s->channels * sizeof(float)) +
                     s->channels * sizeof(uint64_t) + 3 * sizeof(float);
  rc = grid_check_memory(d, per_voxel, scene->path, err);
  if (rc != BK_OK) return rc;
  double ms_generate = bk_now_ms() - t0;

  /* stage 3: pyramid and the n/∇n field, only where n varies */
  t0 = bk_now_ms();
  bk_grid g = pm_kernel_grid(d);
  if (s->has_refraction) {
    rc = oct_build(d, vol->ior, &s->pyramid, err);
    if (rc != BK_OK) goto error;
    rc = BK_ERR_RUNTIME;
    s->ng = fld_build(d->nx, d->ny, d->nz, d->voxel_size, vol->ior, err);
    if (!s->ng) goto error;
    s->octree_enabled = 1;
  }
  pm_params *P = &s->params;
  memset(P, 0, sizeof *P);
  P->grid = g;
  if (s->homogeneous) {
    for (int c = 0; c < 3; c++) P->sigma_t[c] = (float)((vol->sigma_s[c] + vol->sigma_a[c]) * h);
  } else {
    rc = BK_ERR_RUNTIME;
    s->sigma = bk_calloc(s->voxels, s->channels * sizeof(float), "march: extinction grid", err);
    if (!s->sigma) goto error;
    for (size_t i = 0; i < s->voxels; i++)
      for (int c = 0; c < s->channels; c++)
        s->sigma[s->channels * i + c] =
            (float)((vol->sigma_s[3 * i + c] + vol->sigma_a[3 * i + c]) * h);
  }
  double ms_octree = bk_now_ms() - t0 + ms_scan;

  t0 = bk_now_ms();
  for (int c = 0; c < 3; c++)
    if (!(P->sigma_t[c] >= 0.0f)) {
      rc = bk_fail(err, BK_ERR_INPUT, "%s: medium: extinction must be >= 0, got %g per unit",
                   scene->path, (double)P->sigma_t[c] / h);
      goto error;
    }
  double diag = sqrt((double)d->nx * d->nx + (double)d->ny * d->ny + (double)d->nz * d->nz);
  P->step = scene->step;
  P->path_cap = (float)(PM_MAX_PATH_DIAGONALS * diag);
  P->absorb_fraction = PM_ABSORB_FRACTION;
  P->channels = (bk_uint)s->channels;
  P->has_refraction = (bk_uint)s->has_refraction;
  P->homogeneous = (bk_uint)s->homogeneous;
  P->integrator = scene->integrator == INTEGRATOR_RK4 ? 1u : 0u;
  P->mode = PM_MODE_REFERENCE;
  set_scale(s, 1.0);
  ms_generate += bk_now_ms() - t0;

  if (timings) {
    if (s->has_refraction) {
      const uint64_t *v = s->pyramid.voxels_at_level;
      double tot = (double)s->voxels;
      char note[96];
      int at = snprintf(note, sizeof note, "constant:");
      for (int l = OCT_LEVELS; l >= 1 && at < (int)sizeof note; l--)
        at += snprintf(note + at, sizeof note - at, " %.0f%% in %d^3", 100.0 * v[l] / tot,
                       2 << (2 * (l - 1)));
      bk_timings_add(timings, "octree", ms_octree, "%s", note);
    } else {
      bk_timings_add(timings, "octree", ms_octree, "n constant: one straight DDA per photon");
    }
    bk_timings_add(timings, "photon generation", ms_generate,
                   "%d light(s), in-kernel Hammersley, %s", s->lights.count,
                   s->channels == 1 ? "1 channel (one colour)" : "RGB");
  }
  if (stats) {
    stats->ms_octree = ms_octree;
    stats->ms_generate = ms_generate;
  }
  return BK_OK;
error:
  pm_setup_free(s);
  return rc;
}

void pm_setup_free(pm_setup_t *s) {
  if (!s) return;
  free(s->ng);
  free(s->sigma);
  oct_free(&s->pyramid);
  s->ng = NULL;
  s->sigma = NULL;
}

void pm_disable_octree(pm_setup_t *s) {
  if (s->pyramid.level)
    memset(s->pyramid.level, 0, (size_t)s->pyramid.bx * s->pyramid.by * s->pyramid.bz);
  s->octree_enabled = 0;
}

int pm_derive(const pm_setup_t *base, const scene_t *scene, uint64_t photons, pm_setup_t *out,
              bk_error_t *err) {
  *out = *base;
  out->masks = NULL;
  out->tables = NULL;
  out->params.mode = PM_MODE_REFERENCE;
  int rc = ph_prepare(scene, &base->dims, photons, base->seed, &out->lights, err);
  if (rc != BK_OK) return rc;
  if (out->channels == 1) ph_make_grey(&out->lights);
  set_scale(out, 1.0);
  return BK_OK;
}

void pm_record_origins(pm_setup_t *s, int coarse_shift, uint64_t *masks) {
  pm_params *P = &s->params;
  const int m = (1 << coarse_shift) - 1;
  P->mode = PM_MODE_ORIGINS;
  P->coarse_shift = coarse_shift;
  P->cnx = (s->dims.nx + m) >> coarse_shift;
  P->cny = (s->dims.ny + m) >> coarse_shift;
  P->cnz = (s->dims.nz + m) >> coarse_shift;
  s->masks = masks;
}

int pm_sample_tables(pm_setup_t *s, const float *tables, double w_max, bk_error_t *err) {
  pm_params *P = &s->params;
  /* count bits: the photons, with room for 4 passages per photon on average
   * (curved paths may re-enter a voxel); the weight sum takes the rest, with
   * the same room, in quanta of 2^-24 to 2^-8 */
  int count_bits = 2;
  while (count_bits < 64 && (s->lights.photons >> (count_bits - 2)) != 0) count_bits++;
  int shift = 64 - count_bits;
  /* quanta per unit weight: a power of 2 with N w_max of them below 2^shift */
  double room = ldexp(1.0, shift) / (4.0 * (double)(s->lights.photons ? s->lights.photons : 1) *
                                     (w_max > 1.0 ? w_max : 1.0) * 1.001);
  if (room < 256.0)
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive: %llu photons are too many for the per-voxel photon count and "
                   "weight sums (%d bits); use at most about 4e7 photons, or photons.mode "
                   "\"reference\"",
                   (unsigned long long)s->lights.photons, count_bits);
  P->mode = PM_MODE_TABLES;
  P->count_shift = (bk_uint)shift;
  P->weight_scale = (float)ldexp(1.0, (int)floor(log2(room)) > 24 ? 24 : (int)floor(log2(room)));
  s->tables = tables;
  set_scale(s, w_max);
  return BK_OK;
}

size_t pm_acc_count(const pm_setup_t *s) {
  const pm_params *P = &s->params;
  if (P->mode == PM_MODE_ORIGINS) return (size_t)P->cnx * P->cny * P->cnz * (size_t)s->channels;
  return s->voxels * (size_t)pm_acc_stride((int)P->mode, s->channels);
}

size_t pm_mask_count(const pm_setup_t *s) {
  const pm_params *P = &s->params;
  if (P->mode != PM_MODE_ORIGINS) return 0;
  return (size_t)P->cnx * P->cny * P->cnz * (size_t)s->lights.count;
}

int pm_run_host(const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats, bk_error_t *err) {
  bk_progress_t prog;
  uint64_t n = s->lights.photons;
  bk_progress_begin(&prog, "photon marching", n);
  for (uint64_t i = 0; i < n; i++) {
    pm_result r;
    pm_march_photon(&s->params, s->lights.lights, s->ng, s->pyramid.level, s->sigma, acc,
                    s->masks, s->tables, (bk_uint)i, &r, NULL);
    if (stats) add_result(stats, &r);
    if ((i & 4095) == 4095) bk_progress_update(&prog, i + 1);
  }
  bk_progress_end(&prog);
  return BK_OK;
}

int pm_run_cl(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
              bk_error_t *err) {
  int rc = BK_ERR_RUNTIME;
  cl_int cerr = CL_SUCCESS;
  cl_program prog = NULL;
  cl_kernel kern = NULL;
  cl_mem b_params = NULL, b_lights = NULL, b_ng = NULL, b_pyr = NULL, b_sigma = NULL, b_acc = NULL,
         b_out = NULL, b_dummy = NULL, b_masks = NULL, b_tables = NULL;
  pm_result *res = NULL;
  bk_progress_t progress;
  int progress_on = 0;
  char opts[512], b1[32], b2[32];
  const size_t acc_bytes = pm_acc_count(s) * sizeof(uint64_t);
  const size_t mask_bytes = pm_mask_count(s) * sizeof(uint64_t);
  const int mode = (int)s->params.mode;

  if (!cl->has_int64_atomics)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "OpenCL device %s lacks cl_khr_int64_base_atomics, which the photon march "
                   "needs for its fixed-point sums; choose another device with --device or march "
                   "on the host with --host",
                   cl->device_name);
  if (acc_bytes > cl->max_alloc || (s->ng && fld_padded_count(s->dims.nx, s->dims.ny, s->dims.nz) * 4 * sizeof(float) > cl->max_alloc))
    return bk_fail(err, BK_ERR_RUNTIME,
                   "march: the %dx%dx%d grid needs buffers of %s; %s allows %s per buffer "
                   "(lower grid.resolution or march on the host with --host)",
                   s->dims.nx, s->dims.ny, s->dims.nz,
                   bk_format_bytes((double)(s->ng ? fld_padded_count(s->dims.nx, s->dims.ny, s->dims.nz) * 16 : acc_bytes), b1, sizeof b1),
                   cl->device_name, bk_format_bytes((double)cl->max_alloc, b2, sizeof b2));

  double t0 = bk_now_ms();
  const ph_setup_t *L = &s->lights;
  snprintf(opts, sizeof opts,
           "-DHAS_REFRACTION=%d -DHOMOGENEOUS=%d -DINTEGRATOR=%u -DPM_CHANNELS=%d "
           "-DLIGHT_DIRECTIONAL=%d -DLIGHT_SPOT=%d -DLIGHT_POINT=%d -DPM_MODE=%d",
           s->has_refraction, s->homogeneous, s->params.integrator, s->channels,
           L->has_type[PH_DIRECTIONAL], L->has_type[PH_SPOT], L->has_type[PH_POINT], mode);
  if (clh_build(cl, "march.cl", opts, &prog, err) != BK_OK) goto error;
  kern = clCreateKernel(prog, "pm_march", &cerr);
  CLH_CHECK(cerr, err, error);
  /* PM_LOCAL_SIZE, or the largest power of 2 the kernel allows below it */
  size_t local = PM_LOCAL_SIZE, kmax = 0;
  if (clGetKernelWorkGroupInfo(kern, cl->device, CL_KERNEL_WORK_GROUP_SIZE, sizeof kmax, &kmax,
                               NULL) == CL_SUCCESS &&
      kmax > 0)
    while (local > kmax) local /= 2;
  if (stats) stats->ms_build += bk_now_ms() - t0;

  /* inputs stay where they are on a CPU device (USE_HOST_PTR); a GPU copies */
  const cl_mem_flags in = CL_MEM_READ_ONLY | (cl->is_cpu ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR);
  int nlights = L->count > 0 ? L->count : 1;
  ph_light none;
  memset(&none, 0, sizeof none);
  b_params = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof(pm_params),
                            (void *)&s->params, &cerr);
  CLH_CHECK(cerr, err, error);
  b_lights = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                            sizeof(ph_light) * nlights, L->count ? (void *)L->lights : &none, &cerr);
  CLH_CHECK(cerr, err, error);
  b_dummy = clCreateBuffer(cl->context, CL_MEM_READ_WRITE, 64, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  if (s->ng) {
    b_ng = clCreateBuffer(cl->context, in,
                          fld_padded_count(s->dims.nx, s->dims.ny, s->dims.nz) * 4 * sizeof(float), s->ng,
                          &cerr);
    CLH_CHECK(cerr, err, error);
    b_pyr = clCreateBuffer(cl->context, in,
                           (size_t)s->pyramid.bx * s->pyramid.by * s->pyramid.bz, s->pyramid.level,
                           &cerr);
    CLH_CHECK(cerr, err, error);
  }
  if (s->sigma) {
    b_sigma = clCreateBuffer(cl->context, in, s->voxels * s->channels * sizeof(float), s->sigma,
                             &cerr);
    CLH_CHECK(cerr, err, error);
  }
  b_acc = clCreateBuffer(cl->context,
                         CL_MEM_READ_WRITE | (cl->is_cpu ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR),
                         acc_bytes, acc, &cerr);
  CLH_CHECK(cerr, err, error);
  b_out = clCreateBuffer(cl->context, CL_MEM_WRITE_ONLY, PM_CHUNK * sizeof(pm_result), NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  if (mode == PM_MODE_ORIGINS) {
    if (!s->masks) {
      bk_fail(err, BK_ERR_RUNTIME, "march: pilot march without origin masks");
      goto error;
    }
    b_masks = clCreateBuffer(cl->context,
                             CL_MEM_READ_WRITE |
                                 (cl->is_cpu ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR),
                             mask_bytes, s->masks, &cerr);
    CLH_CHECK(cerr, err, error);
  }
  if (mode == PM_MODE_TABLES) {
    if (!s->tables) {
      bk_fail(err, BK_ERR_RUNTIME, "march: weighted march without PDF tables");
      goto error;
    }
    b_tables = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                              (size_t)nlights * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y) *
                                  sizeof(float),
                              (void *)s->tables, &cerr);
    CLH_CHECK(cerr, err, error);
  }
  res = bk_calloc(PM_CHUNK, sizeof(pm_result), "march: photon results", err);
  if (!res) goto error;

  cl_mem args[] = {b_params, b_lights, b_ng ? b_ng : b_dummy, b_pyr ? b_pyr : b_dummy,
                   b_sigma ? b_sigma : b_dummy, b_acc};
  for (cl_uint a = 0; a < 6; a++)
    CLH_CHECK(clSetKernelArg(kern, a, sizeof(cl_mem), &args[a]), err, error);
  CLH_CHECK(clSetKernelArg(kern, 8, sizeof(cl_mem), &b_out), err, error);
  cl_mem b9 = b_masks ? b_masks : b_dummy, b10 = b_tables ? b_tables : b_dummy;
  CLH_CHECK(clSetKernelArg(kern, 9, sizeof(cl_mem), &b9), err, error);
  CLH_CHECK(clSetKernelArg(kern, 10, sizeof(cl_mem), &b10), err, error);

  uint64_t total = L->photons;
  bk_progress_begin(&progress, "photon marching", total);
  progress_on = 1;
  for (uint64_t first = 0; first < total; first += PM_CHUNK) {
    cl_uint f = (cl_uint)first;
    cl_uint count = (cl_uint)(total - first < PM_CHUNK ? total - first : PM_CHUNK);
    /* a fixed work-group size: the global size rounded up to it (the kernel
     * skips the excess), so that every photon count runs the same compiled
     * work-group function (PoCL compiles one per local size on first use,
     * half a second) */
    size_t global = (count + local - 1) / local * local;
    CLH_CHECK(clSetKernelArg(kern, 6, sizeof f, &f), err, error);
    CLH_CHECK(clSetKernelArg(kern, 7, sizeof count, &count), err, error);
    CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, kern, 1, NULL, &global, &local, 0, NULL, NULL),
              err, error);
    CLH_CHECK(clEnqueueReadBuffer(cl->queue, b_out, CL_TRUE, 0, count * sizeof(pm_result), res, 0,
                                  NULL, NULL),
              err, error);
    if (stats)
      for (cl_uint i = 0; i < count; i++) add_result(stats, &res[i]);
    bk_progress_update(&progress, first + count);
  }
  if (cl->is_cpu) {
    /* make the host copy current (a no-op copy on PoCL) */
    void *p = clEnqueueMapBuffer(cl->queue, b_acc, CL_TRUE, CL_MAP_READ, 0, acc_bytes, 0, NULL,
                                 NULL, &cerr);
    CLH_CHECK(cerr, err, error);
    CLH_CHECK(clEnqueueUnmapMemObject(cl->queue, b_acc, p, 0, NULL, NULL), err, error);
    if (b_masks) {
      p = clEnqueueMapBuffer(cl->queue, b_masks, CL_TRUE, CL_MAP_READ, 0, mask_bytes, 0, NULL,
                             NULL, &cerr);
      CLH_CHECK(cerr, err, error);
      CLH_CHECK(clEnqueueUnmapMemObject(cl->queue, b_masks, p, 0, NULL, NULL), err, error);
    }
  } else {
    CLH_CHECK(clEnqueueReadBuffer(cl->queue, b_acc, CL_TRUE, 0, acc_bytes, acc, 0, NULL, NULL),
              err, error);
    if (b_masks)
      CLH_CHECK(clEnqueueReadBuffer(cl->queue, b_masks, CL_TRUE, 0, mask_bytes, s->masks, 0, NULL,
                                    NULL),
                err, error);
  }
  CLH_CHECK(clFinish(cl->queue), err, error);
  rc = BK_OK;
error:
  if (progress_on) bk_progress_end(&progress);
  free(res);
  if (kern) clReleaseKernel(kern);
  if (prog) clReleaseProgram(prog);
  cl_mem all[] = {b_params, b_lights, b_ng, b_pyr, b_sigma, b_acc, b_out, b_dummy, b_masks, b_tables};
  for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
    if (all[i]) clReleaseMemObject(all[i]);
  return rc;
}

/* --- voxel loops on every core ------------------------------------------- */

#define PM_MAX_THREADS 64

typedef struct pm_range_job {
  void (*fn)(void *ctx, size_t lo, size_t hi);
  void *ctx;
  size_t lo, hi;
} pm_range_job_t;

static void *pm_range_run(void *arg) {
  pm_range_job_t *j = arg;
  j->fn(j->ctx, j->lo, j->hi);
  return NULL;
}

void pm_parallel(size_t n, size_t grain, void (*fn)(void *ctx, size_t lo, size_t hi),
                 void *ctx) {
  long cpus = sysconf(_SC_NPROCESSORS_ONLN);
  int threads = cpus < 1 ? 1 : cpus > PM_MAX_THREADS ? PM_MAX_THREADS : (int)cpus;
  if (grain < 1) grain = 1;
  if ((size_t)threads > n / grain) threads = n / grain > 0 ? (int)(n / grain) : 1;
  pm_range_job_t jobs[PM_MAX_THREADS];
  pthread_t tid[PM_MAX_THREADS];
  int started = 0;
  for (int t = 0; t < threads; t++) {
    jobs[t].fn = fn;
    jobs[t].ctx = ctx;
    jobs[t].lo = n * (size_t)t / (size_t)threads;
    jobs[t].hi = n * (size_t)(t + 1) / (size_t)threads;
  }
  /* a thread that cannot start leaves its range to this one */
  for (int t = 1; t < threads; t++) {
    if (pthread_create(&tid[t], NULL, pm_range_run, &jobs[t]) != 0) break;
    started = t;
  }
  pm_range_run(&jobs[0]);
  for (int t = 1; t <= started; t++) pthread_join(tid[t], NULL);
  for (int t = started + 1; t < threads; t++) pm_range_run(&jobs[t]);
}

typedef struct pm_unpack_ctx {
  const pm_setup_t *s;
  const uint64_t *acc;
  float *radiance, *count, *mean_weight;
} pm_unpack_ctx_t;

static void to_radiance_range(void *arg, size_t lo, size_t hi) {
  const pm_unpack_ctx_t *u = arg;
  const int ch = u->s->channels, stride = pm_acc_stride((int)u->s->params.mode, ch);
  const double *k = u->s->to_radiance;
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < 3; c++)
      u->radiance[3 * i + c] = (float)((double)u->acc[stride * i + (ch == 1 ? 0 : c)] * k[c]);
}

void pm_to_radiance(const pm_setup_t *s, const uint64_t *acc, float *radiance) {
  pm_unpack_ctx_t u = {s, acc, radiance, NULL, NULL};
  pm_parallel(s->voxels, PM_GRAIN, to_radiance_range, &u);
}

static void unpack_weights_range(void *arg, size_t lo, size_t hi) {
  const pm_unpack_ctx_t *u = arg;
  const pm_setup_t *s = u->s;
  const int ch = s->channels, stride = pm_acc_stride((int)s->params.mode, ch);
  const unsigned shift = s->params.count_shift;
  const uint64_t low = (1ull << shift) - 1ull;
  const float inv_scale = 1.0f / s->params.weight_scale; /* a power of 2: exact */
  for (size_t i = lo; i < hi; i++) {
    uint64_t q = u->acc[stride * i + ch];
    float n = (float)(q >> shift);
    if (u->count) u->count[i] = n;
    if (u->mean_weight) u->mean_weight[i] = n > 0.0f ? (float)(q & low) * inv_scale / n : 0.0f;
  }
}

void pm_unpack_weights(const pm_setup_t *s, const uint64_t *acc, float *count,
                       float *mean_weight) {
  pm_unpack_ctx_t u = {s, acc, NULL, count, mean_weight};
  pm_parallel(s->voxels, PM_GRAIN, unpack_weights_range, &u);
}

int pm_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol, float *radiance,
            pm_stats_t *stats, bk_timings_t *timings, bk_error_t *err) {
  pm_setup_t s;
  pm_stats_t local;
  uint64_t *acc = NULL;
  if (!stats) stats = &local;
  memset(stats, 0, sizeof *stats);
  int rc = pm_prepare(scene, vol, &s, timings, stats, err);
  if (rc != BK_OK) return rc;
  rc = BK_ERR_RUNTIME;
  acc = bk_calloc(s.voxels, s.channels * sizeof(uint64_t), "march: radiance accumulator", err);
  if (!acc) goto error;
  double t0 = bk_now_ms();
  rc = cl ? pm_run_cl(cl, &s, acc, stats, err) : pm_run_host(&s, acc, stats, err);
  if (rc != BK_OK) goto error;
  pm_to_radiance(&s, acc, radiance);
  stats->ms_march = bk_now_ms() - t0;
  if (timings) {
    double sec = stats->ms_march > 0.0 ? stats->ms_march / 1000.0 : 1e-9;
    /* Euler-equivalent: path / Δs per second, what stepping everywhere needs */
    bk_timings_add(timings, "photon marching", stats->ms_march,
                   "%.1f M photon-steps/s (%.0f M Euler-equivalent), %.0f M voxels/s%s",
                   stats->steps / sec * 1e-6, stats->path_voxels / scene->step / sec * 1e-6,
                   stats->voxels / sec * 1e-6, cl ? "" : ", host C");
  }
  bk_log(2,
         "march: %llu photons: %llu missed the grid, %llu left it, %llu absorbed, %llu at the "
         "step limit; %llu steps, %llu voxel crossings",
         (unsigned long long)stats->photons, (unsigned long long)stats->missed_grid,
         (unsigned long long)stats->left_grid, (unsigned long long)stats->absorbed,
         (unsigned long long)stats->step_limit, (unsigned long long)stats->steps,
         (unsigned long long)stats->voxels);
  if (stats->step_limit)
    bk_log(1, "march: %llu photon(s) stopped at the step limit (trapped by total internal "
              "reflection?)", (unsigned long long)stats->step_limit);
  rc = BK_OK;
error:
  free(acc);
  pm_setup_free(&s);
  return rc;
}

/* Marches one photon with a path recorder, on a scratch accumulator. */
static int trace(const pm_setup_t *s, const pm_params *P, const ph_light *lights, uint32_t index,
                 float *points, int max_points, int *count, pm_result *res, bk_error_t *err) {
  uint64_t *scratch = bk_calloc(s->voxels, s->channels * sizeof(uint64_t), "march: trace scratch", err);
  if (!scratch) return BK_ERR_RUNTIME;
  pm_path_rec rec = {points, max_points, 0};
  pm_result r;
  pm_march_photon(P, lights, s->ng, s->pyramid.level, s->sigma, scratch, NULL, NULL, index, &r,
                  &rec);
  free(scratch);
  const grid_dims_t *d = &s->dims;
  int stored = rec.count < max_points ? rec.count : max_points;
  for (int i = 0; i < stored; i++)
    for (int a = 0; a < 3; a++) points[3 * i + a] = d->origin[a] + points[3 * i + a] * d->voxel_size;
  *count = rec.count;
  if (res) *res = r;
  return BK_OK;
}

int pm_trace_photon(const pm_setup_t *s, uint32_t index, float *points, int max_points,
                    int *count, pm_result *res, bk_error_t *err) {
  if (index >= s->lights.photons)
    return bk_fail(err, BK_ERR_INPUT, "pm_trace_photon: photon %u of %llu", index,
                   (unsigned long long)s->lights.photons);
  return trace(s, &s->params, s->lights.lights, index, points, max_points, count, res, err);
}

int pm_trace_ray(const pm_setup_t *s, const float origin[3], const float dir[3], float *points,
                 int max_points, int *count, pm_result *res, bk_error_t *err) {
  /* a one-photon directional light whose rectangle is a point */
  pm_params P = s->params;
  ph_light L;
  memset(&L, 0, sizeof L);
  const grid_dims_t *d = &s->dims;
  double l = sqrt((double)dir[0] * dir[0] + (double)dir[1] * dir[1] + (double)dir[2] * dir[2]);
  if (!(l > 0.0)) return bk_fail(err, BK_ERR_INPUT, "pm_trace_ray: zero direction");
  L.type = PH_DIRECTIONAL;
  L.px = (origin[0] - d->origin[0]) / d->voxel_size;
  L.py = (origin[1] - d->origin[1]) / d->voxel_size;
  L.pz = (origin[2] - d->origin[2]) / d->voxel_size;
  L.dx = (float)(dir[0] / l), L.dy = (float)(dir[1] / l), L.dz = (float)(dir[2] / l);
  L.power[0] = L.power[1] = L.power[2] = 1.0f;
  L.count = 1;
  P.light_count = 1;
  P.photon_total = 1;
  return trace(s, &P, &L, 0, points, max_points, count, res, err);
}

uint64_t pm_deposit_repeat_host(float value, uint64_t n) {
  volatile uint64_t acc = 0; /* volatile: the loop must really add n times */
  uint64_t a;
  for (uint64_t i = 0; i < n; i++) {
    a = acc;
    pm_deposit(&a, value);
    acc = a;
  }
  return acc;
}

int pm_deposit_repeat_cl(clh_context_t *cl, float value, uint32_t items, uint32_t per_item,
                         uint64_t *sum, bk_error_t *err) {
  int rc = BK_ERR_RUNTIME;
  cl_int cerr = CL_SUCCESS;
  cl_program prog = NULL;
  cl_kernel kern = NULL;
  cl_mem b = NULL;
  cl_ulong zero = 0;
  if (!cl->has_int64_atomics)
    return bk_fail(err, BK_ERR_RUNTIME, "OpenCL device %s lacks cl_khr_int64_base_atomics",
                   cl->device_name);
  if (clh_build(cl, "march.cl", "", &prog, err) != BK_OK) goto error;
  kern = clCreateKernel(prog, "pm_test_deposit", &cerr);
  CLH_CHECK(cerr, err, error);
  b = clCreateBuffer(cl->context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, sizeof zero, &zero, &cerr);
  CLH_CHECK(cerr, err, error);
  CLH_CHECK(clSetKernelArg(kern, 0, sizeof b, &b), err, error);
  CLH_CHECK(clSetKernelArg(kern, 1, sizeof value, &value), err, error);
  CLH_CHECK(clSetKernelArg(kern, 2, sizeof per_item, &per_item), err, error);
  size_t global = items;
  CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, kern, 1, NULL, &global, NULL, 0, NULL, NULL), err,
            error);
  CLH_CHECK(clEnqueueReadBuffer(cl->queue, b, CL_TRUE, 0, sizeof zero, &zero, 0, NULL, NULL), err,
            error);
  *sum = zero;
  rc = BK_OK;
error:
  if (b) clReleaseMemObject(b);
  if (kern) clReleaseKernel(kern);
  if (prog) clReleaseProgram(prog);
  return rc;
}
