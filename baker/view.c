/* view.c: `baker view`: read a baked VDB, march camera rays on OpenCL, write
 * EXR (and PNG). The ray math lives in kernels/view_march.h; this file gathers the
 * grids onto one dense box, places the camera in its voxel space, runs the
 * kernel and writes the images. */
#define _POSIX_C_SOURCE 200809L
#include "view.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/resource.h>
#include <unistd.h>

#include "clhost.h"
#include "exr.h"
#include "frames.h"
#include "grid.h"
#include "field.h"
#include "kernels/view_march.h"
#include "octree.h"
#include "png_io.h"
#include "scene.h"
#include "vdbio.h"

#define VIEW_DEFAULT_FOV 40.0f   /* degrees, vertical; DESIGN.md's example camera */
#define VIEW_DEFAULT_WIDTH 800
#define VIEW_DEFAULT_HEIGHT 600
#define VIEW_DEFAULT_STEP 0.5f   /* voxels, as photons.step */
#define VIEW_STEP_MIN 0.01f      /* below it a ray needs millions of steps */
#define VIEW_STEP_MAX 16.0f      /* above it the medium is undersampled */
#define VIEW_MAX_AXIS 65536      /* pixels along one image side */
#define VIEW_BANDS 16            /* kernel launches per image when showing progress */
#define VIEW_N_EPS 1e-6f         /* n differences below this bend nothing */
#define VIEW_PATH_MAX 4096
#define VIEW_PI 3.14159265358979323846

/* ------------------------------------------------------------------------- */
/* options                                                                    */

typedef struct view_opts {
  const char *in, *out, *png, *scene, *device;
  int has_pos, has_look, has_up, has_fov, has_res, has_bg, has_frames, has_integrator, has_step;
  float pos[3], look[3], up[3], fov, bg[3], exposure, step;
  int width, height, integrator;
  frames_range_t frames;
} view_opts_t;

/* The world-space camera and where each part came from, for messages. */
typedef struct view_cam {
  float pos[3], look[3], up[3], fov;
  int width, height;
  int has_pos, has_look;
  char src[VIEW_PATH_MAX + 160];
} view_cam_t;

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
          "  --frames A-BxS           render frames A..B every S; IN, OUT and --png hold a\n"
          "                           frame pattern: #### (zero padded to the number of #),\n"
          "                           $F4 (Houdini, padded to 4) or $F (unpadded)\n"
          "  --device SPEC            OpenCL device: `P:D` indices or a name substring;\n"
          "                           `list` prints the devices (default PoCL); `host`\n"
          "                           runs the same ray code in plain C, one thread\n"
          "                           (the reference path, slow)\n"
          "  --progress               show progress even when stderr is not a terminal\n"
          "  -q, --quiet              errors only (no timing table)\n"
          "  -v, --verbose            more detail (grids, kernel options, device)\n"
          "  -h, --help               this text\n"
          "\n"
          "Without --camera-pos/--look-at (or a scene camera) the camera frames the grid's\n"
          "bounding box from the -z side, slightly above. Grids: radiance (Vec3f, required),\n"
          "ior (float, default 1), extinction (float or Vec3f, else density, else equal\n"
          "to scattering, else 0), scattering (float or Vec3f, default equal to extinction).\n"
          "Exit status: 0 success, 2 bad input or usage, 1 runtime failure.\n",
          VIEW_DEFAULT_FOV, VIEW_DEFAULT_WIDTH, VIEW_DEFAULT_HEIGHT, VIEW_DEFAULT_STEP);
}

static int parse_float(const char *s, float *out) {
  char *end;
  errno = 0;
  float v = strtof(s, &end);
  if (end == s || *end != 0 || errno == ERANGE || !isfinite(v)) return 0;
  *out = v;
  return 1;
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
    if (!parse_float(p, &out[a])) return 0;
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

/* Returns -1 for --help (exit 0), else an exit status. */
static int parse_args(int argc, char **argv, view_opts_t *o, bk_error_t *err) {
  memset(o, 0, sizeof *o);
  o->step = VIEW_DEFAULT_STEP;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    const char *val = NULL;
#define NEED_VALUE()                                                                      \
  do {                                                                                    \
    if (i + 1 >= argc)                                                                    \
      return bk_fail(err, BK_ERR_INPUT, "%s needs a value (see baker view --help)", a);   \
    val = argv[++i];                                                                      \
  } while (0)
#define BAD_VALUE(what) \
  return bk_fail(err, BK_ERR_INPUT, "%s: expected %s, got '%s'", a, what, val)
    if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
      return -1;
    } else if (!strcmp(a, "-o") || !strcmp(a, "--output")) {
      NEED_VALUE();
      o->out = val;
    } else if (!strcmp(a, "--png")) {
      NEED_VALUE();
      o->png = val;
    } else if (!strcmp(a, "--scene")) {
      NEED_VALUE();
      o->scene = val;
    } else if (!strcmp(a, "--camera-pos") || !strcmp(a, "--camera")) {
      NEED_VALUE();
      if (!parse_vec3(val, o->pos)) BAD_VALUE("three numbers X,Y,Z");
      o->has_pos = 1;
    } else if (!strcmp(a, "--look-at")) {
      NEED_VALUE();
      if (!parse_vec3(val, o->look)) BAD_VALUE("three numbers X,Y,Z");
      o->has_look = 1;
    } else if (!strcmp(a, "--up")) {
      NEED_VALUE();
      if (!parse_vec3(val, o->up)) BAD_VALUE("three numbers X,Y,Z");
      o->has_up = 1;
    } else if (!strcmp(a, "--fov")) {
      NEED_VALUE();
      if (!parse_float(val, &o->fov) || !(o->fov > 0.0f && o->fov < 180.0f))
        BAD_VALUE("a vertical field of view in degrees in (0, 180)");
      o->has_fov = 1;
    } else if (!strcmp(a, "--resolution")) {
      NEED_VALUE();
      if (!parse_res(val, &o->width, &o->height) || o->width < 1 || o->height < 1)
        BAD_VALUE("WxH with 1 <= W, H <= 65536 (e.g. 800x600)");
      o->has_res = 1;
    } else if (!strcmp(a, "--background")) {
      NEED_VALUE();
      if (!parse_vec3(val, o->bg) || o->bg[0] < 0 || o->bg[1] < 0 || o->bg[2] < 0)
        BAD_VALUE("three non-negative numbers R,G,B");
      o->has_bg = 1;
    } else if (!strcmp(a, "--exposure")) {
      NEED_VALUE();
      if (!parse_float(val, &o->exposure) || fabsf(o->exposure) > 64.0f)
        BAD_VALUE("an exposure in stops in [-64, 64]");
    } else if (!strcmp(a, "--integrator")) {
      NEED_VALUE();
      if (!strcmp(val, "euler"))
        o->integrator = VIEW_EULER;
      else if (!strcmp(val, "rk4"))
        o->integrator = VIEW_RK4;
      else
        BAD_VALUE("euler or rk4");
      o->has_integrator = 1;
    } else if (!strcmp(a, "--step")) {
      NEED_VALUE();
      if (!parse_float(val, &o->step) || !(o->step >= VIEW_STEP_MIN && o->step <= VIEW_STEP_MAX))
        BAD_VALUE("a step in voxels in [0.01, 16]");
      o->has_step = 1;
    } else if (!strcmp(a, "--frames")) {
      NEED_VALUE();
      int rc = frames_parse(val, "--frames", &o->frames, err);
      if (rc) return rc;
      o->has_frames = 1;
    } else if (!strcmp(a, "--device")) {
      NEED_VALUE();
      o->device = val;
    } else if (bk_common_option(a)) {
    } else if (a[0] == '-' && a[1] != 0) {
      return bk_fail(err, BK_ERR_INPUT, "unknown option '%s' (see baker view --help)", a);
    } else if (!o->in) {
      o->in = a;
    } else {
      return bk_fail(err, BK_ERR_INPUT, "unexpected argument '%s' (one input per command; "
                     "use a frame pattern and --frames for a sequence)", a);
    }
#undef NEED_VALUE
#undef BAD_VALUE
  }
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
    if (!pat && o->has_frames && frames_count(&o->frames) > 1)
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: --frames renders %d frames but the %s path has no frame pattern "
                     "(#### or $F4)", paths[k], frames_count(&o->frames), what[k]);
  }
  return BK_OK;
}

