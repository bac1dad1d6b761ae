/* scene.c: loads the scene file (DESIGN.md §4) and validates every key.
 *
 * The JSON tree keeps the position of each value, so every message reads
 * "scene.json:LINE:COL: key.path: expected WHAT, found WHAT", pointing at the
 * value the user has to change. Key paths are built as the user wrote them
 * (`lights[0].angle_deg`, `grid.bounds[1][2]`). */
#include "scene.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "integrators.h"
#include "lights.h"
#include "scene_values.h"

static const sc_range_t R_ANY = {-SC_NOLIM, SC_NOLIM, 0, 0, 0, 1};
static const sc_range_t R_NONNEG = {0, SC_NOLIM, 0, 0, 0, 1};
static const sc_range_t R_POSITIVE = {0, SC_NOLIM, 1, 0, 0, 1};
/* Light intensity (W/sr) and irradiance (W/m^2), refused at load rather
 * than caught as Inf after the bake: a voxel's radiance can exceed the
 * light's value by the path bound over the squared voxel size (march.c's
 * fixed-point scale: L <= I * path / h^2), and at 1e38 even the photon power
 * overflows a float, so the bake would run for nothing. 1e20 leaves a factor
 * 3e18 below FLT_MAX for that geometry (voxels down to 1 um, paths up to 1e6
 * voxels) and is 1e16 times a lighthouse. */
static const sc_range_t R_LIGHT = {0, 1e20, 0, 0, 0, 0};
static const sc_range_t R_IOR = {1, 10, 0, 0, 0, 0};
static const sc_range_t R_SMOOTHING = {0, 64, 1, 0, 0, 0};
static const sc_range_t R_ANGLE = {0, 90, 1, 0, 0, 0};
static const sc_range_t R_FOV = {0, 180, 1, 1, 0, 0};
static const sc_range_t R_COUNT_INT = {1, INT_MAX, 0, 0, 1, 1};
static const sc_range_t R_PIXELS = {1, 16384, 0, 0, 1, 0};
static const sc_range_t R_SEED = {0, 4294967295.0, 0, 0, 1, 0};
/* 2^53: beyond it a JSON number no longer names every integer */
/* photons.bounces: events per photon (kernels/scatter.h), at most SCENE_MAX_BOUNCES */
static const sc_range_t R_BOUNCES = {0, SCENE_MAX_BOUNCES, 0, 0, 1, 0};
/* Henyey–Greenstein g: |g| = 1 is a delta, no scattering at all */
static const sc_range_t R_HG = {-1, 1, 1, 1, 0, 0};
static const sc_range_t R_BATCHES = {1, 65536, 0, 0, 1, 0};
static const sc_range_t R_TARGET_ERROR = {0, 1, 1, 0, 0, 0};
static const sc_range_t R_STEP = {SCENE_MIN_STEP, SC_NOLIM, 0, 0, 0, 1};
static const sc_range_t R_PHOTONS = {1, 9007199254740992.0, 0, 0, 1, 1};

/* --- sections ------------------------------------------------------------- */

