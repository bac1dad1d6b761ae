/* view_image.c: what `baker view` writes: the EXR with the camera, source
 * and frame in its header, the PNG preview, and the timing table. */
#define _POSIX_C_SOURCE 200809L
#include "view_image.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "exr.h"
#include "kernels/view_march.h"
#include "png_io.h"
#include "vdbio.h"

static int frame_from_meta(const char *path, int *frame) {
  char text[64];
  bk_error_t e;
  if (vdbio_read_meta(path, "frame", text, sizeof text, &e) != BK_OK || !text[0]) return 0;
  char *end;
  long f = strtol(text, &end, 10);
  if (end == text || *end != 0) return 0;
  *frame = (int)f;
  return 1;
}

/* The two files of a frame, each written (atomically) on its own thread:
 * the PNG's deflate beside the EXR's, about a third of the write stage. */
typedef struct image_jobs {
  const char *out, *png;
  const view_cam_t *c;
  const float *rgba;
  const exr_info_t *info;
  float exposure;
  int rc[2];
  bk_error_t err[2];
} image_jobs_t;

static void write_one(void *ctx, size_t k, size_t lo, size_t hi) {
  (void)lo, (void)hi;
  image_jobs_t *j = ctx;
  const view_cam_t *c = j->c;
  if (k == 0) j->rc[0] = exr_write_rgba(j->out, c->width, c->height, j->rgba, j->info, &j->err[0]);
  else if (j->png)
    j->rc[1] = png_write_preview(j->png, c->width, c->height, j->rgba, j->exposure, &j->err[1]);
}

int view_write_images(const char *in, const char *out, const char *png, const view_cam_t *c,
                      const float *rgba, int has_frame, int frame, float exposure,
                      int integrator, float step, bk_error_t *err) {
  exr_info_t info;
  char comments[256];
  memset(&info, 0, sizeof info);
  info.source = in;
  info.has_frame = has_frame || frame_from_meta(in, &frame);
  info.frame = frame;
  info.has_camera = 1;
  memcpy(info.cam_position, c->pos, sizeof info.cam_position);
  memcpy(info.cam_look_at, c->look, sizeof info.cam_look_at);
  memcpy(info.cam_up, c->up, sizeof info.cam_up);
  info.cam_fov_y_deg = c->fov;
  snprintf(comments, sizeof comments,
           "baker view: linear radiance L (W m^-2 sr^-1), A = 1 - mean transmittance; "
           "%s integrator, step %g voxels", integrator == VIEW_RK4 ? "rk4" : "euler", step);
  info.comments = comments;
  image_jobs_t j;
  memset(&j, 0, sizeof j);
  j.out = out, j.png = png, j.c = c, j.rgba = rgba, j.info = &info, j.exposure = exposure;
  bk_parallel_chunks(png ? 2 : 1, png ? 2 : 1, write_one, &j);
  for (int k = 0; k < 2; k++) /* the EXR's failure first, as when written in turn */
    if (j.rc[k]) {
      *err = j.err[k];
      return j.rc[k];
    }
  return BK_OK;
}

/* ", N reused (file unchanged)" for the read row, or "". */
static const char *reused_note(const view_totals_t *tot, char *buf, size_t n) {
  if (!tot->reused) return "";
  snprintf(buf, n, ", %d reused (file unchanged)", tot->reused);
  return buf;
}

void view_report(const view_totals_t *tot, int with_png) {
  char note[64];
  /* a handful of grazing rays circulate inside a smoothed interface where
   * the discrete field lets them (the photons do the same); many is news */
  if (tot->capped)
    bk_log(tot->capped * 10000 > tot->pixels ? 0 : 2,
           "%s: %llu of %llu camera rays stopped at the step limit (trapped by total internal "
           "reflection)", tot->capped * 10000 > tot->pixels ? "warning" : "view",
           (unsigned long long)tot->capped, (unsigned long long)tot->pixels);
  if (tot->camera_frames && tot->lobe_frames)
    bk_log(1, "view: the phase towards the camera came from radiance_camera in %d frame(s) and "
              "from the flux's lobes in %d (cameras elsewhere than the bake's)",
           tot->camera_frames, tot->lobe_frames);
  if (bk_verbosity >= 1) {
    bk_timings_t t;
    memset(&t, 0, sizeof t);
    double msteps = tot->march_ms > 0 ? (double)tot->ray_steps / (tot->march_ms * 1e3) : 0.0;
    bk_timings_add(&t, "read", tot->read_ms, "%d frame%s%s%s", tot->frames,
                   tot->frames == 1 ? "" : "s", reused_note(tot, note, sizeof note),
                   tot->device_in_read == VIEW_DEVICE_IN_READ       ? ", OpenCL opened meanwhile"
                   : tot->device_in_read == VIEW_DEVICE_BEFORE_READ ? ", OpenCL opened first, "
                                                                      "for its buffer limit"
                                                                    : "");
    bk_timings_add(&t, "build kernel", tot->build_ms, "%s", tot->last_options);
    bk_timings_add(&t, "upload", tot->upload_ms, NULL);
    /* CPU time too: on a shared machine wall time says little about the kernel */
    bk_timings_add(&t, "march", tot->march_ms,
                   "%llu ray-steps, %.2f M ray-steps/s, %llu rays, %.0f ms CPU",
                   (unsigned long long)tot->ray_steps, msteps, (unsigned long long)tot->pixels,
                   tot->march_cpu_ms);
    bk_timings_add(&t, "write", tot->write_ms, with_png ? "EXR + PNG" : "EXR");
    bk_timings_print(&t, stdout); /* as `baker bake` does: the report, not a diagnostic */
    fflush(stdout);
  }
}
