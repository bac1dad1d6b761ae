/* view_cmd.c: the `baker view` command: parses the options (getopt_long,
 * `--opt=value` and `--opt value` alike), settles the camera, background,
 * integrator and step, and renders each frame with the library (volume
 * loading, view_render, view_write_images). */
#define _POSIX_C_SOURCE 200809L
#include "view.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "budget.h"
#include "clhost.h"
#include "cmdline.h"
#include "base/frames.h"
#include "frame_reuse.h"
#include "kernels/view_march.h"
#include "scene.h"

typedef struct view_opts {
  const char *in, *out, *png, *scene, *device;
  view_cam_overrides_t cam;
  int has_bg, has_frames, has_integrator, has_step;
  float bg[3], exposure, step;
  int integrator;
  frames_range_t frames;
  uint64_t max_memory; /* --max-memory; 0: what the machine has available */
} view_opts_t;

void view_usage(FILE *out) {
  fprintf(out,
          "usage: baker view IN.vdb -o OUT.exr [options]\n"
          "\n"
          "Renders the `radiance` grid (Lbar) of a baked VDB: camera rays bend through\n"
          "the `ior` grid (ray equation d/ds(n dx/ds) = grad n) and gather\n"
          "L = integral of T sigma_s Lbar dt + T_end L_background, with sigma from the\n"
          "`extinction` and `scattering` grids. Writes a linear half-float RGBA OpenEXR\n"
          "(A = 1 - mean transmittance) with the camera in its header.\n"
          "\n"
          "options:\n"
          "  -o, --output OUT.exr     output image (required)\n"
          "  --scene SCENE.json       take camera and background from a scene file\n"
          "  --camera-pos X,Y,Z       camera position (world units)\n"
          "  --look-at X,Y,Z          point the camera looks at\n"
          "  --up X,Y,Z               up direction (default 0,1,0)\n"
          "  --fov DEG                VERTICAL field of view in degrees, (0, 180) (default %g)\n"
          "  --resolution WxH         image size in pixels (default %dx%d)\n"
          "  --background R,G,B       radiance behind the volume (default the scene's, else 0)\n"
          "  --png OUT.png            also write an 8-bit sRGB preview\n"
          "  --exposure EV            preview exposure in stops, pixels x 2^EV (default 0)\n"
          "  --integrator euler|rk4   ray-equation integrator (default the scene's, else euler)\n"
          "  --step VOXELS            step where n varies, in voxels (default the scene's\n"
          "                           photons.step, else %g); straight stretches take\n"
          "                           max(step, 1) voxels\n"
          "  --frames A-BxS           render frames A..B every S; OUT and --png hold a\n"
          "                           frame pattern: #### (zero padded to the number of #),\n"
          "                           $F4 (Houdini, padded to 4) or $F (unpadded); IN holds\n"
          "                           one too, or is one file seen by a keyframed --scene\n"
          "                           camera (read once: docs/animation.md)\n"
          "  --max-memory SIZE        refuse a file whose estimated peak memory exceeds\n"
          "                           SIZE (e.g. 8G; default: the memory available)\n"
          "  --device SPEC            OpenCL device: `P:D` indices or a name substring;\n"
          "                           `list` prints the devices (default PoCL); `host`\n"
          "                           runs the same ray code in plain C, one thread\n"
          "                           (the reference path, slow)\n"
          "  --progress[=json]        show progress even when stderr is not a terminal;\n"
          "                           =json: one JSON object per line on stderr\n"
          "  --threads N              at most N host threads and PoCL CPU threads\n"
          "  --log FILE               append every message to FILE as well\n"
          "  -q, --quiet              errors only (no timing table)\n"
          "  -v, --verbose            more detail (grids, kernel options, device)\n"
          "  -h, --help               this text\n"
          "\n"
          "Without --camera-pos/--look-at (or a scene camera) the camera frames the grid's\n"
          "bounding box from the -z side, slightly above. Grids: radiance (Vec3f, required),\n"
          "ior (float, default 1), extinction (float or Vec3f, else density, else equal\n"
          "to scattering, else 0), scattering (float or Vec3f, default equal to extinction),\n"
          "ior_rgb (Vec3f, n per channel: each channel's rays bend by their own n).\n"
          "Exit status: 0 success, 2 bad input or usage, 1 runtime failure.\n",
          VIEW_DEFAULT_FOV, VIEW_DEFAULT_WIDTH, VIEW_DEFAULT_HEIGHT, VIEW_DEFAULT_STEP);
}