static int sc_grid(const sc_ctx_t *c, const json_value_t *g, scene_t *s) {
  static const char *const keys[] = {"bounds", "resolution", "ior_smoothing", "crop_to_objects",
                                     NULL};
  char p[SC_KEY_MAX];
  const json_value_t *b, *res;
  long long r = 0;
  int rc;
  if ((rc = sc_object(c, g, "grid"))) return rc;
  sc_check_keys(c, g, "grid", keys);
  if ((rc = sc_required(c, g, "grid", "bounds", &b))) return rc;
  if (b->type != JSON_ARRAY || b->count != 2)
    return b->type == JSON_ARRAY
               ? sc_fail(c, b, "grid.bounds", "expected [[min x,y,z], [max x,y,z]], found an "
                                              "array of %zu element%s",
                         b->count, b->count == 1 ? "" : "s")
               : sc_fail(c, b, "grid.bounds", "expected [[min x,y,z], [max x,y,z]], found %s",
                         json_type_phrase(b));
  if ((rc = sc_floats(c, b->items[0], "grid.bounds[0]", &R_ANY, 3, 0, s->bounds_min)) ||
      (rc = sc_floats(c, b->items[1], "grid.bounds[1]", &R_ANY, 3, 0, s->bounds_max)))
    return rc;
  for (int a = 0; a < 3; a++) {
    const json_value_t *hi = b->items[1]->items[a];
    snprintf(p, sizeof p, "grid.bounds[1][%d]", a);
    if (!(s->bounds_max[a] > s->bounds_min[a]))
      return sc_fail(c, hi, p, "expected a number > %s (the minimum, grid.bounds[0][%d]), found %s",
                     b->items[0]->items[a]->string, a, hi->string);
    if (!isfinite(s->bounds_max[a] - s->bounds_min[a]))
      return sc_fail(c, hi, p, "expected an extent max - min that fits a float, found %s - %s",
                     hi->string, b->items[0]->items[a]->string);
  }
  if ((rc = sc_required(c, g, "grid", "resolution", &res))) return rc;
  /* the upper limit is grid_check_memory's, which can say how much memory */
  if ((rc = sc_opt_int(c, g, "grid", "resolution", &R_COUNT_INT, &r))) return rc;
  s->resolution = (int)r;
  snprintf(s->where_resolution, sizeof s->where_resolution, "%s:%d:%d: grid.resolution", c->file,
           res->line, res->col);
  if ((rc = sc_opt_bool(c, g, "grid", "crop_to_objects", &s->crop_to_objects))) return rc;
  return sc_opt_float(c, g, "grid", "ior_smoothing", &R_SMOOTHING, &s->ior_smoothing);
}

static int sc_vdb_ref(const sc_ctx_t *c, const json_value_t *obj, const char *parent,
                      const char *key, const char *default_grid, scene_vdb_ref_t *ref) {
  static const char *const keys[] = {"file", "grid", NULL};
  char path[SC_KEY_MAX], p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key), *f;
  int rc;
  if (!v) return BK_OK;
  sc_key(path, parent, key);
  if ((rc = sc_object(c, v, path))) return rc;
  sc_check_keys(c, v, path, keys);
  if ((rc = sc_required(c, v, path, "file", &f)) ||
      (rc = sc_file(c, f, sc_key(p, path, "file"), ref->file, ref->where)))
    return rc;
  snprintf(ref->grid, sizeof ref->grid, "%s", default_grid);
  const json_value_t *g = json_object_get(v, "grid");
  if (g && (rc = sc_string(c, g, sc_key(p, path, "grid"), ref->grid, sizeof ref->grid))) return rc;
  ref->present = 1;
  return BK_OK;
}

static int sc_medium(const sc_ctx_t *c, const json_value_t *m, scene_t *s) {
  static const char *const keys[] = {"sigma_s", "sigma_a", "ior", "g", "density_vdb", "ior_vdb",
                                     NULL};
  int rc;
  if ((rc = sc_object(c, m, "medium"))) return rc;
  sc_check_keys(c, m, "medium", keys);
  if ((rc = sc_opt_floats(c, m, "medium", "sigma_s", &R_NONNEG, 3, 1, s->medium_sigma_s)) ||
      (rc = sc_opt_floats(c, m, "medium", "sigma_a", &R_NONNEG, 3, 1, s->medium_sigma_a)) ||
      (rc = sc_opt_float(c, m, "medium", "ior", &R_IOR, &s->medium_ior)) ||
      (rc = sc_opt_float(c, m, "medium", "g", &R_HG, &s->medium_g)) ||
      (rc = sc_vdb_ref(c, m, "medium", "density_vdb", "density", &s->density_vdb)) ||
      (rc = sc_vdb_ref(c, m, "medium", "ior_vdb", "ior", &s->ior_vdb)))
    return rc;
  return BK_OK;
}

/* A JSON array of at most `max` elements. */
static int sc_array(const sc_ctx_t *c, const json_value_t *v, const char *path, size_t max) {
  if (v->type != JSON_ARRAY)
    return sc_fail(c, v, path, "expected an array, found %s", json_type_phrase(v));
  if (v->count > max)
    return sc_fail(c, v, path, "expected at most %zu elements, found %zu", max, v->count);
  return BK_OK;
}

