/* march_cl.c: the photon march on an OpenCL device (see march.h): the
 * kernel specialised for the scene, its buffers, launches in chunks of
 * PM_CHUNK photons with progress between them, and the sums read back. */
#include "march.h"

#include <stdlib.h>
#include <string.h>

#include "clcopy.h"
#include "field.h"

/* The kernel and the buffers of one march. */
typedef struct pm_cl_run {
  cl_program prog;
  cl_kernel kern;
  size_t local;
  cl_mem params, lights, ng, pyr, sigma_t, acc, out, dummy, masks, tables;
  cl_mem ms_params, sigma_s, g, tally; /* multiple scattering (march_ms.cl) */
  size_t acc_bytes, mask_bytes;
  pm_result *res;
  ms_tally *tallies;
} pm_cl_run_t;

static size_t field_bytes(const pm_setup_t *s) {
  return fld_floats(s->dims.nx, s->dims.ny, s->dims.nz, s->ng, s->params.dispersion ? 3 : 1) *
         sizeof(float);
}

/* What the device must offer: 64-bit atomics, buffers as large as the grid. */
static int check_device(clh_context_t *cl, const pm_setup_t *s, size_t acc_bytes, bk_error_t *err) {
  char b1[32], b2[32];
  if (!cl->has_int64_atomics)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "OpenCL device %s lacks cl_khr_int64_base_atomics, which the photon march "
                   "needs for its fixed-point sums; choose another device with --device or march "
                   "on the host with --host",
                   cl->device_name);
  size_t largest = s->ng && field_bytes(s) > acc_bytes ? field_bytes(s) : acc_bytes;
  if (largest > cl->max_alloc)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "march: the %dx%dx%d grid needs buffers of %s; %s allows %s per buffer "
                   "(lower grid.resolution or march on the host with --host)",
                   s->dims.nx, s->dims.ny, s->dims.nz, bk_format_bytes((double)largest, b1, sizeof b1),
                   cl->device_name, bk_format_bytes((double)cl->max_alloc, b2, sizeof b2));
  return BK_OK;
}

/* The kernel specialised by -D flags for what the scene contains, and the
 * work-group size: PM_LOCAL_SIZE, or the largest power of 2 below it that
 * the kernel allows. */
static int build_kernel(clh_context_t *cl, const pm_setup_t *s, pm_cl_run_t *r, bk_error_t *err) {
  char opts[640], lights[256], ms[128];
  cl_int cerr = CL_SUCCESS;
  const int scatter = s->ms.params.max_bounces > 0;
  ph_kernel_defines(&s->lights, lights, sizeof lights);
  ms_kernel_defines(&s->ms, ms, sizeof ms);
  snprintf(opts, sizeof opts,
           "-DHAS_REFRACTION=%d -DHOMOGENEOUS=%d -DINTEGRATOR=%u -DPM_CHANNELS=%d "
           "-DPM_SIGMA_STRIDE=%u %s -DPM_MODE=%d%s%s%s%s%s%s%s",
           s->has_refraction, s->homogeneous, s->params.integrator, s->channels,
           s->params.sigma_stride & ~PM_SIGMA_CODED_FLAG, lights,
           (int)s->params.mode, scatter ? " " : "", ms,
           s->params.sigma_stride & PM_SIGMA_CODED_FLAG ? " -DPM_SIGMA_CODED=1" : "",
           s->params.dispersion ? " -DDISPERSION=1" : "",
           s->params.flux && s->params.mode != PM_MODE_ORIGINS ? " -DPM_FLUX=1" : "",
           s->params.camera && s->params.flux && s->params.mode != PM_MODE_ORIGINS
               ? " -DPM_CAMERA=1"
               : "",
           s->params.lattice ? " -DPM_LATTICE=1" : "");
  if (clh_build(cl, scatter ? "march_ms.cl" : "march.cl", opts, &r->prog, err) != BK_OK)
    return BK_ERR_RUNTIME;
  r->kern = clCreateKernel(r->prog, scatter ? "pm_march_ms" : "pm_march", &cerr);
  CLH_CHECK(cerr, err, error);
  size_t kmax = 0;
  r->local = PM_LOCAL_SIZE;
  if (clGetKernelWorkGroupInfo(r->kern, cl->device, CL_KERNEL_WORK_GROUP_SIZE, sizeof kmax, &kmax,
                               NULL) == CL_SUCCESS &&
      kmax > 0)
    while (r->local > kmax) r->local /= 2;
  return BK_OK;
error:
  return BK_ERR_RUNTIME;
}