/* ------------------------------------------------------------------------- */
/* camera                                                                     */

static double dot3d(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void cross3d(const double a[3], const double b[3], double out[3]) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}
static int normalize3d(double a[3]) {
  double l = sqrt(dot3d(a, a));
  if (!(l > 0.0) || !isfinite(l)) return 0;
  for (int k = 0; k < 3; k++) a[k] /= l;
  return 1;
}

static void cam_from_inputs(const view_opts_t *o, const scene_t *sc, view_cam_t *c) {
  memset(c, 0, sizeof *c);
  c->up[1] = 1.0f;
  c->fov = VIEW_DEFAULT_FOV;
  c->width = VIEW_DEFAULT_WIDTH;
  c->height = VIEW_DEFAULT_HEIGHT;
  snprintf(c->src, sizeof c->src, "default camera");
  if (sc) {
    c->fov = sc->camera.fov_deg;
    c->width = sc->camera.width;
    c->height = sc->camera.height;
    if (sc->camera.present) {
      memcpy(c->pos, sc->camera.position, sizeof c->pos);
      memcpy(c->look, sc->camera.look_at, sizeof c->look);
      memcpy(c->up, sc->camera.up, sizeof c->up);
      c->has_pos = c->has_look = 1;
      snprintf(c->src, sizeof c->src, "%s: camera", sc->path);
    }
  }
  if (o->has_pos || o->has_look || o->has_up) {
    char flags[64];
    snprintf(flags, sizeof flags, "%s%s%s", o->has_pos ? " --camera-pos" : "",
             o->has_look ? " --look-at" : "", o->has_up ? " --up" : "");
    if (sc && sc->camera.present)
      snprintf(c->src + strlen(c->src), sizeof c->src - strlen(c->src), " overridden by%s", flags);
    else
      snprintf(c->src, sizeof c->src, "camera from%s", flags);
  }
  if (o->has_pos) memcpy(c->pos, o->pos, sizeof c->pos), c->has_pos = 1;
  if (o->has_look) memcpy(c->look, o->look, sizeof c->look), c->has_look = 1;
  if (o->has_up) memcpy(c->up, o->up, sizeof c->up);
  if (o->has_fov) c->fov = o->fov;
  if (o->has_res) c->width = o->width, c->height = o->height;
}

/* Checks what is known of the camera: a view direction and an up that is not
 * along it. */
static int cam_validate(const view_cam_t *c, bk_error_t *err) {
  if (c->width < 1 || c->height < 1)
    return bk_fail(err, BK_ERR_INPUT, "%s: resolution must be at least 1x1, got %dx%d", c->src,
                   c->width, c->height);
  if (!(c->fov > 0.0f && c->fov < 180.0f))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: vertical field of view must be in (0, 180) degrees, got %g", c->src,
                   c->fov);
  if (!c->has_pos || !c->has_look) return BK_OK;
  double f[3], u[3] = {c->up[0], c->up[1], c->up[2]}, r[3];
  double scale = 0.0;
  for (int k = 0; k < 3; k++) {
    f[k] = (double)c->look[k] - c->pos[k];
    scale = fmax(scale, fmax(fabs(c->look[k]), fabs(c->pos[k])));
  }
  if (!(sqrt(dot3d(f, f)) > 1e-6 * fmax(scale, 1e-30)))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: the look-at point (%g, %g, %g) equals the camera position; expected a "
                   "point to look at away from the camera", c->src, c->look[0], c->look[1],
                   c->look[2]);
  cross3d(f, u, r);
  if (!(dot3d(r, r) > 1e-12 * dot3d(f, f) * dot3d(u, u)))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: up (%g, %g, %g) is zero or along the line of sight; expected a vector "
                   "not parallel to look-at - position", c->src, c->up[0], c->up[1], c->up[2]);
  return BK_OK;
}

/* Frames the world box: from the -z side, a little above, far enough that
 * its bounding sphere fits the narrower field of view. */
