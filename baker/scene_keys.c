/* scene_keys.c: keyframed scene values (see scene_values.h, sc_keyed).
 *
 * A value that may move between frames is written either as usual or as
 * {"keys": {"FRAME": VALUE, ...}}: each VALUE is what the plain key takes
 * and is checked the same way; the frame's value is linear in the frame
 * between the nearest keys and held at the first (last) key before (after)
 * them, as Blender's and Houdini's linear channels hold their ends. */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "scene_values.h"

/* A key's frame: an integer written as a JSON object key ("1", "-4"). */
static int key_frame(const sc_ctx_t *c, const json_member_t *m, const char *path, int *out) {
  char *end = NULL;
  errno = 0;
  long f = strtol(m->key, &end, 10);
  if (!m->key[0] || *end || errno || f < INT_MIN / 2 || f > INT_MAX / 2 ||
      strlen(m->key) != m->key_len)
    return sc_fail_at(c, m->line, m->col, path,
                      "expected a whole frame number as key (\"1\", \"24\"), found \"%.100s\"",
                      m->key);
  *out = (int)f;
  return BK_OK;
}

/* A value as the plain key takes it (a unit vector normalised). */
static int plain_value(const sc_ctx_t *c, const json_value_t *v, const char *path,
                       const sc_keyed_t *k, float *out) {
  int rc = k->n == 1 ? sc_float(c, v, path, k->range, out)
                     : sc_floats(c, v, path, k->range, k->n, k->scalar_ok, out);
  if (!rc && k->unit) rc = sc_direction(c, v, path, out);
  return rc;
}

/* One key's value, checked as the plain key is. */
static int key_value(const sc_ctx_t *c, const json_member_t *m, const char *path,
                     const sc_keyed_t *k, float *out) {
  char p[SC_KEY_MAX];
  snprintf(p, sizeof p, "%.400s.%.100s", path, m->key);
  return plain_value(c, m->value, p, k, out);
}

/* The keys' members checked (frames unique), and the two that bracket the
 * frame: *lo the last key at or before it, *hi the first at or after it
 * (the same key when the frame is on one or outside the range). */
static int bracket(const sc_ctx_t *c, const json_value_t *keys, const char *path, int frame,
                   const json_member_t **lo, const json_member_t **hi, int *flo, int *fhi) {
  *lo = *hi = NULL;
  for (size_t i = 0; i < keys->count; i++) {
    const json_member_t *m = &keys->members[i];
    int f = 0, g = 0, rc;
    if ((rc = key_frame(c, m, path, &f))) return rc;
    for (size_t j = 0; j < i; j++)
      if (!key_frame(c, &keys->members[j], path, &g) && g == f)
        return sc_fail_at(c, m->line, m->col, path,
                          "frame %d is keyed twice (\"%s\" at %d:%d and \"%s\")", f,
                          keys->members[j].key, keys->members[j].line, keys->members[j].col,
                          m->key);
    if (f <= frame && (!*lo || f > *flo)) *lo = m, *flo = f;
    if (f >= frame && (!*hi || f < *fhi)) *hi = m, *fhi = f;
  }
  if (!*lo) *lo = *hi, *flo = *fhi; /* before the first key: hold it */
  if (!*hi) *hi = *lo, *fhi = *flo; /* after the last key: hold it */
  return BK_OK;
}

/* {"keys": {...}} at the context's frame into out. */
static int keyed_object(const sc_ctx_t *c, const json_value_t *v, const char *path,
                        const sc_keyed_t *k, float *out) {
  static const char *const known[] = {"keys", NULL};
  char p[SC_KEY_MAX];
  const json_value_t *keys;
  int rc;
  sc_check_keys(c, v, path, known);
  if ((rc = sc_required(c, v, path, "keys", &keys))) return rc;
  sc_key(p, path, "keys");
  if (keys->type != JSON_OBJECT || keys->count == 0)
    return sc_fail(c, keys, p, "expected an object of frame: value pairs such as "
                   "{\"1\": ..., \"24\": ...}, found %s",
                   keys->type == JSON_OBJECT ? "an empty object" : json_type_phrase(keys));
  const json_member_t *lo, *hi;
  int flo = 0, fhi = 0;
  if ((rc = bracket(c, keys, p, c->frame, &lo, &hi, &flo, &fhi))) return rc;
  /* every key is checked, not only the two this frame reads */
  float a[3], b[3];
  for (size_t i = 0; i < keys->count; i++)
    if ((rc = key_value(c, &keys->members[i], p, k, a))) return rc;
  key_value(c, lo, p, k, a);
  key_value(c, hi, p, k, b);
  double t = fhi > flo ? (double)(c->frame - flo) / (double)(fhi - flo) : 0.0;
  double len = 0.0, mix[3];
  for (size_t i = 0; i < k->n; i++) {
    mix[i] = t == 0.0 ? a[i] : (double)a[i] + t * ((double)b[i] - a[i]);
    len += mix[i] * mix[i];
  }
  if (k->unit && !(sqrt(len) > 1e-6))
    return sc_fail(c, keys, p, "keys %d and %d point in opposite directions: at frame %d "
                   "their mix has no direction (add a key between them)", flo, fhi, c->frame);
  for (size_t i = 0; i < k->n; i++)
    out[i] = (float)(k->unit && t != 0.0 ? mix[i] / sqrt(len) : mix[i]);
  if (c->keyed) (*c->keyed)++;
  return BK_OK;
}

int sc_keyed(const sc_ctx_t *c, const json_value_t *v, const char *path, const sc_keyed_t *k,
             float *out) {
  if (v->type == JSON_OBJECT) return keyed_object(c, v, path, k, out);
  return plain_value(c, v, path, k, out);
}

int sc_opt_keyed(const sc_ctx_t *c, const json_value_t *obj, const char *parent, const char *key,
                 const sc_keyed_t *k, float *out) {
  char p[SC_KEY_MAX];
  const json_value_t *v = json_object_get(obj, key);
  return v ? sc_keyed(c, v, sc_key(p, parent, key), k, out) : BK_OK;
}