static int parse_vec3(const char *s, float out[3]) {
  char buf[256];
  if (strlen(s) >= sizeof buf) return 0;
  strcpy(buf, s);
  char *p = buf;
  for (int a = 0; a < 3; a++) {
    char *comma = strchr(p, ',');
    if ((a < 2) != (comma != NULL)) return 0;
    if (comma) *comma = 0;
    if (!cmd_parse_float(p, &out[a])) return 0;
    p = comma ? comma + 1 : p;
  }
  return 1;
}

static int parse_res(const char *s, int *w, int *h) {
  char *end;
  errno = 0;
  long a = strtol(s, &end, 10);
  if (end == s || (*end != 'x' && *end != 'X') || errno) return 0;
  const char *p = end + 1;
  long b = strtol(p, &end, 10);
  if (end == p || *end != 0 || errno) return 0;
  if (a < 0 || b < 0 || a > VIEW_MAX_AXIS || b > VIEW_MAX_AXIS) return 0;
  *w = (int)a;
  *h = (int)b;
  return 1;
}

/* values of the long-only options */
enum {
  OPT_PNG = CMD_FIRST_OWN, OPT_SCENE, OPT_CAMERA_POS, OPT_LOOK_AT, OPT_UP, OPT_FOV, OPT_RESOLUTION,
  OPT_BACKGROUND, OPT_EXPOSURE, OPT_INTEGRATOR, OPT_STEP, OPT_FRAMES, OPT_DEVICE,
  OPT_MAX_MEMORY
};

static const struct option view_longopts[] = {
    {"output", required_argument, NULL, 'o'},
    {"png", required_argument, NULL, OPT_PNG},
    {"scene", required_argument, NULL, OPT_SCENE},
    {"camera-pos", required_argument, NULL, OPT_CAMERA_POS},
    {"camera", required_argument, NULL, OPT_CAMERA_POS},
    {"look-at", required_argument, NULL, OPT_LOOK_AT},
    {"up", required_argument, NULL, OPT_UP},
    {"fov", required_argument, NULL, OPT_FOV},
    {"resolution", required_argument, NULL, OPT_RESOLUTION},
    {"background", required_argument, NULL, OPT_BACKGROUND},
    {"exposure", required_argument, NULL, OPT_EXPOSURE},
    {"integrator", required_argument, NULL, OPT_INTEGRATOR},
    {"step", required_argument, NULL, OPT_STEP},
    {"frames", required_argument, NULL, OPT_FRAMES},
    {"device", required_argument, NULL, OPT_DEVICE},
    {"max-memory", required_argument, NULL, OPT_MAX_MEMORY},
    CMD_COMMON_LONGOPTS,
    {NULL, 0, NULL, 0}};

/* The camera's options; 0 when c is not one of them. */
static int view_cam_option(view_cam_overrides_t *o, int c, const char *val, const char **want) {
  switch (c) {
  case OPT_CAMERA_POS:
    if (!parse_vec3(val, o->pos)) *want = "three numbers X,Y,Z";
    o->has_pos = 1;
    return 1;
  case OPT_LOOK_AT:
    if (!parse_vec3(val, o->look)) *want = "three numbers X,Y,Z";
    o->has_look = 1;
    return 1;
  case OPT_UP:
    if (!parse_vec3(val, o->up)) *want = "three numbers X,Y,Z";
    o->has_up = 1;
    return 1;
  case OPT_FOV:
    if (!cmd_parse_float(val, &o->fov) || !(o->fov > 0.0f && o->fov < 180.0f))
      *want = "a vertical field of view in degrees in (0, 180)";
    o->has_fov = 1;
    return 1;
  case OPT_RESOLUTION:
    if (!parse_res(val, &o->width, &o->height) || o->width < 1 || o->height < 1)
      *want = "WxH with 1 <= W, H <= 65536 (e.g. 800x600)";
    o->has_res = 1;
    return 1;
  }
  return 0;
}