static void cam_fill_default(view_cam_t *c, const double bmin[3], const double bmax[3]) {
  double ctr[3], r2 = 0.0;
  for (int k = 0; k < 3; k++) {
    ctr[k] = 0.5 * (bmin[k] + bmax[k]);
    r2 += 0.25 * (bmax[k] - bmin[k]) * (bmax[k] - bmin[k]);
  }
  double radius = fmax(sqrt(r2), 1e-6);
  double half_y = 0.5 * c->fov * VIEW_PI / 180.0;
  double half_x = atan(tan(half_y) * (double)c->width / (double)c->height);
  double dist = 1.05 * radius / sin(fmin(half_x, half_y));
  double dir[3] = {0.0, 0.25, -1.0};
  normalize3d(dir);
  if (!c->has_look)
    for (int k = 0; k < 3; k++) c->look[k] = (float)ctr[k];
  if (!c->has_pos)
    for (int k = 0; k < 3; k++) c->pos[k] = (float)(ctr[k] + dist * dir[k]);
  c->has_pos = c->has_look = 1;
}

/* ------------------------------------------------------------------------- */
/* the volume: every grid on one dense box                                    */

enum { G_RAD = 0, G_IOR, G_EXT, G_SCA, G_COUNT };

typedef struct view_volume {
  int nx, ny, nz;
  double i2w[3][4], w2i[3][4]; /* index (cell centre) <-> world */
  double voxel_size;           /* world length of one index step */
  int empty;                   /* no grid has active voxels: the image is the background */
  float *medium;               /* 4 per voxel: S = σs L̄ (RGB), σt when grey; per voxel length */
  float *sigma_t4;             /* 4 per voxel: σt (RGB) when RGB and not homogeneous */
  int sigma_ch;                /* 1: grey coefficients, 3: RGB */
  int homogeneous;             /* RGB σt constant: st_const */
  float st_const[3];
  float *ior;                  /* NULL: n = 1 */
  float *ng;                   /* refraction only: {∇n per voxel length, n} per voxel */
  int refraction;
  float n_min, n_max;
  oct_pyramid_t npyr;          /* refraction only: constant blocks of n */
  oct_pyramid_t mpyr;          /* constant blocks of the medium */
  char desc[512];              /* what was read, for -v */
} view_volume_t;

/* Zeroed and page-aligned, so PoCL can use the array in place as a buffer
 * (CL_MEM_USE_HOST_PTR) instead of copying tens of MB; freed with free(). */
#define VIEW_ALIGN 4096
static void *view_alloc(size_t count, size_t size, const char *what, bk_error_t *err) {
  size_t bytes;
  void *p = NULL;
  if (!bk_mul_size(count, size, &bytes) || posix_memalign(&p, VIEW_ALIGN, bytes ? bytes : 1)) {
    bk_fail(err, BK_ERR_RUNTIME, "%s: cannot allocate %zu x %zu bytes", what, count, size);
    return NULL;
  }
  memset(p, 0, bytes);
  return p;
}

static void volume_free(view_volume_t *v) {
  free(v->medium);
  free(v->sigma_t4);
  free(v->ior);
  free(v->ng);
  oct_free(&v->npyr);
  oct_free(&v->mpyr);
  memset(v, 0, sizeof *v);
}

static int find_name(char **names, int count, const char *name) {
  for (int i = 0; i < count; i++)
    if (!strcmp(names[i], name)) return i;
  return -1;
}
static int is_scalar_type(const char *t) { return !strcmp(t, "float") || !strcmp(t, "double"); }
static int is_vec3_type(const char *t) { return !strcmp(t, "vec3s") || !strcmp(t, "vec3d"); }

static int dense_is_empty(const vdbio_dense_t *d) {
  if (d->nx != 1 || d->ny != 1 || d->nz != 1) return 0;
  for (int c = 0; c < d->channels; c++)
    if (d->data[c] != 0.0f) return 0;
  return 1;
}

/* Map p (3-vector) through a 3x4 affine matrix. */
static void affine_apply(const double m[3][4], const double p[3], double out[3]) {
  for (int r = 0; r < 3; r++) out[r] = m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3];
}

/* The linear part of i2w must be s·(rotation or reflection). */
static int check_similarity(const double m[3][4], const char *path, double *scale,
                            bk_error_t *err) {
  double col[3][3], len[3];
  for (int c = 0; c < 3; c++) {
    for (int r = 0; r < 3; r++) col[c][r] = m[r][c];
    len[c] = sqrt(dot3d(col[c], col[c]));
  }
  double s = (len[0] + len[1] + len[2]) / 3.0;
  int ok = s > 0.0 && isfinite(s);
  for (int c = 0; c < 3 && ok; c++) {
    if (fabs(len[c] - s) > 1e-5 * s) ok = 0;
    for (int d = c + 1; d < 3; d++)
      if (fabs(dot3d(col[c], col[d])) > 1e-5 * s * s) ok = 0;
  }
  if (!ok)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: grid \"radiance\" has a transform with non-uniform scale or shear "
                   "(index axes of world length %g, %g, %g); the viewing pass needs cubic "
                   "voxels (translation, rotation and uniform scale only)",
                   path, len[0], len[1], len[2]);
  *scale = s;
  return BK_OK;
}

/* Moves grid `d` (own box) onto the `like` box: a plain copy when its voxels
 * coincide with like's (same axes and size, integer offset), d's own array
 * when the boxes are the same; *out stays NULL otherwise, and the caller
 * resamples. Cells of like outside d's box are 0, the fog background. */
static int place_aligned(vdbio_dense_t *d, const vdbio_dense_t *like, float **out,
                         bk_error_t *err) {
  double m[3][3], off[3], zero[3] = {0, 0, 0}, w0[3];
  *out = NULL;
  affine_apply(d->index_to_world, zero, w0);
  affine_apply(like->world_to_index, w0, off);
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) {
      m[r][c] = 0.0;
      for (int k = 0; k < 3; k++) m[r][c] += like->world_to_index[r][k] * d->index_to_world[k][c];
      if (fabs(m[r][c] - (r == c ? 1.0 : 0.0)) > 1e-6) return BK_OK;
    }
  int o[3];
  for (int r = 0; r < 3; r++) {
    if (fabs(off[r] - nearbyint(off[r])) > 1e-4) return BK_OK;
    o[r] = (int)nearbyint(off[r]);
  }
  const int ch = d->channels;
  if (o[0] == 0 && o[1] == 0 && o[2] == 0 && d->nx == like->nx && d->ny == like->ny &&
      d->nz == like->nz) { /* the same box (the usual case): take the array, no copy */
    *out = d->data;
    d->data = NULL;
    return BK_OK;
  }
  size_t count = (size_t)like->nx * like->ny * like->nz;
  float *a = bk_calloc(count, sizeof(float) * (size_t)ch, "view: dense grid", err);
  if (!a) return BK_ERR_RUNTIME;
  for (int k = 0; k < d->nz; k++) {
    int K = k + o[2];
    if (K < 0 || K >= like->nz) continue;
    for (int j = 0; j < d->ny; j++) {
      int J = j + o[1];
      if (J < 0 || J >= like->ny) continue;
      for (int i = 0; i < d->nx; i++) {
        int I = i + o[0];
        if (I < 0 || I >= like->nx) continue;
        size_t src = ((size_t)i + (size_t)d->nx * ((size_t)j + (size_t)d->ny * k)) * ch;
        size_t dst = ((size_t)I + (size_t)like->nx * ((size_t)J + (size_t)like->ny * K)) * ch;
        memcpy(a + dst, d->data + src, sizeof(float) * (size_t)ch);
      }
    }
  }
  *out = a;
  return BK_OK;
}