void scene_dispersion_rgb(float n_d, float abbe, float out[3]) {
  const double C = 1.0 / (0.6563 * 0.6563), d = 1.0 / (0.5876 * 0.5876), F = 1.0 / (0.4861 * 0.4861);
  const double B = ((double)n_d - 1.0) / ((double)abbe * (F - C)); /* Cauchy B, um^2 */
  out[0] = (float)(n_d + B * (C - d));
  out[1] = n_d;
  out[2] = (float)(n_d + B * (F - d));
}

int scene_has_dispersion(const scene_t *s) {
  for (int i = 0; i < s->object_count; i++) {
    const scene_object_t *o = &s->objects[i];
    if (scene_object_n(o, 0) != o->ior || scene_object_n(o, 2) != o->ior) return 1;
  }
  return 0;
}

static int grey3(const float v[3]) { return v[0] == v[1] && v[0] == v[2]; }

int scene_is_grey(const scene_t *s) {
  if (!grey3(s->medium_sigma_s) || !grey3(s->medium_sigma_a)) return 0;
  for (int i = 0; i < s->object_count; i++)
    if (!grey3(s->objects[i].sigma_s) || !grey3(s->objects[i].sigma_a)) return 0;
  return 1;
}

int scene_crops(const scene_t *s) {
  for (int c = 0; c < 3; c++)
    if (s->medium_sigma_s[c] != 0.0f || s->medium_sigma_a[c] != 0.0f) return 0;
  return s->crop_to_objects && s->object_count > 0 && !s->ior_vdb.present;
}

int scene_batches(const scene_t *s, int per_voxel) {
  if (s->batches > 0) return s->batches;
  if (s->target_error > 0.0f || s->time_budget_s > 0.0f) return SCENE_OPEN_BATCHES;
  return per_voxel ? SCENE_VOXEL_BATCHES : SCENE_FIXED_BATCHES;
}

float scene_object_n(const scene_object_t *o, int ch) {
  return ch != 1 && o->ior_rgb[1] > 0.0f ? o->ior_rgb[ch] : o->ior;
}

/* "ior": a number, or [nR, nG, nB] (dispersion given per channel); "abbe":
 * V_d > 0 with a number ior = n_d. */
static int sc_object_ior(const sc_ctx_t *c, const json_value_t *v, const char *path,
                         scene_object_t *o) {
  char p[SC_KEY_MAX];
  const json_value_t *n = json_object_get(v, "ior"), *abbe = json_object_get(v, "abbe");
  int rc;
  if (n && n->type == JSON_ARRAY) {
    if (abbe)
      return sc_fail(c, abbe, sc_key(p, path, "abbe"),
                     "give either \"abbe\" or an array \"ior\" [nR, nG, nB], not both");
    if ((rc = sc_floats(c, n, sc_key(p, path, "ior"), &R_IOR, 3, 0, o->ior_rgb))) return rc;
    o->ior = o->ior_rgb[1];
    return BK_OK;
  }
  if (n && n->type != JSON_NUMBER)
    return sc_fail(c, n, sc_key(p, path, "ior"),
                   "expected a number or an array [nR, nG, nB] of 3 numbers, found %s",
                   json_type_phrase(n));
  if ((rc = sc_opt_float(c, v, path, "ior", &R_IOR, &o->ior))) return rc;
  if (!abbe) return BK_OK;
  float V = 0.0f;
  if ((rc = sc_float(c, abbe, sc_key(p, path, "abbe"), &R_POSITIVE, &V))) return rc;
  scene_dispersion_rgb(o->ior, V, o->ior_rgb);
  if (!(o->ior_rgb[0] >= 1.0f) || !(o->ior_rgb[2] <= 10.0f))
    return sc_fail(c, abbe, p,
                   "Abbe number %g with ior %g gives n = %g (red, 656.3 nm) to %g (blue, 486.1 nm), "
                   "outside [1, 10]; expected a larger Abbe number",
                   (double)V, (double)o->ior, (double)o->ior_rgb[0], (double)o->ior_rgb[2]);
  return BK_OK;
}

