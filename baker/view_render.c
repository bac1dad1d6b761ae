/* view_render.c: one image of the volume, on OpenCL or on the host
 * (view_render.h): the camera in the volume's voxel space, the kernel built
 * for the volume's options, the fields uploaded, rows marched in bands. */
#define _POSIX_C_SOURCE 200809L
#include "view_render.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "field.h"
#include "kernels/view_march.h"

#define VIEW_BANDS 16            /* kernel launches per image when showing progress */

int view_gpu_init(view_gpu_t *g, const char *device, bk_error_t *err) {
  if (g->ready) return BK_OK;
  if (device && !strcmp(device, "host")) {
    g->host = g->ready = 1;
    return BK_OK;
  }
  int rc = clh_init(&g->cl, device, err);
  if (rc) return rc;
  g->ready = 1;
  bk_log(2, "view: OpenCL device %s (%s)", g->cl.device_name, g->cl.platform_name);
  return BK_OK;
}

void view_gpu_release(view_gpu_t *g) {
  if (g->kernel) clReleaseKernel(g->kernel);
  if (g->program) clReleaseProgram(g->program);
  if (g->ready && !g->host) clh_release(&g->cl);
  memset(g, 0, sizeof *g);
}

static bk_v3 v3_from_linear(const double m[3][4], const double d[3]) {
  double o[3];
  for (int r = 0; r < 3; r++) o[r] = m[r][0] * d[0] + m[r][1] * d[1] + m[r][2] * d[2];
  return v3((float)o[0], (float)o[1], (float)o[2]);
}

/* `radiance_camera` serves this camera: it stands where the bake's did (to
 * a thousandth of a voxel; the metadata holds the float the scene gave). */
static int view_camera_matches(const view_volume_t *v, const view_cam_t *c) {
  if (!v->camera_phase) return 0;
  double d2 = 0.0;
  for (int k = 0; k < 3; k++) {
    const double d = (double)c->pos[k] - v->camera_world[k];
    d2 += d * d;
  }
  const double tol = 1e-3 * v->voxel_size;
  return d2 <= tol * tol;
}

/* Counts the frames by where their phase came from; says it the first time
 * a camera stands elsewhere than the bake's (view_report sums up). */
static void count_camera_phase(const view_volume_t *v, const view_params_t *p,
                               view_totals_t *tot) {
  if (!v->camera_phase) return;
  if (p->camera_phase) {
    tot->camera_frames++;
  } else if (tot->lobe_frames++ == 0) {
    bk_log(1, "view: radiance_camera was baked for a camera at [%g, %g, %g], not this one: "
              "the phase towards the camera comes from the flux's lobes",
           v->camera_world[0], v->camera_world[1], v->camera_world[2]);
  }
}

static void setup_params(const view_volume_t *v, const view_cam_t *c, const float bg[3],
                         float step, view_params_t *p) {
  memset(p, 0, sizeof *p);
  double pos[3] = {c->pos[0], c->pos[1], c->pos[2]}, f[3], r[3], u[3],
         up[3] = {c->up[0], c->up[1], c->up[2]};
  for (int k = 0; k < 3; k++) f[k] = (double)c->look[k] - c->pos[k];
  view_normalize3d(f);
  view_cross3d(f, up, r);
  view_normalize3d(r);
  view_cross3d(r, f, u);
  double th = tan(0.5 * c->fov * VIEW_PI / 180.0), aspect = (double)c->width / c->height;
  double rs[3], us[3], pu[3];
  for (int k = 0; k < 3; k++) rs[k] = r[k] * th * aspect, us[k] = u[k] * th;
  view_affine_apply(v->w2i, pos, pu);
  p->cam_pos = v3((float)(pu[0] + 0.5), (float)(pu[1] + 0.5), (float)(pu[2] + 0.5));
  p->cam_forward = v3_from_linear(v->w2i, f);
  p->cam_right = v3_from_linear(v->w2i, rs);
  p->cam_up = v3_from_linear(v->w2i, us);
  p->background = v3(bg[0], bg[1], bg[2]);
  p->sigma_t = v3(v->st_const[0], v->st_const[1], v->st_const[2]);
  p->width = c->width;
  p->height = c->height;
  p->nx = v->nx;
  p->ny = v->ny;
  p->nz = v->nz;
  p->step = step;
  p->straight_step = step > 1.0f ? step : 1.0f;
  /* a curved ray may wander (total internal reflection): 8 box diagonals' worth */
  double hmin = step < p->straight_step ? step : p->straight_step;
  double lim = 8.0 * ((double)v->nx + v->ny + v->nz) / hmin + 64.0;
  p->max_steps = lim > 1e9 ? 1000000000 : (int)lim;
  p->camera_phase = view_camera_matches(v, c);
}