static cl_mem make_buffer(clh_context_t *cl, cl_mem_flags flags, size_t bytes, const void *data,
                          bk_error_t *err) {
  cl_int cerr = CL_SUCCESS;
  cl_mem b = clCreateBuffer(cl->context, flags, bytes, (void *)data, &cerr);
  CLH_CHECK(cerr, err, error);
  return b;
error:
  return NULL;
}

/* A grid-sized buffer (flags: read-only input, or read-write sums): the
 * host's memory itself on a CPU device; on a GPU a copy written through
 * clcopy.h's pinned stages, sums as a fill when they start at zero.
 * (While the sums were made with CL_MEM_COPY_HOST_PTR, a 1024^3 bake on
 * NVIDIA's driver peaked 8 GiB higher, the sums' size: docs/gpu.md.) */
static cl_mem make_grid_buffer(clh_context_t *cl, cl_mem_flags flags, size_t bytes,
                               const void *data, bk_error_t *err) {
  if (cl->is_cpu) return make_buffer(cl, flags | CL_MEM_USE_HOST_PTR, bytes, data, err);
  cl_mem b = make_buffer(cl, flags, bytes, NULL, err);
  if (b && ((flags & CL_MEM_READ_ONLY) ? clc_write(cl, b, bytes, data, err)
                                        : clc_upload(cl, b, bytes, data, err)) != BK_OK) {
    clReleaseMemObject(b);
    return NULL;
  }
  return b;
}

/* Inputs and outputs on the device (make_grid_buffer for the grid-sized
 * ones). Optional inputs the scene does not use get a small dummy buffer. */
static int make_buffers(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_cl_run_t *r,
                        bk_error_t *err) {
  const cl_mem_flags in = CL_MEM_READ_ONLY, sums = CL_MEM_READ_WRITE;
  const cl_mem_flags copy = CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR;
  const ph_setup_t *L = &s->lights;
  /* room for every light: batches may change the lights (pm_run_cl_batches) */
  size_t nlights = SCENE_MAX_LIGHTS;
  ph_light all[SCENE_MAX_LIGHTS];
  memset(all, 0, sizeof all);
  memcpy(all, L->lights, sizeof(ph_light) * (size_t)L->count);
  /* the volume's σ, read in place on a CPU device: σt and σs, or the one
   * coded buffer of both */
  const size_t sigma_bytes = s->sigma_floats * sizeof(float);
  const size_t pyr_bytes = oct_bytes(&s->pyramid);
  const int coded = (s->params.sigma_stride & PM_SIGMA_CODED_FLAG) != 0;
  if (!(r->params = make_buffer(cl, copy, sizeof(pm_params), &s->params, err)) ||
      !(r->lights = make_buffer(cl, copy, sizeof(ph_light) * nlights, all, err)) ||
      !(r->dummy = make_buffer(cl, CL_MEM_READ_WRITE, 64, NULL, err)) ||
      (s->ng && !(r->ng = make_grid_buffer(cl, in, field_bytes(s), s->ng, err))) ||
      (s->ng && !(r->pyr = make_grid_buffer(cl, in, pyr_bytes, s->pyramid.level, err))) ||
      ((!s->homogeneous || (coded && s->ms.sigma_grid)) &&
       !(r->sigma_t = make_grid_buffer(cl, in, sigma_bytes, s->sigma_t, err))) ||
      !(r->acc = make_grid_buffer(cl, sums, r->acc_bytes, acc, err)) ||
      !(r->out = make_buffer(cl, CL_MEM_WRITE_ONLY, PM_CHUNK * sizeof(pm_result), NULL, err)))
    return BK_ERR_RUNTIME;
  if (s->ms.params.max_bounces &&
      (!(r->ms_params = make_buffer(cl, copy, sizeof(ms_params), &s->ms.params, err)) ||
       (s->ms.g_grid &&
        !(r->g = make_grid_buffer(cl, in, s->voxels * sizeof(float), s->g, err))) ||
       (s->ms.sigma_grid && !coded &&
        !(r->sigma_s = make_grid_buffer(cl, in, sigma_bytes, s->sigma_s, err))) ||
       !(r->tally = make_buffer(cl, CL_MEM_WRITE_ONLY, PM_CHUNK * sizeof(ms_tally), NULL, err))))
    return BK_ERR_RUNTIME;
  if (s->params.mode == PM_MODE_ORIGINS) {
    if (!s->masks) return bk_fail(err, BK_ERR_RUNTIME, "march: origin recorder without masks");
    if (!(r->masks = make_grid_buffer(cl, sums, r->mask_bytes, s->masks, err)))
      return BK_ERR_RUNTIME;
  }
  if (s->params.mode == PM_MODE_TABLES) {
    if (!s->tables) return bk_fail(err, BK_ERR_RUNTIME, "march: sampling tables missing");
    /* one table per light of this march (batches keep the lights' number) */
    size_t bytes = (size_t)L->count * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y) * sizeof(float);
    if (!(r->tables = make_buffer(cl, copy, bytes, s->tables, err))) return BK_ERR_RUNTIME;
  }
  return BK_OK;
}