static int sc_object_entry(const sc_ctx_t *c, const json_value_t *v, const char *path,
                           scene_object_t *o) {
  static const char *const keys[] = {"mesh", "ior", "abbe", "sigma_a", "sigma_s", "g", "transform",
                                     NULL};
  static const char *const tkeys[] = {"scale", "rotate_deg", "translate", NULL};
  char p[SC_KEY_MAX];
  const json_value_t *mesh, *t;
  int rc;
  scene_object_defaults(o);
  if ((rc = sc_object(c, v, path))) return rc;
  sc_check_keys(c, v, path, keys);
  if ((rc = sc_required(c, v, path, "mesh", &mesh)) ||
      (rc = sc_file(c, mesh, sc_key(p, path, "mesh"), o->mesh, o->where)) ||
      (rc = sc_object_ior(c, v, path, o)) ||
      (rc = sc_opt_floats(c, v, path, "sigma_a", &R_NONNEG, 3, 1, o->sigma_a)) ||
      (rc = sc_opt_floats(c, v, path, "sigma_s", &R_NONNEG, 3, 1, o->sigma_s)) ||
      (rc = sc_opt_float(c, v, path, "g", &R_HG, &o->g)))
    return rc;
  if (!(t = json_object_get(v, "transform"))) return BK_OK;
  sc_key(p, path, "transform");
  if ((rc = sc_object(c, t, p))) return rc;
  sc_check_keys(c, t, p, tkeys);
  /* a zero scale collapses the mesh, a negative one turns it inside out */
  const sc_keyed_t scale = {&R_POSITIVE, 3, 1, 0}, any = {&R_ANY, 3, 0, 0};
  if ((rc = sc_opt_keyed(c, t, p, "scale", &scale, o->scale)) ||
      (rc = sc_opt_keyed(c, t, p, "rotate_deg", &any, o->rotate_deg)) ||
      (rc = sc_opt_keyed(c, t, p, "translate", &any, o->translate)))
    return rc;
  return BK_OK;
}

/* The loader's typed reads for a light kind's parse function (lights.h). */
typedef struct sc_light_ctx {
  const sc_ctx_t *c;
  const json_value_t *v; /* the light's object */
  const char *path;      /* "lights[i]" */
} sc_light_ctx_t;

/* Every light value may be keyframed (scene_keys.c): a light that moves,
 * turns, dims or widens over the frames. */
static int sc_light_position(void *ctx, const char *key, float out[3]) {
  const sc_light_ctx_t *x = ctx;
  const sc_keyed_t k = {&R_ANY, 3, 0, 0};
  return sc_opt_keyed(x->c, x->v, x->path, key, &k, out);
}
static int sc_light_colour(void *ctx, const char *key, float out[3]) {
  const sc_light_ctx_t *x = ctx;
  const sc_keyed_t k = {&R_LIGHT, 3, 1, 0};
  return sc_opt_keyed(x->c, x->v, x->path, key, &k, out);
}
static int sc_light_angle(void *ctx, const char *key, float *out) {
  const sc_light_ctx_t *x = ctx;
  const sc_keyed_t k = {&R_ANGLE, 1, 0, 0};
  return sc_opt_keyed(x->c, x->v, x->path, key, &k, out);
}
static int sc_light_direction(void *ctx, const char *key, float out[3]) {
  const sc_light_ctx_t *x = ctx;
  const sc_keyed_t k = {&R_ANY, 3, 0, 1};
  const json_value_t *d;
  int rc;
  if ((rc = sc_required(x->c, x->v, x->path, key, &d))) return rc;
  return sc_opt_keyed(x->c, x->v, x->path, key, &k, out);
}