/* Bytes of a pyramid's levels; a 16-byte stand-in when it was not built. */
static size_t pyr_bytes(const oct_pyramid_t *p) {
  return p->level ? oct_bytes(p) : 16;
}

static cl_mem make_buffer(view_gpu_t *g, const void *data, size_t bytes, cl_mem_flags flags,
                          const char *what, bk_error_t *err) {
  if (bytes > g->cl.max_alloc) {
    char a[32], b[32];
    bk_fail(err, BK_ERR_RUNTIME, "OpenCL: %s needs %s in one buffer, the device allows %s", what,
            bk_format_bytes((double)bytes, a, sizeof a),
            bk_format_bytes((double)g->cl.max_alloc, b, sizeof b));
    return NULL;
  }
  cl_int rc;
  /* arrays from view_alloc are used in place on a CPU device (no copy); the
   * host keeps them unchanged until the buffer is released */
  cl_mem_flags how = !data ? 0
                     : ((uintptr_t)data % VIEW_ALIGN == 0) ? CL_MEM_USE_HOST_PTR
                                                            : CL_MEM_COPY_HOST_PTR;
  cl_mem m = clCreateBuffer(g->cl.context, flags | how, bytes ? bytes : 16, (void *)data, &rc);
  if (rc != CL_SUCCESS) {
    bk_fail(err, BK_ERR_RUNTIME, "OpenCL: clCreateBuffer for %s (%zu bytes) failed: %s", what,
            bytes, clh_error_name(rc));
    return NULL;
  }
  return m;
}