/* Arguments of pm_march (kernels/march.cl) but the photon range (6, 7). */
static int set_args(pm_cl_run_t *r, bk_error_t *err) {
  cl_mem a[11] = {r->params, r->lights, r->ng ? r->ng : r->dummy, r->pyr ? r->pyr : r->dummy,
                  r->sigma_t ? r->sigma_t : r->dummy, r->acc, NULL, NULL, r->out,
                  r->masks ? r->masks : r->dummy, r->tables ? r->tables : r->dummy};
  for (cl_uint i = 0; i < 11; i++)
    if (a[i]) CLH_CHECK(clSetKernelArg(r->kern, i, sizeof(cl_mem), &a[i]), err, error);
  if (!r->tally) return BK_OK;
  cl_mem m[4] = {r->ms_params, r->sigma_s   ? r->sigma_s
                                 : r->sigma_t ? r->sigma_t /* coded: one buffer */
                                              : r->dummy, r->g ? r->g : r->dummy,
                  r->tally}; /* march_ms.cl */
  for (cl_uint i = 0; i < 4; i++)
    CLH_CHECK(clSetKernelArg(r->kern, 11 + i, sizeof(cl_mem), &m[i]), err, error);
  return BK_OK;
error:
  return BK_ERR_RUNTIME;
}

/* Host copies of a chunk's per-photon results (and energy tallies when
 * photons scatter more than once). */
static int alloc_results(const pm_setup_t *s, pm_cl_run_t *r, bk_error_t *err) {
  r->res = bk_calloc(PM_CHUNK, sizeof(pm_result), "march: photon results", err);
  if (r->res && s->ms.params.max_bounces)
    r->tallies = bk_calloc(PM_CHUNK, sizeof(ms_tally), "march: photon energy tallies", err);
  return !r->res || (s->ms.params.max_bounces && !r->tallies) ? BK_ERR_RUNTIME : BK_OK;
}