/* Applies option c with value val; BK_OK or BK_ERR_INPUT with the message in err. */
static int view_option(view_opts_t *o, int c, const char *name, const char *val,
                       bk_error_t *err) {
  const char *want = NULL;
  if (view_cam_option(&o->cam, c, val, &want)) {
  } else if (c == 'o') {
    o->out = val;
  } else if (c == OPT_PNG) {
    o->png = val;
  } else if (c == OPT_SCENE) {
    o->scene = val;
  } else if (c == OPT_BACKGROUND) {
    if (!parse_vec3(val, o->bg) || o->bg[0] < 0 || o->bg[1] < 0 || o->bg[2] < 0)
      want = "three non-negative numbers R,G,B";
    o->has_bg = 1;
  } else if (c == OPT_EXPOSURE) {
    if (!cmd_parse_float(val, &o->exposure) || fabsf(o->exposure) > 64.0f)
      want = "an exposure in stops in [-64, 64]";
  } else if (c == OPT_INTEGRATOR) {
    if (!strcmp(val, "euler")) o->integrator = VIEW_EULER;
    else if (!strcmp(val, "rk4")) o->integrator = VIEW_RK4;
    else want = "euler or rk4";
    o->has_integrator = 1;
  } else if (c == OPT_STEP) {
    if (!cmd_parse_float(val, &o->step) || !(o->step >= VIEW_STEP_MIN && o->step <= VIEW_STEP_MAX))
      want = "a step in voxels in [0.01, 16]";
    o->has_step = 1;
  } else if (c == OPT_FRAMES) {
    int rc = frames_parse(val, "--frames", &o->frames, err);
    if (rc) return rc;
    o->has_frames = 1;
  } else if (c == OPT_DEVICE) {
    o->device = val;
  } else if (c == OPT_MAX_MEMORY) {
    if (!budget_parse_size(val, &o->max_memory)) want = "a size such as 8G or 500M";
  }
  if (want) return bk_fail(err, BK_ERR_INPUT, "%s: expected %s, got '%s'", name, want, val);
  return BK_OK;
}

/* What the options must agree on: an input and an .exr output, a .png
 * preview, frame patterns exactly when --frames renders several (the input
 * may be one file for every frame: a camera moving through one bake). */
static int view_check_opts(view_opts_t *o, bk_error_t *err) {
  if (o->device && !strcmp(o->device, "list")) return BK_OK;
  if (!o->in) return bk_fail(err, BK_ERR_INPUT, "no input given (baker view IN.vdb -o OUT.exr)");
  if (!o->out) return bk_fail(err, BK_ERR_INPUT, "no output given (-o OUT.exr)");
  size_t n = strlen(o->out);
  if (n < 4 || strcasecmp(o->out + n - 4, ".exr") != 0)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: expected an .exr output (use --png OUT.png for a preview)", o->out);
  if (o->png) {
    n = strlen(o->png);
    if (n < 4 || strcasecmp(o->png + n - 4, ".png") != 0)
      return bk_fail(err, BK_ERR_INPUT, "--png %s: expected a .png file name", o->png);
  }
  /* frame patterns and --frames go together */
  const char *paths[3] = {o->in, o->out, o->png};
  const char *what[3] = {"input", "output", "--png"};
  for (int k = 0; k < 3; k++) {
    if (!paths[k]) continue;
    int pat = frames_has_pattern(paths[k]);
    if (pat && !o->has_frames)
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: the %s path holds a frame pattern (#### or $F4); give --frames A-B",
                     paths[k], what[k]);
    if (!pat && k > 0 && o->has_frames && frames_count(&o->frames) > 1)
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: --frames renders %d frames but the %s path has no frame pattern "
                     "(#### or $F4)", paths[k], frames_count(&o->frames), what[k]);
  }
  return BK_OK;
}

