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
#include "json.h"
#include "lights.h"

#define SC_KEY_MAX 512 /* longest key path quoted in a message */

typedef struct sc_ctx {
  const char *file; /* the scene path as given, for messages */
  const char *dir;  /* for relative paths */
  bk_error_t *err;
} sc_ctx_t;

/* The values a number may take. hi_silent: hi is only the limit of the C
 * type, not worth mentioning unless the value exceeds it. */
typedef struct sc_range {
  double lo, hi;
  unsigned char lo_open, hi_open, integer, hi_silent;
} sc_range_t;

#define SC_NOLIM ((double)FLT_MAX)
static const sc_range_t R_ANY = {-SC_NOLIM, SC_NOLIM, 0, 0, 0, 1};
static const sc_range_t R_NONNEG = {0, SC_NOLIM, 0, 0, 0, 1};
static const sc_range_t R_POSITIVE = {0, SC_NOLIM, 1, 0, 0, 1};
static const sc_range_t R_IOR = {1, 10, 0, 0, 0, 0};
static const sc_range_t R_SMOOTHING = {0, 64, 1, 0, 0, 0};
static const sc_range_t R_ANGLE = {0, 90, 1, 0, 0, 0};
static const sc_range_t R_FOV = {0, 180, 1, 1, 0, 0};
static const sc_range_t R_COUNT_INT = {1, INT_MAX, 0, 0, 1, 1};
static const sc_range_t R_PIXELS = {1, 16384, 0, 0, 1, 0};
static const sc_range_t R_SEED = {0, 4294967295.0, 0, 0, 1, 0};
/* 2^53: beyond it a JSON number no longer names every integer */
static const sc_range_t R_PHOTONS = {1, 9007199254740992.0, 0, 0, 1, 1};

/* --- messages ------------------------------------------------------------- */

__attribute__((format(printf, 5, 6))) static int sc_fail_at(const sc_ctx_t *c, int line, int col,
                                                            const char *path, const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  return bk_fail(c->err, BK_ERR_INPUT, "%s:%d:%d: %s%s%s", c->file, line, col, path,
                 *path ? ": " : "", msg);
}
#define sc_fail(c, v, path, ...) sc_fail_at((c), (v)->line, (v)->col, (path), __VA_ARGS__)

/* Key paths are cut at SC_KEY_MAX: a message with a cut path still helps. */
static void sc_append(char *buf, size_t *n, const char *s) {
  while (*s && *n + 1 < SC_KEY_MAX) buf[(*n)++] = *s++;
  buf[*n] = 0;
}
static const char *sc_key(char *buf, const char *parent, const char *key) {
  size_t n = 0;
  sc_append(buf, &n, parent);
  if (*parent) sc_append(buf, &n, ".");
  sc_append(buf, &n, key);
  return buf;
}
static const char *sc_index(char *buf, const char *parent, size_t i) {
  char index[32];
  size_t n = 0;
  snprintf(index, sizeof index, "[%zu]", i);
  sc_append(buf, &n, parent);
  sc_append(buf, &n, index);
  return buf;
}

/* Edit distance, to suggest the key a typo was meant to be. */
static int sc_distance(const char *a, const char *b) {
  size_t la = strlen(a), lb = strlen(b);
  int row[64];
  if (la >= 64 || lb >= 64) return 64;
  for (size_t j = 0; j <= lb; j++) row[j] = (int)j;
  for (size_t i = 1; i <= la; i++) {
    int diag = row[0];
    row[0] = (int)i;
    for (size_t j = 1; j <= lb; j++) {
      int up = row[j], best = diag + (a[i - 1] != b[j - 1]);
      if (up + 1 < best) best = up + 1;
      if (row[j - 1] + 1 < best) best = row[j - 1] + 1;
      row[j] = best;
      diag = up;
    }
  }
  return row[lb];
}