/* Photons [s->first, s->last), PM_CHUNK at a time, counting outcomes into stats. */
static int launch(clh_context_t *cl, const pm_setup_t *s, pm_cl_run_t *r, pm_stats_t *stats,
                  int quiet, bk_error_t *err) {
  bk_progress_t progress;
  const uint64_t total = s->last;
  int rc = BK_ERR_RUNTIME;
  bk_progress_begin(&progress, "photon marching", s->last - s->first);
  for (uint64_t first = s->first; first < total; first += PM_CHUNK) {
  if (quiet) progress.enabled = 0; /* batches show their own progress */
    cl_uint f = (cl_uint)first;
    cl_uint count = (cl_uint)(total - first < PM_CHUNK ? total - first : PM_CHUNK);
    /* a fixed work-group size: the global size rounded up to it (the kernel
     * skips the excess), so that every photon count runs the same compiled
     * work-group function (PoCL compiles one per local size on first use,
     * half a second) */
    size_t global = (count + r->local - 1) / r->local * r->local;
    CLH_CHECK(clSetKernelArg(r->kern, 6, sizeof f, &f), err, error);
    CLH_CHECK(clSetKernelArg(r->kern, 7, sizeof count, &count), err, error);
    CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, r->kern, 1, NULL, &global, &r->local, 0, NULL, NULL),
              err, error);
    CLH_CHECK(clEnqueueReadBuffer(cl->queue, r->out, CL_TRUE, 0, count * sizeof(pm_result), r->res,
                                  0, NULL, NULL),
              err, error);
    if (r->tally)
      CLH_CHECK(clEnqueueReadBuffer(cl->queue, r->tally, CL_TRUE, 0, count * sizeof(ms_tally),
                                    r->tallies, 0, NULL, NULL),
                err, error);
    for (cl_uint i = 0; i < count; i++) {
      if (stats) pm_stats_add(stats, &r->res[i]);
      if (stats && r->tally) pm_stats_add_tally(stats, &r->tallies[i]);
      pm_count_cell_work(s, first + i, &r->res[i]);
    }
    bk_progress_update(&progress, first + count - s->first);
  }
  rc = BK_OK;
error:
  bk_progress_end(&progress);
  return rc;
}

/* Makes the host's copy of buffer b (bytes, at host) current: a map on a
 * CPU device, where the buffer is the host memory; a read on a GPU. */