/* Returns CMD_HELP or CMD_VERSION for those (exit 0), else an exit status. */
static int parse_args(int argc, char **argv, view_opts_t *o, bk_error_t *err) {
  cmd_parser_t p;
  int c;
  memset(o, 0, sizeof *o);
  o->step = VIEW_DEFAULT_STEP;
  cmd_begin(&p, argc, argv, "view", "o:" CMD_COMMON_SHORTOPTS, view_longopts);
  while ((c = cmd_next(&p, err)) != CMD_END) {
    if (c == CMD_ERROR) return err->code;
    if (c == CMD_HELP || c == CMD_VERSION) return c;
    if (c != CMD_POSITIONAL) {
      if (view_option(o, c, p.opt, p.arg, err)) return err->code;
    } else if (!o->in) {
      o->in = p.arg;
    } else {
      return bk_fail(err, BK_ERR_INPUT, "unexpected argument '%s' (one input per command; "
                     "use a frame pattern and --frames for a sequence)", p.arg);
    }
  }
  return view_check_opts(o, err);
}

/* One `baker view` run: the settings every frame shares and the state the
 * frames carry from one to the next. */
typedef struct view_job {
  view_opts_t o;
  scene_t scene;
  int have_scene;
  view_cam_t cam;
  float bg[3], step;
  int integrator;
  frames_range_t fr;
  int nframes;
  int camera_keyed; /* the scene keyframes a value: its camera is set per frame */
  view_gpu_t gpu;
  view_volume_t vol;
  uint64_t vol_key; /* fr_file_key of the file vol was read from (0: none) */
  int vol_frame;
  view_totals_t tot;
  float *rgba;
} view_job_t;

/* Camera, background, integrator and step: flags, else the scene's, else
 * the defaults. */
static int view_settings(view_job_t *j, bk_error_t *err) {
  const view_opts_t *o = &j->o;
  int rc;
  if (o->scene) {
    if ((rc = scene_load(o->scene, &j->scene, err))) return rc;
    j->have_scene = 1;
    j->camera_keyed = o->has_frames && j->scene.keyed_values > 0;
  }
  view_cam_from_inputs(&o->cam, j->have_scene ? &j->scene : NULL, &j->cam);
  if ((rc = view_cam_validate(&j->cam, err))) return rc;
  if (o->has_bg)
    memcpy(j->bg, o->bg, sizeof j->bg);
  else if (j->have_scene)
    memcpy(j->bg, j->scene.background, sizeof j->bg);
  j->integrator = o->has_integrator                                         ? o->integrator
                  : j->have_scene && j->scene.integrator == INTEGRATOR_RK4 ? VIEW_RK4
                                                                             : VIEW_EULER;
  j->step = o->step;
  if (!o->has_step && j->have_scene) {
    j->step = bk_clampf(j->scene.step, VIEW_STEP_MIN, VIEW_STEP_MAX);
    if (j->step != j->scene.step)
      bk_warn("%s: photons.step %g voxels is outside [%g, %g] for camera rays; using %g",
              j->scene.path, j->scene.step, VIEW_STEP_MIN, VIEW_STEP_MAX, j->step);
  }
  return BK_OK;
}

/* The paths of frame number `frame`; png is left alone without --png. */
static int view_frame_paths(const view_opts_t *o, int frame, char *in, char *out, char *png,
                            bk_error_t *err) {
  int rc;
  if ((rc = frames_expand(o->in, frame, in, VIEW_PATH_MAX, err)) ||
      (rc = frames_expand(o->out, frame, out, VIEW_PATH_MAX, err)) ||
      (o->png && (rc = frames_expand(o->png, frame, png, VIEW_PATH_MAX, err))))
    return rc;
  return BK_OK;
}