/* One light: its kind from light_kinds[], whose keys are all required. */
static int sc_light(const sc_ctx_t *c, const json_value_t *v, const char *path, scene_light_t *l) {
  const char *names[LIGHT_KIND_COUNT];
  char p[SC_KEY_MAX];
  const json_value_t *tv;
  int rc, type = 0;
  for (int i = 0; i < LIGHT_KIND_COUNT; i++) names[i] = light_kinds[i].name;
  if ((rc = sc_object(c, v, path)) || (rc = sc_required(c, v, path, "type", &tv)) ||
      (rc = sc_enum(c, tv, sc_key(p, path, "type"), names, LIGHT_KIND_COUNT, &type)))
    return rc;
  const light_kind_t *kind = &light_kinds[type];
  l->type = kind->type;
  for (size_t i = 0; i < v->count; i++) {
    const json_member_t *m = &v->members[i];
    if (!sc_known(m->key, light_keys))
      sc_warn_unknown(c, m, path, light_keys);
    else if (strcmp(m->key, "type") != 0 && !light_kind_takes(kind, m->key))
      bk_warn("%s:%d:%d: %s: not used by a %s light, ignored", c->file, m->line, m->col,
              sc_key(p, path, m->key), kind->name);
  }
  for (const char *const *k = kind->keys; *k; k++) {
    const json_value_t *kv;
    if ((rc = sc_required(c, v, path, *k, &kv))) return rc;
  }
  sc_light_ctx_t x = {c, v, path};
  const light_reader_t reader = {&x, sc_light_position, sc_light_colour, sc_light_angle,
                                 sc_light_direction};
  return kind->parse(&reader, l);
}

/* photons.bounces: "auto" or a whole number of scattering events. */
static int sc_bounces(const sc_ctx_t *c, const json_value_t *obj, int *out) {
  const json_value_t *v = json_object_get(obj, "bounces");
  double n;
  int rc;
  if (!v) return BK_OK;
  if (v->type == JSON_STRING && strcmp(v->string, "auto") == 0) return *out = SCENE_BOUNCES_AUTO, BK_OK;
  if (v->type == JSON_STRING)
    return sc_fail(c, v, "photons.bounces",
                   "expected \"auto\" or a whole number from 0 to %d, found \"%.200s\"",
                   SCENE_MAX_BOUNCES, v->string);
  if ((rc = sc_number(c, v, "photons.bounces", &R_BOUNCES, &n))) return rc;
  *out = (int)n;
  return BK_OK;
}

static int sc_photons(const sc_ctx_t *c, const json_value_t *v, scene_t *s) {
  static const char *const keys[] = {"mode",    "count",        "seed",          "integrator",
                                     "step",    "bounces",      "batches",       "target_error",
                                     "time_budget_s", NULL};
  static const char *const modes[] = {"reference", "adaptive"};        /* photon_mode_t */
  const char *integrators[INTEGRATOR_KIND_COUNT];
  const json_value_t *e;
  long long seed = s->seed, batches = s->batches;
  int rc, k;
  for (int i = 0; i < INTEGRATOR_KIND_COUNT; i++) integrators[i] = integrator_kinds[i].name;
  if ((rc = sc_object(c, v, "photons"))) return rc;
  sc_check_keys(c, v, "photons", keys);
  if ((e = json_object_get(v, "mode"))) {
    if ((rc = sc_enum(c, e, "photons.mode", modes, 2, &k))) return rc;
    s->mode = (photon_mode_t)k;
  }
  if ((e = json_object_get(v, "integrator"))) {
    if ((rc = sc_enum(c, e, "photons.integrator", integrators, INTEGRATOR_KIND_COUNT, &k)))
      return rc;
    s->integrator = integrator_kinds[k].id;
  }
  if ((rc = sc_opt_int(c, v, "photons", "count", &R_PHOTONS, &s->photon_count)) ||
      (rc = sc_opt_int(c, v, "photons", "seed", &R_SEED, &seed)) ||
      (rc = sc_opt_float(c, v, "photons", "step", &R_STEP, &s->step)) ||
      (rc = sc_bounces(c, v, &s->bounces)) ||
      (rc = sc_opt_int(c, v, "photons", "batches", &R_BATCHES, &batches)) ||
      (rc = sc_opt_float(c, v, "photons", "target_error", &R_TARGET_ERROR, &s->target_error)) ||
      (rc = sc_opt_float(c, v, "photons", "time_budget_s", &R_POSITIVE, &s->time_budget_s)))
    return rc;
  s->seed = (unsigned)seed;
  s->batches = (int)batches;
  return BK_OK;
}