static int read_back(clh_context_t *cl, cl_mem b, size_t bytes, void *host, bk_error_t *err) {
  cl_int cerr = CL_SUCCESS;
  if (!cl->is_cpu) return clc_read(cl, b, bytes, host, err);
  void *p = clEnqueueMapBuffer(cl->queue, b, CL_TRUE, CL_MAP_READ, 0, bytes, 0, NULL, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  CLH_CHECK(clEnqueueUnmapMemObject(cl->queue, b, p, 0, NULL, NULL), err, error);
  return BK_OK;
error:
  return BK_ERR_RUNTIME;
}

static void release(pm_cl_run_t *r) {
  free(r->res);
  free(r->tallies);
  if (r->kern) clReleaseKernel(r->kern);
  if (r->prog) clReleaseProgram(r->prog);
  cl_mem all[] = {r->params, r->lights, r->ng,     r->pyr,       r->sigma_t, r->acc,
                  r->out,    r->dummy,  r->masks,  r->tables,    r->ms_params, r->sigma_s,
                  r->g,      r->tally};
  for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
    if (all[i]) clReleaseMemObject(all[i]);
}

int pm_run_cl(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
              bk_error_t *err) {
  pm_cl_run_t r;
  memset(&r, 0, sizeof r);
  r.acc_bytes = pm_acc_count(s) * sizeof(uint64_t);
  if (stats) stats->bounces = (int)s->ms.params.max_bounces;
  r.mask_bytes = pm_mask_count(s) * sizeof(uint64_t);
  int rc = check_device(cl, s, r.acc_bytes, err);
  if (rc != BK_OK) return rc;
  double t0 = bk_now_ms();
  if ((rc = build_kernel(cl, s, &r, err))) goto done;
  if (stats) stats->ms_build += bk_now_ms() - t0;
  rc = BK_ERR_RUNTIME;
  if (alloc_results(s, &r, err) || make_buffers(cl, s, acc, &r, err) || set_args(&r, err) ||
      launch(cl, s, &r, stats, 0, err) || read_back(cl, r.acc, r.acc_bytes, acc, err) ||
      (r.masks && read_back(cl, r.masks, r.mask_bytes, s->masks, err)))
    goto done;
  CLH_CHECK(clFinish(cl->queue), err, done);
  rc = BK_OK;
done:
  release(&r);
  return rc;
}

/* The host's view of acc around a batch callback: a map on a CPU device.
 * A GPU's copy is read after each batch (before the first it equals the
 * host's, made from it) and zeroed on the device where the callback asks;
 * a callback that stops may change the host's copy, which is then the
 * result. */
static int call_next(clh_context_t *cl, pm_cl_run_t *r, uint64_t *acc, int done, pm_setup_t *run,
                     pm_batch_fn next, void *ctx, int *go, bk_error_t *err) {
  cl_int cerr = CL_SUCCESS;
  void *p = NULL;
  if (cl->is_cpu) {
    p = clEnqueueMapBuffer(cl->queue, r->acc, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, r->acc_bytes,
                           0, NULL, NULL, &cerr);
    CLH_CHECK(cerr, err, error);
  } else if (done > 0 && clc_read(cl, r->acc, r->acc_bytes, acc, err)) {
    return BK_ERR_RUNTIME;
  }
  *go = next(ctx, done, acc, run, err);
  if (cl->is_cpu) {
    if (*go == PM_BATCH_GO_ZERO) memset(p, 0, r->acc_bytes);
    CLH_CHECK(clEnqueueUnmapMemObject(cl->queue, r->acc, p, 0, NULL, NULL), err, error);
  } else if (*go == PM_BATCH_GO_ZERO) {
    const cl_ulong zero = 0;
    CLH_CHECK(clEnqueueFillBuffer(cl->queue, r->acc, &zero, sizeof zero, 0, r->acc_bytes, 0, NULL,
                                  NULL),
              err, error);
  }
  return *go < 0 ? err->code : BK_OK;
error:
  return BK_ERR_RUNTIME;
}

/* A batch's lights and parameters to the device. */
static int load_batch(clh_context_t *cl, pm_cl_run_t *r, const pm_setup_t *run, bk_error_t *err) {
  size_t n = (size_t)run->lights.count;
  if (n > SCENE_MAX_LIGHTS) return bk_fail(err, BK_ERR_RUNTIME, "march: batch with %zu lights", n);
  CLH_CHECK(clEnqueueWriteBuffer(cl->queue, r->params, CL_TRUE, 0, sizeof(pm_params), &run->params,
                                 0, NULL, NULL),
            err, error);
  if (n)
    CLH_CHECK(clEnqueueWriteBuffer(cl->queue, r->lights, CL_TRUE, 0, n * sizeof(ph_light),
                                   run->lights.lights, 0, NULL, NULL),
              err, error);
  if (r->tables && n) /* sampling tables: a batch may bring new ones */
    CLH_CHECK(clEnqueueWriteBuffer(cl->queue, r->tables, CL_TRUE, 0,
                                   n * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y) * sizeof(float),
                                   run->tables, 0, NULL, NULL),
              err, error);
  return BK_OK;
error:
  return BK_ERR_RUNTIME;
}

int pm_run_cl_batches(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
                      pm_batch_fn next, void *ctx, bk_error_t *err) {
  pm_cl_run_t r;
  memset(&r, 0, sizeof r);
  r.acc_bytes = pm_acc_count(s) * sizeof(uint64_t);
  if (stats) stats->bounces = (int)s->ms.params.max_bounces;
  int rc = check_device(cl, s, r.acc_bytes, err);
  if (rc != BK_OK) return rc;
  if (s->params.mode == PM_MODE_ORIGINS)
    return bk_fail(err, BK_ERR_RUNTIME, "march: batches are not for the origin recorder");
  double t0 = bk_now_ms();
  if ((rc = build_kernel(cl, s, &r, err))) goto done;
  if (stats) stats->ms_build += bk_now_ms() - t0;
  rc = BK_ERR_RUNTIME;
  if (alloc_results(s, &r, err) || make_buffers(cl, s, acc, &r, err) || set_args(&r, err))
    goto done;
  pm_setup_t run = *s;
  for (int done = 0;; done++) {
    int go = 0;
    if (call_next(cl, &r, acc, done, &run, next, ctx, &go, err)) goto done;
    if (!go) break;
    if (load_batch(cl, &r, &run, err) || launch(cl, &run, &r, stats, 1, err)) goto done;
  }
  CLH_CHECK(clFinish(cl->queue), err, done);
  rc = BK_OK;
done:
  release(&r);
  return rc;
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