/* A keyframed scene's camera at this frame (the flags still override it). */
static int view_frame_camera(view_job_t *j, int frame, bk_error_t *err) {
  if (!j->camera_keyed) return BK_OK;
  scene_free(&j->scene);
  j->have_scene = 0;
  int rc = scene_load_frame(j->o.scene, NULL, 0, frame, &j->scene, err);
  if (rc) return rc;
  j->have_scene = 1;
  view_cam_from_inputs(&j->o.cam, &j->scene, &j->cam);
  return view_cam_validate(&j->cam, err);
}

/* Every frame's input must exist, its camera be valid and every output
 * directory be writable before the first image is rendered; then the image
 * buffer. */
static int view_prepare(view_job_t *j, bk_error_t *err) {
  const view_opts_t *o = &j->o;
  char in[VIEW_PATH_MAX], out[VIEW_PATH_MAX], png[VIEW_PATH_MAX];
  int rc;
  j->fr = (frames_range_t){0, 0, 1};
  if (o->has_frames) j->fr = o->frames;
  j->nframes = frames_count(&j->fr);
  for (int f = 0; f < j->nframes; f++) {
    if ((rc = view_frame_paths(o, frames_at(&j->fr, f), in, out, png, err))) return rc;
    if (access(in, R_OK) != 0)
      return bk_fail(err, BK_ERR_INPUT, "%s: cannot open VDB file: %s%s", in, strerror(errno),
                     o->has_frames ? " (frame pattern expanded with --frames)" : "");
    if ((rc = bk_check_output_dir(out, err)) || (o->png && (rc = bk_check_output_dir(png, err))) ||
        (rc = view_frame_camera(j, frames_at(&j->fr, f), err)))
      return rc;
  }
  const view_cam_t *cam = &j->cam;
  size_t npix = (size_t)cam->width * (size_t)cam->height, bytes;
  uint64_t mem = bk_physical_memory();
  if (!bk_mul_size(npix, 5 * sizeof(float), &bytes) || (mem && bytes > mem / 2)) {
    char b[32];
    return bk_fail(err, BK_ERR_INPUT, "%s: a %dx%d image needs %s, more than half this "
                   "machine's memory", cam->src, cam->width, cam->height,
                   bk_format_bytes((double)npix * 5 * sizeof(float), b, sizeof b));
  }
  j->rgba = bk_calloc(npix, 4 * sizeof(float), "view: image", err);
  return j->rgba ? BK_OK : BK_ERR_RUNTIME;
}

/* The device, opened in the read's time (`when`: VIEW_DEVICE_*). A failure
 * is left for view_frame's own call, which reports it only when the volume
 * needs a device. */
static void view_open_in_read(view_job_t *j, int when) {
  bk_error_t ignored;
  if (!j->gpu.ready && view_gpu_init(&j->gpu, j->o.device, &ignored) == BK_OK)
    j->tot.device_in_read = when;
}

/* While the grids are decoded in reader processes: OpenCL's start-up, tens
 * of ms of library loading. */
static void view_start_gpu(void *ctx) { view_open_in_read(ctx, VIEW_DEVICE_IN_READ); }

/* Before a large file is read: the device, opened now, and its largest
 * buffer (0: the host, or no device, which view_frame reports). */
static uint64_t view_max_buffer(void *ctx, const char **device) {
  view_job_t *j = ctx;
  view_open_in_read(j, VIEW_DEVICE_BEFORE_READ);
  if (!j->gpu.ready || j->gpu.host) return 0;
  *device = j->gpu.cl.device_name;
  return j->gpu.cl.max_alloc;
}

/* The frame's volume: the previous frame's when the file's contents hash
 * the same (docs/animation.md), else read. */