/* Refuses NaN/inf anywhere and negative coefficients. */
static int check_values(const char *path, const char *name, const float *a, size_t n,
                        int nonneg, bk_error_t *err) {
  size_t bad = 0, neg = 0;
  float most_neg = 0.0f;
  for (size_t i = 0; i < n; i++) {
    if (!isfinite(a[i])) bad++;
    else if (nonneg && a[i] < 0.0f) {
      neg++;
      if (a[i] < most_neg) most_neg = a[i];
    }
  }
  if (bad)
    return bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" holds %zu NaN or infinite values",
                   path, name, bad);
  if (neg)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: grid \"%s\" holds %zu negative values (down to %g); expected "
                   "coefficients >= 0", path, name, neg, most_neg);
  return BK_OK;
}

/* The medium's constant blocks: S = σs L̄ and σt constant over a block and
 * the one voxel around it that trilinear sampling reads (one step crosses
 * it). Built before padding. */
static size_t pyr_bytes(const oct_pyramid_t *p) {
  return p->level ? (size_t)p->bx * p->by * p->bz : 16;
}

static int build_medium_pyramid(view_volume_t *v, bk_error_t *err) {
  oct_source_t src[2] = {{v->medium, 4, 4}, {v->sigma_t4, 4, 3}};
  return oct_build_fields(v->nx, v->ny, v->nz, src, v->sigma_t4 ? 2 : 1, 1, 0.0f, &v->mpyr, err);
}

/* Replaces an unpadded 4-float field by its padded copy (kernels/ray_core.h). */
static int pad_field(const view_volume_t *v, float **a, bk_error_t *err) {
  if (!*a) return BK_OK;
  float *o = view_alloc(fld_padded_count(v->nx, v->ny, v->nz), 4 * sizeof(float),
                        "view: padded field", err);
  if (!o) return BK_ERR_RUNTIME;
  fld_pad4(v->nx, v->ny, v->nz, *a, o);
  free(*a);
  *a = o;
  return BK_OK;
}

/* Expands a 1-channel array to 3 (replacing it). */
static int expand_to_rgb(float **a, size_t n, bk_error_t *err) {
  float *o = bk_calloc(n, 3 * sizeof(float), "view: coefficients", err);
  if (!o) return BK_ERR_RUNTIME;
  for (size_t i = 0; i < n; i++) o[3 * i] = o[3 * i + 1] = o[3 * i + 2] = (*a)[i];
  free(*a);
  *a = o;
  return BK_OK;
}

/* All entries of a (n voxels x ch) equal: fills c[3]. */
static int is_constant(const float *a, size_t n, int ch, float c[3]) {
  for (int k = 0; k < 3; k++) c[k] = a[ch == 1 ? 0 : k];
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < ch; k++)
      if (a[i * ch + k] != c[k]) return 0;
  return 1;
}