static void sc_warn_unknown(const sc_ctx_t *c, const json_member_t *m, const char *parent,
                            const char *const *known) {
  char p[SC_KEY_MAX], hint[128] = "";
  int best = 3;
  for (; known && *known; known++) {
    int d = sc_distance(m->key, *known);
    if (d < best && 2 * d < (int)strlen(*known)) {
      best = d;
      snprintf(hint, sizeof hint, " (did you mean \"%s\"?)", *known);
    }
  }
  bk_warn("%s:%d:%d: %s: unknown key, ignored%s", c->file, m->line, m->col, sc_key(p, parent, m->key),
          hint);
}

static int sc_known(const char *key, const char *const *known) {
  for (; *known; known++)
    if (strcmp(key, *known) == 0) return 1;
  return 0;
}

/* Warns about every key of obj not in the NULL-terminated list `known`. */
static void sc_check_keys(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                          const char *const *known) {
  for (size_t i = 0; i < obj->count; i++)
    if (!sc_known(obj->members[i].key, known)) sc_warn_unknown(c, &obj->members[i], path, known);
}

/* --- typed getters ---------------------------------------------------------- */

static const char *sc_range_text(const sc_range_t *r, char *buf, size_t n) {
  const char *noun = r->integer ? "an integer" : "a number";
  int has_lo = r->lo > -SC_NOLIM, has_hi = !r->hi_silent;
  if (has_lo && has_hi)
    snprintf(buf, n, "%s in %c%.10g, %.10g%c", noun, r->lo_open ? '(' : '[', r->lo, r->hi,
             r->hi_open ? ')' : ']');
  else if (has_lo)
    snprintf(buf, n, "%s %s %.10g", noun, r->lo_open ? ">" : ">=", r->lo);
  else
    snprintf(buf, n, "%s", noun);
  return buf;
}

static int sc_number(const sc_ctx_t *c, const json_value_t *v, const char *path,
                     const sc_range_t *r, double *out) {
  char want[128];
  if (v->type != JSON_NUMBER)
    return sc_fail(c, v, path, "expected %s, found %s", r->integer ? "an integer" : "a number",
                   json_type_phrase(v));
  double x = v->number;
  /* JSON has no inf, but 1e400 overflows to it, and 1e39 overflows a float */
  if (!isfinite(x) || fabs(x) > FLT_MAX)
    return sc_fail(c, v, path, "expected a finite number, found %s", v->string);
  if (r->integer && x != floor(x))
    return sc_fail(c, v, path, "expected an integer, found %s", v->string);
  if (!r->integer) x = (double)(float)x; /* check what will be stored */
  int lo_bad = r->lo_open ? !(x > r->lo) : !(x >= r->lo);
  int hi_bad = r->hi_open ? !(x < r->hi) : !(x <= r->hi);
  if (hi_bad && r->hi_silent) {
    snprintf(want, sizeof want, "%s <= %.17g", r->integer ? "an integer" : "a number", r->hi);
    return sc_fail(c, v, path, "expected %s, found %s", want, v->string);
  }
  if (lo_bad || hi_bad)
    return sc_fail(c, v, path, "expected %s, found %s", sc_range_text(r, want, sizeof want),
                   v->string);
  *out = x;
  return BK_OK;
}

static int sc_float(const sc_ctx_t *c, const json_value_t *v, const char *path,
                    const sc_range_t *r, float *out) {
  double x = 0.0; /* set whenever sc_number succeeds; gcc cannot see it */
  int rc = sc_number(c, v, path, r, &x);
  if (rc == BK_OK) *out = (float)x;
  return rc;
}

/* "[0, -1, 0]" as written, for messages about a whole vector */
static const char *sc_vec_text(const json_value_t *v, char *buf, size_t n) {
  size_t used = (size_t)snprintf(buf, n, "[");
  for (size_t i = 0; i < v->count && used < n; i++)
    used += (size_t)snprintf(buf + used, n - used, "%s%s", i ? ", " : "", v->items[i]->string);
  if (used < n) snprintf(buf + used, n - used, "]");
  return buf;
}