static int sc_threshold(const sc_ctx_t *c, const json_value_t *obj, const char *key, float *out) {
  char p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key);
  if (!v) return BK_OK;
  sc_key(p, "adaptive", key);
  if (v->type == JSON_NUMBER) return sc_float(c, v, p, &R_NONNEG, out);
  if (v->type == JSON_STRING && strcmp(v->string, "auto") == 0) return *out = SCENE_AUTO, BK_OK;
  if (v->type == JSON_STRING)
    return sc_fail(c, v, p, "expected \"auto\" or a number >= 0, found \"%.200s\"", v->string);
  return sc_fail(c, v, p, "expected \"auto\" or a number >= 0, found %s", json_type_phrase(v));
}

static int sc_adaptive(const sc_ctx_t *c, const json_value_t *v, scene_t *s) {
  static const char *const keys[] = {"pilot", "gradient_threshold", "luminance_threshold",
                                     "alpha", "tables", NULL};
  static const char *const tables[] = {"pilot", "measured"}; /* scene_t.retable */
  const json_value_t *e;
  long long pilot = s->pilot;
  int rc;
  if ((rc = sc_object(c, v, "adaptive"))) return rc;
  sc_check_keys(c, v, "adaptive", keys);
  if ((e = json_object_get(v, "tables")) &&
      (rc = sc_enum(c, e, "adaptive.tables", tables, 2, &s->retable)))
    return rc;
  if ((rc = sc_opt_int(c, v, "adaptive", "pilot", &R_COUNT_INT, &pilot)) ||
      (rc = sc_threshold(c, v, "gradient_threshold", &s->gradient_threshold)) ||
      (rc = sc_threshold(c, v, "luminance_threshold", &s->luminance_threshold)) ||
      (rc = sc_opt_float(c, v, "adaptive", "alpha", &R_NONNEG, &s->alpha)))
    return rc;
  s->pilot = (int)pilot;
  return BK_OK;
}

/* A camera vector for a message: as written, or a keyframed one's value at
 * the frame. */
static const char *cam_vec_text(const json_value_t *v, int frame, const float x[3], char *buf,
                                size_t n) {
  if (v->type != JSON_OBJECT) return sc_vec_text(v, buf, n);
  snprintf(buf, n, "[%g, %g, %g] at frame %d", x[0], x[1], x[2], frame);
  return buf;
}

static int sc_camera(const sc_ctx_t *c, const json_value_t *v, scene_camera_t *cam) {
  static const char *const keys[] = {"position", "look_at", "up", "fov_deg", "resolution",
                                     "bake_phase", NULL};
  const json_value_t *pos, *at, *up;
  float size[2] = {(float)cam->width, (float)cam->height};
  char text[128];
  int rc;
  if ((rc = sc_object(c, v, "camera"))) return rc;
  sc_check_keys(c, v, "camera", keys);
  /* position, look_at, up and fov_deg may be keyframed (docs/animation.md) */
  const sc_keyed_t point = {&R_ANY, 3, 0, 0}, fov = {&R_FOV, 1, 0, 0};
  if ((rc = sc_required(c, v, "camera", "position", &pos)) ||
      (rc = sc_required(c, v, "camera", "look_at", &at)) ||
      (rc = sc_keyed(c, pos, "camera.position", &point, cam->position)) ||
      (rc = sc_keyed(c, at, "camera.look_at", &point, cam->look_at)) ||
      (rc = sc_opt_keyed(c, v, "camera", "up", &point, cam->up)) ||
      (rc = sc_opt_keyed(c, v, "camera", "fov_deg", &fov, &cam->fov_deg)) ||
      (rc = sc_opt_floats(c, v, "camera", "resolution", &R_PIXELS, 2, 0, size)) ||
      (rc = sc_opt_bool(c, v, "camera", "bake_phase", &cam->bake_phase)))
    return rc;
  cam->width = (int)size[0];
  cam->height = (int)size[1];
  double f[3], u[3], fl = 0, ul = 0, x[3], xl = 0;
  for (int a = 0; a < 3; a++) {
    f[a] = (double)cam->look_at[a] - cam->position[a];
    u[a] = cam->up[a];
    fl += f[a] * f[a];
    ul += u[a] * u[a];
  }
  if (!(fl > 0.0) && pos->type == JSON_OBJECT)
    return sc_fail(c, at, "camera.look_at", "expected a point other than camera.position, found "
                   "[%g, %g, %g], where the keyframed position is at frame %d", cam->look_at[0],
                   cam->look_at[1], cam->look_at[2], c->frame);
  if (!(fl > 0.0))
    return sc_fail(c, at, "camera.look_at", "expected a point other than camera.position, found %s",
                   cam_vec_text(at, c->frame, cam->look_at, text, sizeof text));
  for (int a = 0; a < 3; a++) {
    x[a] = f[(a + 1) % 3] * u[(a + 2) % 3] - f[(a + 2) % 3] * u[(a + 1) % 3];
    xl += x[a] * x[a];
  }
  /* the view needs an up that is not along the line of sight (1e-6 rad) */
  if (!(xl > 1e-12 * fl * ul)) {
    up = json_object_get(v, "up");
    return sc_fail(c, up ? up : at, up ? "camera.up" : "camera.look_at",
                   "expected a vector not parallel to look_at - position, found %s",
                   up ? cam_vec_text(up, c->frame, cam->up, text, sizeof text)
                      : "the default up [0, 1, 0]");
  }
  cam->present = 1;
  return BK_OK;
}