static int volume_load(const char *path, view_volume_t *v, bk_error_t *err) {
  char **names = NULL, **types = NULL;
  int count = 0, rc;
  vdbio_dense_t own[G_COUNT], like;
  float *arr[G_COUNT] = {NULL, NULL, NULL, NULL};
  int ch[G_COUNT] = {0, 0, 0, 0}, present[G_COUNT] = {0, 0, 0, 0}, empty[G_COUNT] = {0};
  const char *gname[G_COUNT] = {"radiance", "ior", "extinction", "scattering"};
  memset(own, 0, sizeof own);
  memset(v, 0, sizeof *v);

  if ((rc = vdbio_list_grids(path, &names, &types, &count, err))) return rc;
  /* which grids, and of which types */
  int idx[G_COUNT];
  for (int g = 0; g < G_COUNT; g++) idx[g] = find_name(names, count, gname[g]);
  if (idx[G_EXT] < 0 && (idx[G_EXT] = find_name(names, count, "density")) >= 0)
    gname[G_EXT] = "density";
  if (idx[G_RAD] < 0) {
    char list[1024] = "";
    for (int i = 0; i < count; i++)
      snprintf(list + strlen(list), sizeof list - strlen(list), "%s\"%s\" (%s)", i ? ", " : "",
               names[i], types[i]);
    rc = bk_fail(err, BK_ERR_INPUT,
                 "%s: no \"radiance\" grid, which `baker view` renders (the Vec3f grid `baker "
                 "bake` writes); the file has %s", path, count ? list : "no grids");
    goto error;
  }
  for (int g = 0; g < G_COUNT; g++) {
    if (idx[g] < 0) continue;
    const char *t = types[idx[g]];
    int ok = g == G_RAD ? is_vec3_type(t)
             : g == G_IOR ? is_scalar_type(t)
                          : (is_scalar_type(t) || is_vec3_type(t));
    if (!ok) {
      rc = bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" holds %s values, expected %s", path,
                   gname[g], t,
                   g == G_RAD ? "Vec3f (vec3s) radiance" : g == G_IOR ? "float" : "float or Vec3f");
      goto error;
    }
    present[g] = 1;
  }

  /* each grid over its own active box */
  for (int g = 0; g < G_COUNT; g++) {
    if (!present[g]) continue;
    if ((rc = vdbio_read_dense(path, gname[g], 0, &own[g], err))) goto error;
    ch[g] = own[g].channels;
    empty[g] = dense_is_empty(&own[g]);
  }
  double scale = 1.0;
  if ((rc = check_similarity(own[G_RAD].index_to_world, path, &scale, err))) goto error;

  /* the union of the non-empty boxes, in radiance index space */
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  int any = 0;
  for (int g = 0; g < G_COUNT; g++) {
    if (!present[g] || empty[g]) continue;
    any = 1;
    const vdbio_dense_t *d = &own[g];
    for (int c = 0; c < 8; c++) {
      double p[3] = {(c & 1) ? d->nx - 0.5 : -0.5, (c & 2) ? d->ny - 0.5 : -0.5,
                     (c & 4) ? d->nz - 0.5 : -0.5};
      double w[3], u[3];
      affine_apply(d->index_to_world, p, w);
      affine_apply(own[G_RAD].world_to_index, w, u);
      for (int k = 0; k < 3; k++) {
        lo[k] = fmin(lo[k], u[k]);
        hi[k] = fmax(hi[k], u[k]);
      }
    }
  }
  like = own[G_RAD];
  like.data = NULL;
  if (!any) {
    v->empty = 1;
    like.nx = like.ny = like.nz = 1;
  } else {
    int ilo[3], n[3];
    for (int k = 0; k < 3; k++) {
      ilo[k] = (int)floor(lo[k] + 0.5 + 1e-6);
      int ihi = (int)ceil(hi[k] - 0.5 - 1e-6);
      n[k] = ihi - ilo[k] + 1;
      if (n[k] < 1 || n[k] > GRID_MAX_AXIS) {
        rc = bk_fail(err, BK_ERR_INPUT, "%s: the grids span %d voxels along axis %d (at most %d)",
                     path, n[k], k, GRID_MAX_AXIS);
        goto error;
      }
    }
    double shift[3] = {ilo[0], ilo[1], ilo[2]}, t[3];
    for (int r = 0; r < 3; r++) {
      t[r] = 0.0;
      for (int c = 0; c < 3; c++) t[r] += own[G_RAD].index_to_world[r][c] * shift[c];
      like.index_to_world[r][3] += t[r];
      like.world_to_index[r][3] -= shift[r];
    }
    like.nx = n[0];
    like.ny = n[1];
    like.nz = n[2];
  }
  grid_dims_t gd = {like.nx, like.ny, like.nz, (float)scale, {0, 0, 0}};
  /* peak: the grids as read (up to 10 floats), ng, medium, σt and a padded copy */
  if ((rc = grid_check_memory(&gd, 24 * sizeof(float), path, err))) goto error;

  /* every grid onto the like box: copied when aligned, else resampled */
  for (int g = 0; g < G_COUNT; g++) {
    if (!present[g] || v->empty) continue;
    if ((rc = place_aligned(&own[g], &like, &arr[g], err))) goto error;
    if (!arr[g]) {
      vdbio_dense_t r;
      int found = 0;
      if ((rc = vdbio_read_dense_like(path, gname[g], &like, &r, &found, err))) goto error;
      if (!found) {
        rc = bk_fail(err, BK_ERR_RUNTIME, "%s: grid \"%s\" vanished while reading", path, gname[g]);
        goto error;
      }
      arr[g] = r.data;
    }
    vdbio_dense_free(&own[g]);
  }

  v->nx = like.nx;
  v->ny = like.ny;
  v->nz = like.nz;
  memcpy(v->i2w, like.index_to_world, sizeof v->i2w);
  memcpy(v->w2i, like.world_to_index, sizeof v->w2i);
  v->voxel_size = scale;
  size_t nvox = (size_t)v->nx * v->ny * v->nz;
  snprintf(v->desc, sizeof v->desc, "%dx%dx%d voxels of %g; radiance", v->nx, v->ny, v->nz, scale);
  for (int g = 1; g < G_COUNT; g++)
    if (present[g])
      snprintf(v->desc + strlen(v->desc), sizeof v->desc - strlen(v->desc), ", %s (%s)", gname[g],
               ch[g] == 1 ? "float" : "Vec3f");
  if (v->empty) goto done;

  for (int g = 0; g < G_COUNT; g++)
    if (arr[g] && (rc = check_values(path, gname[g], arr[g], nvox * (size_t)ch[g],
                                     g == G_EXT || g == G_SCA, err)))
      goto error;

  /* n: values below 1 are background (0) or nonsense; n >= 1 by contract */
  if (arr[G_IOR]) {
    v->ior = arr[G_IOR];
    arr[G_IOR] = NULL;
    v->n_min = 1e30f;
    v->n_max = -1e30f;
    for (size_t i = 0; i < nvox; i++) {
      float n = v->ior[i] < 1.0f ? 1.0f : v->ior[i];
      v->ior[i] = n;
      v->n_min = n < v->n_min ? n : v->n_min;
      v->n_max = n > v->n_max ? n : v->n_max;
    }
    v->refraction = v->n_max - v->n_min > VIEW_N_EPS;
    if (v->refraction) {
      const oct_source_t n = {v->ior, 1, 1};
      v->ng = fld_build(v->nx, v->ny, v->nz, v->voxel_size, v->ior, err);
      if (!v->ng || (rc = oct_build_fields(v->nx, v->ny, v->nz, &n, 1, OCT_HALO, 0.0f,
                                           &v->npyr, err))) {
        rc = BK_ERR_RUNTIME;
        goto error;
      }
    }
  } else {
    v->n_min = v->n_max = 1.0f;
  }

  /* coefficients: σs absent -> σt; σt absent -> σs; both absent -> 0 */
  if (!arr[G_EXT] && arr[G_SCA]) {
    arr[G_EXT] = arr[G_SCA];
    ch[G_EXT] = ch[G_SCA];
    arr[G_SCA] = NULL;
  }
  if (!arr[G_EXT])
    bk_warn("%s: no extinction, density or scattering grid: the medium is transparent and the "
            "image shows only the background", path);
  if (arr[G_EXT] && arr[G_SCA] && ch[G_SCA] != ch[G_EXT]) {
    int g = ch[G_SCA] == 1 ? G_SCA : G_EXT;
    if ((rc = expand_to_rgb(&arr[g], nvox, err))) goto error;
    ch[g] = 3;
  }
  v->sigma_ch = arr[G_EXT] ? ch[G_EXT] : 1;
  const float *ext = arr[G_EXT], *sca = arr[G_SCA] ? arr[G_SCA] : arr[G_EXT];
  const float *rad = arr[G_RAD];
  const int sc = v->sigma_ch;
  /* pack {S = σs L̄, σt (grey)} and, for RGB, {σt}; σ per voxel length */
  v->medium = view_alloc(nvox, 4 * sizeof(float), "view: medium", err);
  if (!v->medium) {
    rc = BK_ERR_RUNTIME;
    goto error;
  }
  for (size_t i = 0; i < nvox; i++)
    for (int c = 0; c < 3; c++)
      v->medium[4 * i + c] =
          sca ? (float)scale * sca[i * sc + (sc == 3 ? c : 0)] * rad[3 * i + c] : 0.0f;
  if (sc == 1) {
    if (ext)
      for (size_t i = 0; i < nvox; i++) v->medium[4 * i + 3] = (float)scale * ext[i];
  } else {
    v->homogeneous = is_constant(ext, nvox, 3, v->st_const);
    for (int c = 0; c < 3; c++) v->st_const[c] *= (float)scale;
    if (!v->homogeneous) {
      v->sigma_t4 = view_alloc(nvox, 4 * sizeof(float), "view: extinction", err);
      if (!v->sigma_t4) {
        rc = BK_ERR_RUNTIME;
        goto error;
      }
      for (size_t i = 0; i < nvox; i++)
        for (int c = 0; c < 3; c++) v->sigma_t4[4 * i + c] = (float)scale * ext[3 * i + c];
    }
  }
  /* the grids as read are packed now: free them before padding (peak memory) */
  for (int g = 0; g < G_COUNT; g++) free(arr[g]), arr[g] = NULL;
  if ((rc = build_medium_pyramid(v, err)) || (rc = pad_field(v, &v->medium, err)) ||
      (rc = pad_field(v, &v->sigma_t4, err)))
    goto error;