/* An array of `n` numbers in range r; a single number too when scalar_ok
 * (a grey colour, a uniform scale). */
static int sc_floats(const sc_ctx_t *c, const json_value_t *v, const char *path,
                     const sc_range_t *r, size_t n, int scalar_ok, float *out) {
  char p[SC_KEY_MAX];
  int rc;
  if (scalar_ok && v->type == JSON_NUMBER) {
    float x;
    if ((rc = sc_float(c, v, path, r, &x))) return rc;
    for (size_t i = 0; i < n; i++) out[i] = x;
    return BK_OK;
  }
  const char *want = r->integer ? "integers" : "numbers";
  if (v->type != JSON_ARRAY)
    return sc_fail(c, v, path, "expected %san array of %zu %s, found %s",
                   scalar_ok ? "a number or " : "", n, want, json_type_phrase(v));
  if (v->count != n)
    return sc_fail(c, v, path, "expected an array of %zu %s, found an array of %zu element%s", n,
                   want, v->count, v->count == 1 ? "" : "s");
  for (size_t i = 0; i < n; i++)
    if ((rc = sc_float(c, v->items[i], sc_index(p, path, i), r, &out[i]))) return rc;
  return BK_OK;
}

static int sc_string(const sc_ctx_t *c, const json_value_t *v, const char *path, char *out,
                     size_t size) {
  if (v->type != JSON_STRING)
    return sc_fail(c, v, path, "expected a string, found %s", json_type_phrase(v));
  if (v->string_len == 0) return sc_fail(c, v, path, "expected a non-empty string, found \"\"");
  if (strlen(v->string) != v->string_len)
    return sc_fail(c, v, path, "expected a string without \\u0000, found one with it");
  if (v->string_len >= size)
    return sc_fail(c, v, path, "expected a string shorter than %zu bytes, found %zu bytes", size,
                   v->string_len);
  memcpy(out, v->string, v->string_len + 1);
  return BK_OK;
}

/* One of `names` (n of them); *out is its index. */
static int sc_enum(const sc_ctx_t *c, const json_value_t *v, const char *path,
                   const char *const *names, int n, int *out) {
  char want[256] = "";
  size_t used = 0;
  for (int i = 0; i < n && used < sizeof want; i++)
    used += (size_t)snprintf(want + used, sizeof want - used, "%s\"%s\"",
                             i == 0 ? "" : i == n - 1 ? " or " : ", ", names[i]);
  if (v->type != JSON_STRING)
    return sc_fail(c, v, path, "expected %s, found %s", want, json_type_phrase(v));
  for (int i = 0; i < n; i++)
    if (strcmp(v->string, names[i]) == 0) return *out = i, BK_OK;
  return sc_fail(c, v, path, "expected %s, found \"%.200s\"", want, v->string);
}

/* A file named relative to the scene file, plus its "where" for later stages. */
static int sc_file(const sc_ctx_t *c, const json_value_t *v, const char *path,
                   char out[SCENE_PATH_MAX], char where[SCENE_WHERE_MAX]) {
  char rel[SCENE_PATH_MAX];
  int rc = sc_string(c, v, path, rel, sizeof rel);
  if (rc) return rc;
  size_t dl = strlen(c->dir), rl = strlen(rel);
  if (rel[0] == '/' || strcmp(c->dir, ".") == 0) {
    memcpy(out, rel, rl + 1);
  } else if (dl + 1 + rl < SCENE_PATH_MAX) {
    memcpy(out, c->dir, dl);
    out[dl] = '/';
    memcpy(out + dl + 1, rel, rl + 1);
  } else {
    return sc_fail(c, v, path, "expected a path shorter than %d bytes once joined to %s, found %zu",
                   SCENE_PATH_MAX, c->dir, dl + 1 + rl);
  }
  snprintf(where, SCENE_WHERE_MAX, "%s:%d:%d: %s", c->file, v->line, v->col, path);
  return BK_OK;
}