static int sc_root(const sc_ctx_t *c, const json_value_t *root, scene_t *s) {
  static const char *const keys[] = {"grid", "photons", "medium", "objects", "lights",
                                     "adaptive", "camera", "background", NULL};
  char p[SC_KEY_MAX];
  const json_value_t *v;
  int rc;
  if (root->type != JSON_OBJECT)
    return sc_fail(c, root, "", "expected an object at the top level, found %s",
                   json_type_phrase(root));
  sc_check_keys(c, root, "", keys);
  if ((rc = sc_required(c, root, "", "grid", &v)) || (rc = sc_grid(c, v, s))) return rc;
  if ((v = json_object_get(root, "medium")) && (rc = sc_medium(c, v, s))) return rc;
  if ((v = json_object_get(root, "objects"))) {
    if ((rc = sc_array(c, v, "objects", SCENE_MAX_OBJECTS))) return rc;
    if (v->count) {
      s->objects = bk_calloc(v->count, sizeof *s->objects, "scene objects", c->err);
      if (!s->objects) return BK_ERR_RUNTIME;
    }
    for (size_t i = 0; i < v->count; i++, s->object_count++)
      if ((rc = sc_object_entry(c, v->items[i], sc_index(p, "objects", i), &s->objects[i])))
        return rc;
  }
  if ((v = json_object_get(root, "lights"))) {
    if ((rc = sc_array(c, v, "lights", SCENE_MAX_LIGHTS))) return rc;
    if (v->count) {
      s->lights = bk_calloc(v->count, sizeof *s->lights, "scene lights", c->err);
      if (!s->lights) return BK_ERR_RUNTIME;
    }
    for (size_t i = 0; i < v->count; i++, s->light_count++)
      if ((rc = sc_light(c, v->items[i], sc_index(p, "lights", i), &s->lights[i]))) return rc;
  }
  if ((v = json_object_get(root, "photons")) && (rc = sc_photons(c, v, s))) return rc;
  if ((v = json_object_get(root, "adaptive")) && (rc = sc_adaptive(c, v, s))) return rc;
  if ((v = json_object_get(root, "camera")) && (rc = sc_camera(c, v, &s->camera))) return rc;
  return sc_opt_floats(c, root, "", "background", &R_NONNEG, 3, 1, s->background);
}

/* --- public ----------------------------------------------------------------- */

void scene_defaults(scene_t *s) {
  memset(s, 0, sizeof *s);
  s->ior_smoothing = 2.0f;
  s->crop_to_objects = 1;
  s->medium_ior = 1.0f;
  s->mode = MODE_REFERENCE;
  s->photon_count = 122000;
  s->seed = 1;
  s->integrator = INTEGRATOR_EULER;
  s->step = 0.5f;
  s->bounces = SCENE_BOUNCES_AUTO;
  s->batches = 0; /* scene_batches() */
  s->pilot = 4000;
  s->gradient_threshold = SCENE_AUTO;
  s->luminance_threshold = SCENE_AUTO;
  s->alpha = 1.0f;
  s->camera.up[1] = 1.0f;
  s->camera.fov_deg = 40.0f;
  s->camera.bake_phase = 1;
  s->camera.width = 800;
  s->camera.height = 600;
}

