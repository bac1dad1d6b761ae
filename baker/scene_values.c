/* scene_values.c: typed values of the scene's JSON tree (see
 * scene_values.h). */
#include "scene_values.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

/* --- messages ------------------------------------------------------------- */

const char *sc_origin(const sc_ctx_t *c, int line, int col, char *buf, size_t len) {
  if (line == 0 && c->sets && col > 0) snprintf(buf, len, "--set %.300s", c->sets[col - 1]);
  else snprintf(buf, len, "%s:%d:%d", c->file, line, col);
  return buf;
}

int sc_fail_at(const sc_ctx_t *c, int line, int col,
               const char *path, const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  char at[SCENE_PATH_MAX + 320];
  return bk_fail(c->err, BK_ERR_INPUT, "%s: %s%s%s", sc_origin(c, line, col, at, sizeof at), path,
                 *path ? ": " : "", msg);
}

/* Key paths are cut at SC_KEY_MAX: a message with a cut path still helps. */
static void sc_append(char *buf, size_t *n, const char *s) {
  while (*s && *n + 1 < SC_KEY_MAX) buf[(*n)++] = *s++;
  buf[*n] = 0;
}
const char *sc_key(char *buf, const char *parent, const char *key) {
  size_t n = 0;
  sc_append(buf, &n, parent);
  if (*parent) sc_append(buf, &n, ".");
  sc_append(buf, &n, key);
  return buf;
}
const char *sc_index(char *buf, const char *parent, size_t i) {
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

void sc_warn_unknown(const sc_ctx_t *c, const json_member_t *m, const char *parent,
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
  char at[SCENE_PATH_MAX + 320];
  bk_warn("%s: %s: unknown key, ignored%s", sc_origin(c, m->line, m->col, at, sizeof at),
          sc_key(p, parent, m->key), hint);
}

int sc_known(const char *key, const char *const *known) {
  for (; *known; known++)
    if (strcmp(key, *known) == 0) return 1;
  return 0;
}

/* Warns about every key of obj not in the NULL-terminated list `known`. */
void sc_check_keys(const sc_ctx_t *c, const json_value_t *obj, const char *path,
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

int sc_number(const sc_ctx_t *c, const json_value_t *v, const char *path,
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

int sc_float(const sc_ctx_t *c, const json_value_t *v, const char *path,
             const sc_range_t *r, float *out) {
  double x = 0.0; /* set whenever sc_number succeeds; gcc cannot see it */
  int rc = sc_number(c, v, path, r, &x);
  if (rc == BK_OK) *out = (float)x;
  return rc;
}

/* "[0, -1, 0]" as written, for messages about a whole vector */
const char *sc_vec_text(const json_value_t *v, char *buf, size_t n) {
  size_t used = (size_t)snprintf(buf, n, "[");
  for (size_t i = 0; i < v->count && used < n; i++)
    used += (size_t)snprintf(buf + used, n - used, "%s%s", i ? ", " : "", v->items[i]->string);
  if (used < n) snprintf(buf + used, n - used, "]");
  return buf;
}

/* An array of `n` numbers in range r; a single number too when scalar_ok
 * (a grey colour, a uniform scale). */
int sc_floats(const sc_ctx_t *c, const json_value_t *v, const char *path,
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

int sc_string(const sc_ctx_t *c, const json_value_t *v, const char *path, char *out,
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
int sc_enum(const sc_ctx_t *c, const json_value_t *v, const char *path,
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
int sc_file(const sc_ctx_t *c, const json_value_t *v, const char *path,
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
  char at[SCENE_PATH_MAX + 320];
  /* a long origin loses its tail (the test keeps -Wformat-truncation quiet) */
  if (snprintf(where, SCENE_WHERE_MAX, "%s: %s", sc_origin(c, v->line, v->col, at, sizeof at),
               path) < 0)
    where[0] = 0;
  return BK_OK;
}

int sc_object(const sc_ctx_t *c, const json_value_t *v, const char *path) {
  if (v->type != JSON_OBJECT)
    return sc_fail(c, v, path, "expected an object, found %s", json_type_phrase(v));
  return BK_OK;
}

int sc_required(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                const char *key, const json_value_t **out) {
  if ((*out = json_object_get(obj, key))) return BK_OK;
  return sc_fail(c, obj, path, "missing required key \"%s\"", key);
}

/* Optional keys: leave *out (the default) alone when absent. */
int sc_opt_float(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                 const char *key, const sc_range_t *r, float *out) {
  char p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key);
  return v ? sc_float(c, v, sc_key(p, path, key), r, out) : BK_OK;
}
int sc_opt_floats(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                  const char *key, const sc_range_t *r, size_t n, int scalar_ok,
                  float *out) {
  char p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key);
  return v ? sc_floats(c, v, sc_key(p, path, key), r, n, scalar_ok, out) : BK_OK;
}
int sc_opt_int(const sc_ctx_t *c, const json_value_t *obj, const char *path,
               const char *key, const sc_range_t *r, long long *out) {
  char p[SC_KEY_MAX];
  double x = 0.0;
  const json_value_t *v = json_object_get(obj, key);
  if (!v) return BK_OK;
  int rc = sc_number(c, v, sc_key(p, path, key), r, &x);
  if (rc == BK_OK) *out = (long long)x;
  return rc;
}

int sc_opt_bool(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                const char *key, int *out) {
  char p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key);
  if (!v) return BK_OK;
  if (v->type != JSON_BOOL)
    return sc_fail(c, v, sc_key(p, path, key), "expected true or false, found %s",
                   json_type_phrase(v));
  *out = v->boolean;
  return BK_OK;
}

/* Normalises d in place; a zero vector has no direction. */
int sc_direction(const sc_ctx_t *c, const json_value_t *v, const char *path, float d[3]) {
  char text[128];
  double len = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
  if (!(len > 0.0) || !isfinite(len))
    return sc_fail(c, v, path, "expected a non-zero direction, found %s",
                   sc_vec_text(v, text, sizeof text));
  for (int a = 0; a < 3; a++) d[a] = (float)(d[a] / len);
  return BK_OK;
}