static int sc_object(const sc_ctx_t *c, const json_value_t *v, const char *path) {
  if (v->type != JSON_OBJECT)
    return sc_fail(c, v, path, "expected an object, found %s", json_type_phrase(v));
  return BK_OK;
}

static int sc_required(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                       const char *key, const json_value_t **out) {
  if ((*out = json_object_get(obj, key))) return BK_OK;
  return sc_fail(c, obj, path, "missing required key \"%s\"", key);
}

/* Optional keys: leave *out (the default) alone when absent. */
static int sc_opt_float(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                        const char *key, const sc_range_t *r, float *out) {
  char p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key);
  return v ? sc_float(c, v, sc_key(p, path, key), r, out) : BK_OK;
}
static int sc_opt_floats(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                         const char *key, const sc_range_t *r, size_t n, int scalar_ok,
                         float *out) {
  char p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key);
  return v ? sc_floats(c, v, sc_key(p, path, key), r, n, scalar_ok, out) : BK_OK;
}
static int sc_opt_int(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                      const char *key, const sc_range_t *r, long long *out) {
  char p[SC_KEY_MAX];
  double x = 0.0;
  const json_value_t *v = json_object_get(obj, key);
  if (!v) return BK_OK;
  int rc = sc_number(c, v, sc_key(p, path, key), r, &x);
  if (rc == BK_OK) *out = (long long)x;
  return rc;
}

/* Normalises d in place; a zero vector has no direction. */
static int sc_direction(const sc_ctx_t *c, const json_value_t *v, const char *path, float d[3]) {
  char text[128];
  double len = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
  if (!(len > 0.0) || !isfinite(len))
    return sc_fail(c, v, path, "expected a non-zero direction, found %s",
                   sc_vec_text(v, text, sizeof text));
  for (int a = 0; a < 3; a++) d[a] = (float)(d[a] / len);
  return BK_OK;
}

/* --- sections ------------------------------------------------------------- */