done:
  rc = BK_OK;
error:
  for (int g = 0; g < G_COUNT; g++) {
    vdbio_dense_free(&own[g]);
    free(arr[g]);
  }
  vdbio_free_names(names, types, count);
  if (rc) volume_free(v);
  return rc;
}

/* World bounding box of the volume's cells. */
static void volume_world_box(const view_volume_t *v, double bmin[3], double bmax[3]) {
  for (int k = 0; k < 3; k++) bmin[k] = 1e300, bmax[k] = -1e300;
  for (int c = 0; c < 8; c++) {
    double p[3] = {(c & 1) ? v->nx - 0.5 : -0.5, (c & 2) ? v->ny - 0.5 : -0.5,
                   (c & 4) ? v->nz - 0.5 : -0.5};
    double w[3];
    affine_apply(v->i2w, p, w);
    for (int k = 0; k < 3; k++) bmin[k] = fmin(bmin[k], w[k]), bmax[k] = fmax(bmax[k], w[k]);
  }
}

/* ------------------------------------------------------------------------- */
/* rendering                                                                  */

typedef struct view_gpu {
  clh_context_t cl;
  int ready;
  int host;            /* --device host: kernels/view_march.h in plain C, no OpenCL */
  cl_program program;
  cl_kernel kernel;
  char options[256];
} view_gpu_t;

typedef struct view_totals {
  double read_ms, build_ms, upload_ms, march_ms, write_ms;
  double march_cpu_ms; /* CPU time of the whole process (all device threads) while marching */
  uint64_t ray_steps, pixels, capped;
  int frames;
  char last_options[256];
} view_totals_t;