static int view_frame_volume(view_job_t *j, const char *in, int frame, bk_error_t *err) {
  double t0 = bk_now_ms();
  uint64_t key = j->nframes > 1 ? fr_file_key(in) : 0;
  if (key && key == j->vol_key) {
    j->tot.read_ms += bk_now_ms() - t0;
    j->tot.reused++;
    bk_log(2, "view: %s: reused from frame %d (file unchanged)", in, j->vol_frame);
    return BK_OK;
  }
  view_volume_free(&j->vol);
  j->vol_key = 0;
  const view_load_hooks_t hooks = {view_start_gpu, view_max_buffer, j};
  int rc = view_volume_load(in, &j->vol, j->o.max_memory, &hooks, err);
  j->tot.read_ms += bk_now_ms() - t0;
  if (rc) return rc;
  j->vol_key = key, j->vol_frame = frame;
  bk_log(2, "view: %s: %s%s; n in [%g, %g]%s", in, j->vol.desc, j->vol.empty ? " (all empty)" : "",
         j->vol.n_min, j->vol.n_max, j->vol.refraction ? ", refracting" : "");
  return BK_OK;
}

/* Frame f of the range: camera (keyframed), read (or keep), (first frame)
 * frame a default camera, render, write. */
static int view_frame(view_job_t *j, int f, bk_error_t *err) {
  const view_opts_t *o = &j->o;
  view_cam_t *cam = &j->cam;
  char in[VIEW_PATH_MAX], out[VIEW_PATH_MAX], png[VIEW_PATH_MAX];
  int rc, frame = frames_at(&j->fr, f);
  view_frame_paths(o, frame, in, out, png, err); /* checked by view_prepare */
  if ((rc = view_frame_camera(j, frame, err)) || (rc = view_frame_volume(j, in, frame, err)))
    return rc;
  if (f == 0 || j->camera_keyed) { /* a default camera is framed on the first frame and kept */
    double bmin[3], bmax[3];
    view_volume_world_box(&j->vol, bmin, bmax);
    view_cam_fill_default(cam, bmin, bmax);
    if ((rc = view_cam_validate(cam, err))) return rc;
    bk_log(2, "view: camera at (%g, %g, %g) looking at (%g, %g, %g), vertical fov %g deg, %dx%d",
           cam->pos[0], cam->pos[1], cam->pos[2], cam->look[0], cam->look[1], cam->look[2],
           cam->fov, cam->width, cam->height);
  }
  if (!j->vol.empty && (rc = view_gpu_init(&j->gpu, o->device, err))) return rc;
  if ((rc = view_render(&j->gpu, &j->vol, cam, j->bg, j->integrator, j->step, j->rgba, &j->tot,
                        err)))
    return rc;
  double t0 = bk_now_ms();
  if ((rc = view_write_images(in, out, o->png ? png : NULL, cam, j->rgba, o->has_frames, frame,
                              o->exposure, j->integrator, j->step, err)))
    return rc;
  j->tot.write_ms += bk_now_ms() - t0;
  j->tot.frames++;
  if (bk_verbosity >= 1)
    printf("view: %s -> %s%s%s (%dx%d)\n", in, out, o->png ? ", " : "", o->png ? png : "",
           cam->width, cam->height);
  return BK_OK;
}

int view_main(int argc, char **argv) {
  bk_error_t err;
  view_job_t job, *j = &job;
  memset(&err, 0, sizeof err);
  memset(j, 0, sizeof *j);
  int rc = parse_args(argc, argv, &j->o, &err);
  if (rc == CMD_HELP) view_usage(stdout);
  else if (rc == CMD_VERSION) cmd_print_version();
  if (rc == CMD_HELP || rc == CMD_VERSION) return BK_OK;
  if (rc) {
    bk_report("view", err.msg);
    return rc;
  }
  if (j->o.device && !strcmp(j->o.device, "list")) {
    clh_list_devices(stdout);
    return BK_OK;
  }
  if (!(rc = view_settings(j, &err)) && !(rc = view_prepare(j, &err)))
    for (int f = 0; f < j->nframes && !rc; f++) rc = view_frame(j, f, &err);
  if (!rc) view_report(&j->tot, j->o.png != NULL);

  if (rc) bk_report("view", err.msg);
  view_volume_free(&j->vol);
  view_gpu_release(&j->gpu);
  free(j->rgba);
  if (j->have_scene) scene_free(&j->scene);
  return rc;
}