static int sc_grid(const sc_ctx_t *c, const json_value_t *g, scene_t *s) {
  static const char *const keys[] = {"bounds", "resolution", "ior_smoothing", NULL};
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
  static const char *const keys[] = {"sigma_s", "sigma_a", "ior", "density_vdb", "ior_vdb", NULL};
  int rc;
  if ((rc = sc_object(c, m, "medium"))) return rc;
  sc_check_keys(c, m, "medium", keys);
  if ((rc = sc_opt_floats(c, m, "medium", "sigma_s", &R_NONNEG, 3, 1, s->medium_sigma_s)) ||
      (rc = sc_opt_floats(c, m, "medium", "sigma_a", &R_NONNEG, 3, 1, s->medium_sigma_a)) ||
      (rc = sc_opt_float(c, m, "medium", "ior", &R_IOR, &s->medium_ior)) ||
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

static int sc_object_entry(const sc_ctx_t *c, const json_value_t *v, const char *path,
                           scene_object_t *o) {
  static const char *const keys[] = {"mesh", "ior", "sigma_a", "sigma_s", "transform", NULL};
  static const char *const tkeys[] = {"scale", "rotate_deg", "translate", NULL};
  char p[SC_KEY_MAX];
  const json_value_t *mesh, *t;
  int rc;
  scene_object_defaults(o);
  if ((rc = sc_object(c, v, path))) return rc;
  sc_check_keys(c, v, path, keys);
  if ((rc = sc_required(c, v, path, "mesh", &mesh)) ||
      (rc = sc_file(c, mesh, sc_key(p, path, "mesh"), o->mesh, o->where)) ||
      (rc = sc_opt_float(c, v, path, "ior", &R_IOR, &o->ior)) ||
      (rc = sc_opt_floats(c, v, path, "sigma_a", &R_NONNEG, 3, 1, o->sigma_a)) ||
      (rc = sc_opt_floats(c, v, path, "sigma_s", &R_NONNEG, 3, 1, o->sigma_s)))
    return rc;
  if (!(t = json_object_get(v, "transform"))) return BK_OK;
  sc_key(p, path, "transform");
  if ((rc = sc_object(c, t, p))) return rc;
  sc_check_keys(c, t, p, tkeys);
  /* a zero scale collapses the mesh, a negative one turns it inside out */
  if ((rc = sc_opt_floats(c, t, p, "scale", &R_POSITIVE, 3, 1, o->scale)) ||
      (rc = sc_opt_floats(c, t, p, "rotate_deg", &R_ANY, 3, 0, o->rotate_deg)) ||
      (rc = sc_opt_floats(c, t, p, "translate", &R_ANY, 3, 0, o->translate)))
    return rc;
  return BK_OK;
}

/* The loader's typed reads for a light kind's parse function (lights.h). */
typedef struct sc_light_ctx {
  const sc_ctx_t *c;
  const json_value_t *v; /* the light's object */
  const char *path;      /* "lights[i]" */
} sc_light_ctx_t;

static int sc_light_position(void *ctx, const char *key, float out[3]) {
  const sc_light_ctx_t *x = ctx;
  return sc_opt_floats(x->c, x->v, x->path, key, &R_ANY, 3, 0, out);
}
static int sc_light_colour(void *ctx, const char *key, float out[3]) {
  const sc_light_ctx_t *x = ctx;
  return sc_opt_floats(x->c, x->v, x->path, key, &R_NONNEG, 3, 1, out);
}
static int sc_light_angle(void *ctx, const char *key, float *out) {
  const sc_light_ctx_t *x = ctx;
  return sc_opt_float(x->c, x->v, x->path, key, &R_ANGLE, out);
}
static int sc_light_direction(void *ctx, const char *key, float out[3]) {
  const sc_light_ctx_t *x = ctx;
  char p[SC_KEY_MAX];
  const json_value_t *d;
  int rc;
  if ((rc = sc_required(x->c, x->v, x->path, key, &d))) return rc;
  sc_key(p, x->path, key);
  if ((rc = sc_floats(x->c, d, p, &R_ANY, 3, 0, out)) || (rc = sc_direction(x->c, d, p, out)))
    return rc;
  return BK_OK;
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

static int sc_photons(const sc_ctx_t *c, const json_value_t *v, scene_t *s) {
  static const char *const keys[] = {"mode", "count", "seed", "integrator", "step", NULL};
  static const char *const modes[] = {"reference", "adaptive"};        /* photon_mode_t */
  const char *integrators[INTEGRATOR_KIND_COUNT];
  const json_value_t *e;
  long long seed = s->seed;
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
      (rc = sc_opt_float(c, v, "photons", "step", &R_POSITIVE, &s->step)))
    return rc;
  s->seed = (unsigned)seed;
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
                                     "alpha", NULL};
  long long pilot = s->pilot;
  int rc;
  if ((rc = sc_object(c, v, "adaptive"))) return rc;
  sc_check_keys(c, v, "adaptive", keys);
  if ((rc = sc_opt_int(c, v, "adaptive", "pilot", &R_COUNT_INT, &pilot)) ||
      (rc = sc_threshold(c, v, "gradient_threshold", &s->gradient_threshold)) ||
      (rc = sc_threshold(c, v, "luminance_threshold", &s->luminance_threshold)) ||
      (rc = sc_opt_float(c, v, "adaptive", "alpha", &R_NONNEG, &s->alpha)))
    return rc;
  s->pilot = (int)pilot;
  return BK_OK;
}

static int sc_camera(const sc_ctx_t *c, const json_value_t *v, scene_camera_t *cam) {
  static const char *const keys[] = {"position", "look_at", "up", "fov_deg", "resolution", NULL};
  const json_value_t *pos, *at, *up;
  float size[2] = {(float)cam->width, (float)cam->height};
  char text[128];
  int rc;
  if ((rc = sc_object(c, v, "camera"))) return rc;
  sc_check_keys(c, v, "camera", keys);
  if ((rc = sc_required(c, v, "camera", "position", &pos)) ||
      (rc = sc_required(c, v, "camera", "look_at", &at)) ||
      (rc = sc_floats(c, pos, "camera.position", &R_ANY, 3, 0, cam->position)) ||
      (rc = sc_floats(c, at, "camera.look_at", &R_ANY, 3, 0, cam->look_at)) ||
      (rc = sc_opt_floats(c, v, "camera", "up", &R_ANY, 3, 0, cam->up)) ||
      (rc = sc_opt_float(c, v, "camera", "fov_deg", &R_FOV, &cam->fov_deg)) ||
      (rc = sc_opt_floats(c, v, "camera", "resolution", &R_PIXELS, 2, 0, size)))
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
  if (!(fl > 0.0))
    return sc_fail(c, at, "camera.look_at", "expected a point other than camera.position, found %s",
                   sc_vec_text(at, text, sizeof text));
  for (int a = 0; a < 3; a++) {
    x[a] = f[(a + 1) % 3] * u[(a + 2) % 3] - f[(a + 2) % 3] * u[(a + 1) % 3];
    xl += x[a] * x[a];
  }
  /* the view needs an up that is not along the line of sight (1e-6 rad) */
  if (!(xl > 1e-12 * fl * ul)) {
    up = json_object_get(v, "up");
    return sc_fail(c, up ? up : at, up ? "camera.up" : "camera.look_at",
                   "expected a vector not parallel to look_at - position, found %s",
                   up ? sc_vec_text(up, text, sizeof text) : "the default up [0, 1, 0]");
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
  s->medium_ior = 1.0f;
  s->mode = MODE_REFERENCE;
  s->photon_count = 122000;
  s->seed = 1;
  s->integrator = INTEGRATOR_EULER;
  s->step = 0.5f;
  s->pilot = 4000;
  s->gradient_threshold = SCENE_AUTO;
  s->luminance_threshold = SCENE_AUTO;
  s->alpha = 1.0f;
  s->camera.up[1] = 1.0f;
  s->camera.fov_deg = 40.0f;
  s->camera.width = 800;
  s->camera.height = 600;
}

void scene_object_defaults(scene_object_t *o) {
  memset(o, 0, sizeof *o);
  o->ior = 1.5f;
  for (int a = 0; a < 3; a++) o->scale[a] = 1.0f;
}

int scene_load(const char *path, scene_t *s, bk_error_t *err) {
  bk_error_t local;
  char *text = NULL;
  size_t len = 0;
  json_value_t *root = NULL;
  sc_ctx_t c = {s->path, s->dir, err ? err : &local};
  int rc;
  if (!err) err = &local;
  scene_defaults(s);
  size_t pl = strlen(path);
  if (pl == 0 || pl >= SCENE_PATH_MAX)
    return bk_fail(err, BK_ERR_INPUT, "%.200s: expected a scene path of 1 to %d bytes, found %zu",
                   path, SCENE_PATH_MAX - 1, pl);
  memcpy(s->path, path, pl + 1);
  const char *slash = strrchr(path, '/');
  if (!slash) snprintf(s->dir, sizeof s->dir, ".");
  else if (slash == path) snprintf(s->dir, sizeof s->dir, "/");
  else memcpy(s->dir, path, (size_t)(slash - path)), s->dir[slash - path] = 0;

  if ((rc = bk_read_file(path, &text, &len, err))) goto error;
  s->hash = bk_hash64(text, len, BK_HASH_SEED);
  if (!(root = json_parse(text, len, path, err))) {
    rc = err->code ? err->code : BK_ERR_INPUT;
    goto error;
  }
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