void scene_object_defaults(scene_object_t *o) {
  memset(o, 0, sizeof *o);
  o->ior = 1.5f;
  for (int a = 0; a < 3; a++) o->scale[a] = 1.0f;
}

/* The scene's name for messages and its directory for relative paths: "-"
 * is standard input, named <stdin>, its paths relative to the working
 * directory. */
static int scene_names(const char *path, scene_t *s, bk_error_t *err) {
  size_t pl = strlen(path);
  if (pl == 0 || pl >= SCENE_PATH_MAX)
    return bk_fail(err, BK_ERR_INPUT, "%.200s: expected a scene path of 1 to %d bytes, found %zu",
                   path, SCENE_PATH_MAX - 1, pl);
  if (!strcmp(path, "-")) {
    snprintf(s->path, sizeof s->path, "<stdin>");
    snprintf(s->dir, sizeof s->dir, ".");
    return BK_OK;
  }
  memcpy(s->path, path, pl + 1);
  const char *slash = strrchr(path, '/');
  if (!slash) snprintf(s->dir, sizeof s->dir, ".");
  else if (slash == path) snprintf(s->dir, sizeof s->dir, "/");
  else memcpy(s->dir, path, (size_t)(slash - path)), s->dir[slash - path] = 0;
  return BK_OK;
}

int scene_load(const char *path, scene_t *s, bk_error_t *err) {
  return scene_load_frame(path, NULL, 0, 0, s, err);
}

int scene_load_with(const char *path, const char *const *sets, int set_count, scene_t *s,
                    bk_error_t *err) {
  return scene_load_frame(path, sets, set_count, 0, s, err);
}

int scene_load_frame(const char *path, const char *const *sets, int set_count, int frame,
                     scene_t *s, bk_error_t *err) {
  bk_error_t local;
  char *text = NULL;
  const char *bytes;
  size_t len = 0;
  json_value_t *root = NULL;
  if (!err) err = &local;
  sc_ctx_t c = {s->path, s->dir, err, sets, frame, &s->keyed_values};
  scene_defaults(s);
  s->frame = frame;
  int rc = scene_names(path, s, err);
  if (rc) return rc;
  if (!strcmp(path, "-")) rc = scene_read_stdin(&bytes, &len, err);
  else if (!(rc = bk_read_file(path, &text, &len, err))) bytes = text;
  if (rc) goto error;
  /* the hash names what is baked: the file's bytes, then each override */
  s->hash = bk_hash64(bytes, len, BK_HASH_SEED);
  for (int k = 0; k < set_count; k++) s->hash = bk_hash64(sets[k], strlen(sets[k]) + 1, s->hash);
  if (!(root = json_parse(bytes, len, s->path, err))) {
    rc = err->code ? err->code : BK_ERR_INPUT;
    goto error;
  }
  if ((rc = scene_apply_sets(root, sets, set_count, err))) goto error;
  if ((rc = sc_root(&c, root, s))) goto error;
  free(text);
  json_free(root);
  return BK_OK;
error:
  free(text);
  json_free(root);
  scene_free(s);
  return rc;
}

void scene_free(scene_t *s) {
  if (!s) return;
  free(s->objects);
  free(s->lights);
  s->objects = NULL;
  s->lights = NULL;
  s->object_count = s->light_count = 0;
}

const char *scene_light_type_name(light_type_t t) {
  const light_kind_t *k = light_kind(t);
  return k ? k->name : "unknown";
}

const char *scene_mode_name(photon_mode_t m) {
  switch (m) {
  case MODE_REFERENCE: return "reference";
  case MODE_ADAPTIVE: return "adaptive";
  }
  return "unknown";
}

const char *scene_integrator_name(integrator_t i) {
  const integrator_kind_t *k = integrator_kind(i);
  return k ? k->name : "unknown";
}