static void gpu_release(view_gpu_t *g) {
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

static void setup_params(const view_volume_t *v, const view_cam_t *c, const float bg[3],
                         float step, view_params_t *p) {
  memset(p, 0, sizeof *p);
  double pos[3] = {c->pos[0], c->pos[1], c->pos[2]}, f[3], r[3], u[3],
         up[3] = {c->up[0], c->up[1], c->up[2]};
  for (int k = 0; k < 3; k++) f[k] = (double)c->look[k] - c->pos[k];
  normalize3d(f);
  cross3d(f, up, r);
  normalize3d(r);
  cross3d(r, f, u);
  double th = tan(0.5 * c->fov * VIEW_PI / 180.0), aspect = (double)c->width / c->height;
  double rs[3], us[3], pu[3];
  for (int k = 0; k < 3; k++) rs[k] = r[k] * th * aspect, us[k] = u[k] * th;
  affine_apply(v->w2i, pos, pu);
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
  const view_fields f = {v->medium, v->sigma_t4, v->ng, v->npyr.level, v->mpyr.level};
  const view_flags fl = {v->refraction, v->sigma_ch == 1, integrator, v->homogeneous};
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

/* Renders one image into rgba (width*height*4 floats). */
static int render(view_gpu_t *g, const view_volume_t *v, const view_cam_t *c, const float bg[3],
                  int integrator, float step, float *rgba, view_totals_t *tot, bk_error_t *err) {
  const size_t npix = (size_t)c->width * (size_t)c->height;
  int rc = BK_OK;
  cl_mem b[8] = {0};
  err->code = BK_OK;
  bk_uint *steps = NULL;
  view_params_t p;
  setup_params(v, c, bg, step, &p);

  if (v->empty) { /* nothing in the file but background */
    for (size_t i = 0; i < npix; i++) {
      rgba[4 * i] = bg[0], rgba[4 * i + 1] = bg[1], rgba[4 * i + 2] = bg[2];
      rgba[4 * i + 3] = 0.0f;
    }
    return BK_OK;
  }
  if (g->host) return render_host(v, &p, integrator, rgba, tot);

  double t0 = bk_now_ms();
  char opts[256];
  snprintf(opts, sizeof opts,
           "-DHAS_REFRACTION=%d -DINTEGRATOR=%d -DGREY=%d -DHOMOGENEOUS=%d", v->refraction,
           integrator, v->sigma_ch == 1, v->homogeneous);
  if (!g->kernel || strcmp(opts, g->options) != 0) {
    if (g->kernel) clReleaseKernel(g->kernel), g->kernel = NULL;
    if (g->program) clReleaseProgram(g->program), g->program = NULL;
    if ((rc = clh_build(&g->cl, "view.cl", opts, &g->program, err))) goto error;
    cl_int krc;
    g->kernel = clCreateKernel(g->program, "view_render", &krc);
    CLH_CHECK(krc, err, error);
    snprintf(g->options, sizeof g->options, "%s", opts);
    bk_log(2, "view: kernel view.cl built with %s", opts);
  }
  snprintf(tot->last_options, sizeof tot->last_options, "%s", opts);
  double t1 = bk_now_ms();
  tot->build_ms += t1 - t0;

  const size_t npad = ((size_t)v->nx + 2) * ((size_t)v->ny + 2) * ((size_t)v->nz + 2);
  const cl_mem_flags ro = CL_MEM_READ_ONLY;
  if (!(b[0] = make_buffer(g, v->medium, npad * 4 * sizeof(float), ro, "medium", err)) ||
      !(b[1] = make_buffer(g, v->sigma_t4, v->sigma_t4 ? npad * 4 * sizeof(float) : 16, ro,
                           "extinction", err)) ||
      !(b[2] = make_buffer(g, v->ng, v->ng ? npad * 4 * sizeof(float) : 16, ro, "ior", err)) ||
      !(b[3] = make_buffer(g, v->npyr.level, pyr_bytes(&v->npyr), ro, "constant blocks of n", err)) ||
      !(b[4] = make_buffer(g, v->mpyr.level, pyr_bytes(&v->mpyr), ro, "constant blocks", err)) ||
      !(b[5] = make_buffer(g, NULL, npix * 4 * sizeof(float), CL_MEM_WRITE_ONLY, "image", err)) ||
      !(b[6] =
            make_buffer(g, NULL, npix * sizeof(bk_uint), CL_MEM_WRITE_ONLY, "step counts", err))) {
    rc = err->code ? err->code : BK_ERR_RUNTIME;
    goto error;
  }
  CLH_CHECK(clSetKernelArg(g->kernel, 0, sizeof p, &p), err, error);
  for (int a = 0; a < 7; a++)
    CLH_CHECK(clSetKernelArg(g->kernel, (cl_uint)a + 1, sizeof(cl_mem), &b[a]), err, error);
  CLH_CHECK(clFinish(g->cl.queue), err, error);
  double t2 = bk_now_ms(), c2 = cpu_ms();
  tot->upload_ms += t2 - t1;

  /* in bands of rows, so a long render shows progress */
  bk_progress_t prog;
  bk_progress_begin(&prog, "view: marching", (uint64_t)c->height);
  /* one launch unless progress is shown: each launch ends on its slowest
   * work-group while the other cores wait */
  int nbands = prog.enabled ? VIEW_BANDS : 1;
  int band = (c->height + nbands - 1) / nbands;
  for (int y0 = 0; y0 < c->height; y0 += band) {
    size_t off[2] = {0, (size_t)y0};
    /* every band the same size (the kernel skips rows past the image), so
     * PoCL compiles one work-group function, not one per band height */
    size_t gsz[2] = {(size_t)c->width, (size_t)band};
    CLH_CHECK(clEnqueueNDRangeKernel(g->cl.queue, g->kernel, 2, off, gsz, NULL, 0, NULL, NULL), err,
              error);
    CLH_CHECK(clFinish(g->cl.queue), err, error);
    bk_progress_update(&prog, (uint64_t)(y0 + band < c->height ? y0 + band : c->height));
  }
  bk_progress_end(&prog);
  steps = bk_calloc(npix, sizeof *steps, "view: step counts", err);
  if (!steps) {
    rc = BK_ERR_RUNTIME;
    goto error;
  }
  CLH_CHECK(clEnqueueReadBuffer(g->cl.queue, b[5], CL_TRUE, 0, npix * 4 * sizeof(float), rgba, 0,
                                NULL, NULL),
            err, error);
  CLH_CHECK(clEnqueueReadBuffer(g->cl.queue, b[6], CL_TRUE, 0, npix * sizeof(bk_uint), steps, 0,
                                NULL, NULL),
            err, error);
  tot->march_ms += bk_now_ms() - t2;
  tot->march_cpu_ms += cpu_ms() - c2;
  for (size_t i = 0; i < npix; i++) {
    tot->ray_steps += steps[i];
    if (v->refraction && steps[i] >= (bk_uint)p.max_steps) tot->capped++;
  }
  tot->pixels += npix;

error:
  if (rc == BK_OK) rc = err->code; /* set by CLH_CHECK */
  for (int a = 0; a < 7; a++)
    if (b[a]) clReleaseMemObject(b[a]);
  free(steps);
  return rc;
}

/* ------------------------------------------------------------------------- */
/* the command                                                                */

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

static int write_images(const char *in, const char *out, const char *png, const view_cam_t *c,
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
  int rc = exr_write_rgba(out, c->width, c->height, rgba, &info, err);
  if (!rc && png) rc = png_write_preview(png, c->width, c->height, rgba, exposure, err);
  return rc;
}

int view_main(int argc, char **argv) {
  bk_error_t err;
  view_opts_t o;
  scene_t scene;
  view_gpu_t gpu;
  view_volume_t vol;
  view_totals_t tot;
  view_cam_t cam;
  float *rgba = NULL;
  int have_scene = 0;
  memset(&err, 0, sizeof err);
  memset(&gpu, 0, sizeof gpu);
  memset(&vol, 0, sizeof vol);
  memset(&tot, 0, sizeof tot);

  int rc = parse_args(argc, argv, &o, &err);
  if (rc == -1) {
    view_usage(stdout);
    return BK_OK;
  }
  if (rc) {
    fprintf(stderr, "baker view: %s\n", err.msg);
    return rc;
  }
  if (o.device && !strcmp(o.device, "list")) {
    clh_list_devices(stdout);
    return BK_OK;
  }
  if (o.scene) {
    if ((rc = scene_load(o.scene, &scene, &err))) goto done;
    have_scene = 1;
  }
  cam_from_inputs(&o, have_scene ? &scene : NULL, &cam);
  if ((rc = cam_validate(&cam, &err))) goto done;
  float bg[3] = {0.0f, 0.0f, 0.0f};
  if (o.has_bg)
    memcpy(bg, o.bg, sizeof bg);
  else if (have_scene)
    memcpy(bg, scene.background, sizeof bg);
  int integrator = o.has_integrator ? o.integrator
                   : have_scene && scene.integrator == INTEGRATOR_RK4 ? VIEW_RK4 : VIEW_EULER;
  float step = o.step;
  if (!o.has_step && have_scene) {
    step = bk_clampf(scene.step, VIEW_STEP_MIN, VIEW_STEP_MAX);
    if (step != scene.step)
      bk_warn("%s: photons.step %g voxels is outside [%g, %g] for camera rays; using %g",
              scene.path, scene.step, VIEW_STEP_MIN, VIEW_STEP_MAX, step);
  }

  /* every frame's input must exist and every output directory be writable
   * before the first image is rendered */
  frames_range_t fr = {0, 0, 1};
  if (o.has_frames) fr = o.frames;
  const int nframes = frames_count(&fr);
  char in[VIEW_PATH_MAX], out[VIEW_PATH_MAX], png[VIEW_PATH_MAX];
  for (int f = 0; f < nframes; f++) {
    int frame = frames_at(&fr, f);
    if ((rc = frames_expand(o.in, frame, in, sizeof in, &err)) ||
        (rc = frames_expand(o.out, frame, out, sizeof out, &err)) ||
        (o.png && (rc = frames_expand(o.png, frame, png, sizeof png, &err))))
      goto done;
    if (access(in, R_OK) != 0) {
      rc = bk_fail(&err, BK_ERR_INPUT, "%s: cannot open VDB file: %s%s", in, strerror(errno),
                   o.has_frames ? " (frame pattern expanded with --frames)" : "");
      goto done;
    }
    if ((rc = bk_check_output_dir(out, &err)) || (o.png && (rc = bk_check_output_dir(png, &err))))
      goto done;
  }
  size_t npix = (size_t)cam.width * (size_t)cam.height, bytes;
  uint64_t mem = bk_physical_memory();
  if (!bk_mul_size(npix, 5 * sizeof(float), &bytes) || (mem && bytes > mem / 2)) {
    char b[32];
    rc = bk_fail(&err, BK_ERR_INPUT, "%s: a %dx%d image needs %s, more than half this machine's "
                 "memory", cam.src, cam.width, cam.height,
                 bk_format_bytes((double)npix * 5 * sizeof(float), b, sizeof b));
    goto done;
  }
  rgba = bk_calloc(npix, 4 * sizeof(float), "view: image", &err);
  if (!rgba) {
    rc = BK_ERR_RUNTIME;
    goto done;
  }

  for (int f = 0; f < nframes; f++) {
    int frame = frames_at(&fr, f);
    frames_expand(o.in, frame, in, sizeof in, &err);
    frames_expand(o.out, frame, out, sizeof out, &err);
    if (o.png) frames_expand(o.png, frame, png, sizeof png, &err);

    double t0 = bk_now_ms();
    if ((rc = volume_load(in, &vol, &err))) goto done;
    tot.read_ms += bk_now_ms() - t0;
    bk_log(2, "view: %s: %s%s; n in [%g, %g]%s", in, vol.desc, vol.empty ? " (all empty)" : "",
           vol.n_min, vol.n_max, vol.refraction ? ", refracting" : "");
    if (f == 0) { /* a default camera is framed on the first frame and kept */
      double bmin[3], bmax[3];
      volume_world_box(&vol, bmin, bmax);
      cam_fill_default(&cam, bmin, bmax);
      if ((rc = cam_validate(&cam, &err))) goto done;
      bk_log(2, "view: camera at (%g, %g, %g) looking at (%g, %g, %g), vertical fov %g deg, %dx%d",
             cam.pos[0], cam.pos[1], cam.pos[2], cam.look[0], cam.look[1], cam.look[2], cam.fov,
             cam.width, cam.height);
    }
    if (!vol.empty && !gpu.ready && o.device && !strcmp(o.device, "host")) {
      gpu.host = gpu.ready = 1;
    } else if (!vol.empty && !gpu.ready) {
      if ((rc = clh_init(&gpu.cl, o.device, &err))) goto done;
      gpu.ready = 1;
      bk_log(2, "view: OpenCL device %s (%s)", gpu.cl.device_name, gpu.cl.platform_name);
    }
    if ((rc = render(&gpu, &vol, &cam, bg, integrator, step, rgba, &tot, &err))) goto done;
    t0 = bk_now_ms();
    if ((rc = write_images(in, out, o.png ? png : NULL, &cam, rgba, o.has_frames, frame,
                           o.exposure, integrator, step, &err)))
      goto done;
    tot.write_ms += bk_now_ms() - t0;
    tot.frames++;
    if (bk_verbosity >= 1)
      printf("view: %s -> %s%s%s (%dx%d)\n", in, out, o.png ? ", " : "", o.png ? png : "",
             cam.width, cam.height);
    volume_free(&vol);
  }

  /* a handful of grazing rays circulate inside a smoothed interface where
   * the discrete field lets them (the photons do the same); many is news */
  if (tot.capped)
    bk_log(tot.capped * 10000 > tot.pixels ? 0 : 2,
           "%s: %llu of %llu camera rays stopped at the step limit (trapped by total internal "
           "reflection)", tot.capped * 10000 > tot.pixels ? "warning" : "view",
           (unsigned long long)tot.capped, (unsigned long long)tot.pixels);
  if (bk_verbosity >= 1) {
    bk_timings_t t;
    memset(&t, 0, sizeof t);
    double msteps = tot.march_ms > 0 ? (double)tot.ray_steps / (tot.march_ms * 1e3) : 0.0;
    bk_timings_add(&t, "read", tot.read_ms, "%d frame%s", tot.frames, tot.frames == 1 ? "" : "s");
    bk_timings_add(&t, "build kernel", tot.build_ms, "%s", tot.last_options);
    bk_timings_add(&t, "upload", tot.upload_ms, NULL);
    /* CPU time too: on a shared machine wall time says little about the kernel */
    bk_timings_add(&t, "march", tot.march_ms,
                   "%llu ray-steps, %.2f M ray-steps/s, %llu rays, %.0f ms CPU",
                   (unsigned long long)tot.ray_steps, msteps, (unsigned long long)tot.pixels,
                   tot.march_cpu_ms);
    bk_timings_add(&t, "write", tot.write_ms, o.png ? "EXR + PNG" : "EXR");
    bk_timings_print(&t, stdout); /* as `baker bake` does: the report, not a diagnostic */
    fflush(stdout);
  }
  rc = BK_OK;

done:
  if (rc) fprintf(stderr, "baker view: %s\n", err.msg);
  volume_free(&vol);
  gpu_release(&gpu);
  free(rgba);
  if (have_scene) scene_free(&scene);
  return rc;
}