/* CPU time used by this process so far, all threads (PoCL's included). */
static double cpu_ms(void) {
  struct rusage ru;
  if (getrusage(RUSAGE_SELF, &ru) != 0) return 0.0;
  return (ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) * 1e3 +
         (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-3;
}

/* The reference path: the kernel's own code, compiled by the C compiler,
 * one pixel after another. Slow; for tests and for machines without OpenCL. */
static int render_host(const view_volume_t *v, const view_params_t *p, int integrator,
                       float *rgba, view_totals_t *tot) {
  const view_fields f = {v->medium,     v->sigma_t4, v->ng,     v->npyr.level,
                         v->mpyr.level, v->aniso,    v->aniso_s};
  const view_flags fl = {v->refraction,     v->sigma_ch == 1, integrator,
                         v->homogeneous,    v->ior_rb != NULL, v->aniso != NULL,
                         v->medium_floats == 2};
  double t0 = bk_now_ms(), c0 = cpu_ms();
  bk_progress_t prog;
  bk_progress_begin(&prog, "view: marching (host)", (uint64_t)p->height);
  for (int y = 0; y < p->height; y++) {
    for (int x = 0; x < p->width; x++) {
      bk_uint n;
      view_march_pixel(p, f, fl, x, y, rgba + 4 * ((size_t)y * p->width + x), &n);
      tot->ray_steps += n;
      if (v->refraction && n >= (bk_uint)p->max_steps) tot->capped++;
    }
    bk_progress_update(&prog, (uint64_t)y + 1);
  }
  bk_progress_end(&prog);
  tot->pixels += (uint64_t)p->width * p->height;
  tot->march_ms += bk_now_ms() - t0;
  tot->march_cpu_ms += cpu_ms() - c0;
  snprintf(tot->last_options, sizeof tot->last_options, "host C reference path");
  return BK_OK;
}

/* Builds view.cl with this volume's options unless the last image's kernel
 * has them. */
static int build_kernel(view_gpu_t *g, const view_volume_t *v, int integrator,
                        view_totals_t *tot, bk_error_t *err) {
  int rc;
  char opts[256];
  snprintf(opts, sizeof opts,
           "-DHAS_REFRACTION=%d -DINTEGRATOR=%d -DGREY=%d -DHOMOGENEOUS=%d%s%s%s", v->refraction,
           integrator, v->sigma_ch == 1, v->homogeneous, v->ior_rb ? " -DDISPERSION=1" : "",
           v->aniso ? " -DANISO=1" : "", v->medium_floats == 2 ? " -DGREY_LIGHT=1" : "");
  if (!g->kernel || strcmp(opts, g->options) != 0) {
    if (g->kernel) clReleaseKernel(g->kernel), g->kernel = NULL;
    if (g->program) clReleaseProgram(g->program), g->program = NULL;
    if ((rc = clh_build(&g->cl, "view.cl", opts, &g->program, err))) return rc;
    cl_int krc;
    g->kernel = clCreateKernel(g->program, "view_render", &krc);
    CLH_CHECK(krc, err, error);
    snprintf(g->options, sizeof g->options, "%s", opts);
    bk_log(2, "view: kernel view.cl built with %s", opts);
  }
  snprintf(tot->last_options, sizeof tot->last_options, "%s", opts);
  return BK_OK;
error:
  return err->code;
}

/* The fields and the image as buffers b[0..8], set as the kernel's
 * arguments after the parameters. */
static int upload(view_gpu_t *g, const view_volume_t *v, const view_params_t *p, size_t npix,
                  cl_mem b[9], bk_error_t *err) {
  const size_t aniso_bytes = v->aniso ? fld_padded_count(v->nx, v->ny, v->nz) * 4 * sizeof(float)
                                      : 16;
  const size_t npad = fld_padded_count(v->nx, v->ny, v->nz);
  const cl_mem_flags ro = CL_MEM_READ_ONLY;
  if (!(b[0] = make_buffer(g, v->medium, npad * (size_t)v->medium_floats * sizeof(float), ro,
                           "medium", err)) ||
      !(b[1] = make_buffer(g, v->sigma_t4, v->sigma_t4 ? npad * 4 * sizeof(float) : 16, ro,
                           "extinction", err)) ||
      !(b[2] = make_buffer(g, v->ng,
                           v->ng ? fld_floats(v->nx, v->ny, v->nz, v->ng, v->ior_rb ? 3 : 1) *
                                       sizeof(float)
                                 : 16,
                           ro, "ior", err)) ||
      !(b[3] = make_buffer(g, v->npyr.level, pyr_bytes(&v->npyr), ro, "constant blocks of n", err)) ||
      !(b[4] = make_buffer(g, v->mpyr.level, pyr_bytes(&v->mpyr), ro, "constant blocks", err)) ||
      !(b[5] = make_buffer(g, NULL, npix * 4 * sizeof(float), CL_MEM_WRITE_ONLY, "image", err)) ||
      !(b[6] =
            make_buffer(g, NULL, npix * sizeof(bk_uint), CL_MEM_WRITE_ONLY, "step counts", err)) ||
      !(b[7] = make_buffer(g, v->aniso, aniso_bytes, ro, "phase lobes", err)) ||
      !(b[8] = make_buffer(g, v->aniso_s, aniso_bytes, ro, "phase lobes", err)))
    return err->code ? err->code : BK_ERR_RUNTIME;
  CLH_CHECK(clSetKernelArg(g->kernel, 0, sizeof *p, p), err, error);
  for (int a = 0; a < 9; a++)
    CLH_CHECK(clSetKernelArg(g->kernel, (cl_uint)a + 1, sizeof(cl_mem), &b[a]), err, error);
  CLH_CHECK(clFinish(g->cl.queue), err, error);
  return BK_OK;
error:
  return err->code;
}

/* In bands of rows, so a long render shows progress. */
static int march_bands(view_gpu_t *g, int width, int height, bk_error_t *err) {
  bk_progress_t prog;
  bk_progress_begin(&prog, "view: marching", (uint64_t)height);
  /* one launch unless progress is shown: each launch ends on its slowest
   * work-group while the other cores wait */
  int nbands = prog.enabled ? VIEW_BANDS : 1;
  int band = (height + nbands - 1) / nbands;
  for (int y0 = 0; y0 < height; y0 += band) {
    size_t off[2] = {0, (size_t)y0};
    /* every band the same size (the kernel skips rows past the image), so
     * PoCL compiles one work-group function, not one per band height */
    size_t gsz[2] = {(size_t)width, (size_t)band};
    CLH_CHECK(clEnqueueNDRangeKernel(g->cl.queue, g->kernel, 2, off, gsz, NULL, 0, NULL, NULL), err,
              error);
    CLH_CHECK(clFinish(g->cl.queue), err, error);
    bk_progress_update(&prog, (uint64_t)(y0 + band < height ? y0 + band : height));
  }
  bk_progress_end(&prog);
  return BK_OK;
error:
  return err->code;
}

/* The image into rgba and the per-pixel step counts into a new *steps. */
static int read_back(view_gpu_t *g, cl_mem b[7], size_t npix, float *rgba, bk_uint **steps,
                     bk_error_t *err) {
  *steps = bk_calloc(npix, sizeof **steps, "view: step counts", err);
  if (!*steps) return BK_ERR_RUNTIME;
  CLH_CHECK(clEnqueueReadBuffer(g->cl.queue, b[5], CL_TRUE, 0, npix * 4 * sizeof(float), rgba, 0,
                                NULL, NULL),
            err, error);
  CLH_CHECK(clEnqueueReadBuffer(g->cl.queue, b[6], CL_TRUE, 0, npix * sizeof(bk_uint), *steps, 0,
                                NULL, NULL),
            err, error);
  return BK_OK;
error:
  return err->code;
}

int view_render(view_gpu_t *g, const view_volume_t *v, const view_cam_t *c, const float bg[3],
                int integrator, float step, float *rgba, view_totals_t *tot, bk_error_t *err) {
  const size_t npix = (size_t)c->width * (size_t)c->height;
  int rc = BK_OK;
  cl_mem b[9] = {0};
  err->code = BK_OK;
  bk_uint *steps = NULL;
  view_params_t p;
  setup_params(v, c, bg, step, &p);
  count_camera_phase(v, &p, tot);

  if (v->empty) { /* nothing in the file but background */
    for (size_t i = 0; i < npix; i++) {
      rgba[4 * i] = bg[0], rgba[4 * i + 1] = bg[1], rgba[4 * i + 2] = bg[2];
      rgba[4 * i + 3] = 0.0f;
    }
    return BK_OK;
  }
  if (g->host) return render_host(v, &p, integrator, rgba, tot);

  double t0 = bk_now_ms();
  if ((rc = build_kernel(g, v, integrator, tot, err))) goto error;
  double t1 = bk_now_ms();
  tot->build_ms += t1 - t0;
  if ((rc = upload(g, v, &p, npix, b, err))) goto error;
  double t2 = bk_now_ms(), c2 = cpu_ms();
  tot->upload_ms += t2 - t1;
  if ((rc = march_bands(g, c->width, c->height, err)) ||
      (rc = read_back(g, b, npix, rgba, &steps, err)))
    goto error;
  tot->march_ms += bk_now_ms() - t2;
  tot->march_cpu_ms += cpu_ms() - c2;
  for (size_t i = 0; i < npix; i++) {
    tot->ray_steps += steps[i];
    if (v->refraction && steps[i] >= (bk_uint)p.max_steps) tot->capped++;
  }
  tot->pixels += npix;

error:
  if (rc == BK_OK) rc = err->code; /* set by CLH_CHECK */
  for (int a = 0; a < 9; a++)
    if (b[a]) clReleaseMemObject(b[a]);
  free(steps);
  return rc;
}
