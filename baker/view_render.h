/* view_render.h: one image of a dense volume (view_volume.h) through a
 * camera (view_camera.h), on OpenCL (kernels/view.cl) or, with --device host,
 * the same ray code (kernels/view_march.h) compiled for the host, one pixel after
 * another. Each pixel's camera ray bends through n with the ray equation and
 * gathers L = ∫ T σs L̄ dt + T_end·L_background; out come linear RGBA floats,
 * A = 1 − mean transmittance, and the work done for the timing table. */
#ifndef BAKER_VIEW_RENDER_H
#define BAKER_VIEW_RENDER_H

#include <stdint.h>

#include "clhost.h"
#include "view_camera.h"
#include "view_volume.h"

#define VIEW_DEFAULT_STEP 0.5f   /* voxels, as photons.step */
#define VIEW_STEP_MIN 0.01f      /* below it a ray needs millions of steps */
#define VIEW_STEP_MAX 16.0f      /* above it the medium is undersampled */

/* The device and the kernel built for the last image's options. */
typedef struct view_gpu {
  clh_context_t cl;
  int ready;
  int host;            /* --device host: kernels/view_march.h in plain C, no OpenCL */
  cl_program program;
  cl_kernel kernel;
  char options[256];
} view_gpu_t;

/* When the device opened, if in the read's time: while the readers worked,
 * or before them, to check its largest buffer (view_volume.h). */
enum { VIEW_DEVICE_IN_READ = 1, VIEW_DEVICE_BEFORE_READ = 2 };

/* Times and work over all frames, for the timing table. */
typedef struct view_totals {
  double read_ms, build_ms, upload_ms, march_ms, write_ms;
  double march_cpu_ms; /* CPU time of the whole process (all device threads) while marching */
  uint64_t ray_steps, pixels, capped;
  int frames;
  int reused;          /* frames that kept the previous frame's volume */
  int device_in_read;  /* the device was opened in the read's time: VIEW_DEVICE_* */
  int camera_frames, lobe_frames; /* radiance_camera: frames at the bake's camera, elsewhere */
  char last_options[256];
} view_totals_t;

/* Opens the device once (g->ready): "host" for the host C path, else an
 * OpenCL device spec (NULL: PoCL/default). */
int view_gpu_init(view_gpu_t *g, const char *device, bk_error_t *err);
void view_gpu_release(view_gpu_t *g);

/* Renders one image into rgba (width*height*4 floats); integrator is
 * VIEW_EULER or VIEW_RK4, step in voxels where n varies. */
int view_render(view_gpu_t *g, const view_volume_t *v, const view_cam_t *c, const float bg[3],
                int integrator, float step, float *rgba, view_totals_t *tot, bk_error_t *err);

#endif
