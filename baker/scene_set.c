/* scene_set.c: `--set KEY=VALUE` overrides of the scene's JSON tree, and the
 * scene read from standard input (see scene.h).
 *
 * An override replaces (or adds) one value by its dotted key path with array
 * indices, `medium.sigma_s`, `lights[0].intensity`, before the tree is
 * validated, so every check of the scene file applies to it as well; its
 * values carry line 0 and the override's index, and messages name the
 * `--set` instead of a line of the file. VALUE is JSON (`0.3`, `[5,5,5]`,
 * `"rk4"`); text that is not JSON is taken as a string (`--set
 * photons.integrator=rk4`). */
#define _POSIX_C_SOURCE 200809L
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "json.h"
#include "scene.h"

/* Every value of an override's tree points back at the override. */
static void mark_origin(json_value_t *v, int index) {
  v->line = 0;
  v->col = index + 1;
  for (size_t i = 0; v->type == JSON_ARRAY && i < v->count; i++) mark_origin(v->items[i], index);
  for (size_t i = 0; v->type == JSON_OBJECT && i < v->count; i++) {
    v->members[i].line = 0;
    v->members[i].col = index + 1;
    mark_origin(v->members[i].value, index);
  }
}

/* VALUE as JSON, else as a JSON string. */
static json_value_t *set_value(const char *text, int index, bk_error_t *err) {
  bk_error_t ignored;
  json_value_t *v = json_parse(text, strlen(text), "--set", &ignored);
  if (!v) {
    v = calloc(1, sizeof *v);
    if (v) v->string = strdup(text);
    if (!v || !v->string) {
      json_free(v);
      bk_fail(err, BK_ERR_RUNTIME, "--set: out of memory");
      return NULL;
    }
    v->type = JSON_STRING;
    v->string_len = strlen(text);
  }
  mark_origin(v, index);
  return v;
}

/* The member `name` of obj, added (holding an empty object) when missing. */
static json_value_t **member_slot(json_value_t *obj, const char *name, size_t n, int index) {
  for (size_t i = 0; i < obj->count; i++)
    if (obj->members[i].key_len == n && !memcmp(obj->members[i].key, name, n))
      return &obj->members[i].value;
  json_member_t *m = realloc(obj->members, (obj->count + 1) * sizeof *m);
  if (!m) return NULL;
  obj->members = m;
  m = &obj->members[obj->count];
  memset(m, 0, sizeof *m);
  m->key = strndup(name, n);
  m->key_len = n;
  m->col = index + 1;
  m->value = calloc(1, sizeof *m->value);
  if (!m->key || !m->value) {
    free(m->key);
    free(m->value);
    return NULL;
  }
  m->value->type = JSON_OBJECT;
  m->value->col = index + 1;
  obj->count++;
  return &m->value;
}

/* Walks KEY from the root to the slot its value goes into. */
static int find_slot(json_value_t *root, const char *set, size_t keylen, int index,
                     json_value_t ***slot, bk_error_t *err) {
  json_value_t **at = &root;
  const char *p = set, *end = set + keylen;
  while (p < end) {
    if (*p == '[') {
      char *q;
      unsigned long i = strtoul(p + 1, &q, 10);
      if (q == p + 1 || *q != ']' || !isdigit((unsigned char)p[1]))
        return bk_fail(err, BK_ERR_INPUT, "--set %s: expected an index like [0] at \"%.*s\"", set,
                       (int)(end - p), p);
      if ((*at)->type != JSON_ARRAY || i >= (*at)->count)
        return bk_fail(err, BK_ERR_INPUT, "--set %s: \"%.*s\" has no element [%lu] in the scene",
                       set, (int)(p - set), set, i);
      at = &(*at)->items[i];
      p = q + 1;
    } else {
      if (*p == '.' && p > set) p++;
      size_t n = strcspn(p, ".[=");
      if (n == 0 || p + n > end)
        return bk_fail(err, BK_ERR_INPUT, "--set %s: expected KEY=VALUE with KEY a path like "
                       "medium.sigma_s or lights[0].intensity", set);
      if ((*at)->type != JSON_OBJECT)
        return bk_fail(err, BK_ERR_INPUT, "--set %s: \"%.*s\" is not an object in the scene",
                       set, (int)(p - set - (p > set)), set);
      if (!(at = member_slot(*at, p, n, index)))
        return bk_fail(err, BK_ERR_RUNTIME, "--set: out of memory");
      p += n;
    }
  }
  *slot = at;
  return BK_OK;
}

int scene_apply_sets(json_value_t *root, const char *const *sets, int count, bk_error_t *err) {
  for (int k = 0; k < count; k++) {
    const char *eq = strchr(sets[k], '=');
    if (!eq || eq == sets[k])
      return bk_fail(err, BK_ERR_INPUT, "--set %s: expected KEY=VALUE (e.g. medium.sigma_s=0.3)",
                     sets[k]);
    json_value_t **slot = NULL;
    int rc = find_slot(root, sets[k], (size_t)(eq - sets[k]), k, &slot, err);
    if (rc) return rc;
    json_value_t *v = set_value(eq + 1, k, err);
    if (!v) return BK_ERR_RUNTIME;
    json_free(*slot);
    *slot = v;
  }
  return BK_OK;
}

/* Standard input is read once: every frame of a batch bakes the same text. */
int scene_read_stdin(const char **text, size_t *len, bk_error_t *err) {
  static char *buf;
  static size_t n;
  if (!buf) {
    size_t cap = 1 << 16;
    if (!(buf = malloc(cap + 1))) return bk_fail(err, BK_ERR_RUNTIME, "<stdin>: out of memory");
    size_t got;
    while ((got = fread(buf + n, 1, cap - n, stdin)) > 0) {
      n += got;
      if (n < cap) continue;
      char *bigger = realloc(buf, cap * 2 + 1);
      if (!bigger) return bk_fail(err, BK_ERR_RUNTIME, "<stdin>: out of memory");
      buf = bigger;
      cap *= 2;
    }
    buf[n] = 0;
  }
  *text = buf;
  *len = n;
  return BK_OK;
}
