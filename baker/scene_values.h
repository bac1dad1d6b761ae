/* scene_values.h: typed values of the scene's JSON tree with positioned
 * errors, for the section readers of baker/scene.c (private to the scene
 * stage).
 *
 * Every getter checks one value and, when it is wrong, fails with
 * "scene.json:LINE:COL: key.path: expected WHAT, found WHAT", pointing at the
 * value the user has to change. Key paths are built as the user wrote them
 * (`lights[0].angle_deg`, `grid.bounds[1][2]`); unknown keys get a warning
 * with the nearest known key. */
#ifndef BAKER_SCENE_VALUES_H
#define BAKER_SCENE_VALUES_H

#include <float.h>
#include <stddef.h>

#include "base/common.h"
#include "json.h"
#include "scene.h"

#define SC_KEY_MAX 512 /* longest key path quoted in a message */

typedef struct sc_ctx {
  const char *file; /* the scene path as given, for messages */
  const char *dir;  /* for relative paths */
  bk_error_t *err;
  /* --set KEY=VALUE texts: values they put in the tree carry line 0 and, as
   * column, the 1-based index of their --set, so messages name it */
  const char *const *sets;
  int frame;  /* the frame keyframed values are evaluated at (scene_keys.c) */
  int *keyed; /* counts the keyframed values read; NULL: not counted */
} sc_ctx_t;

/* "scene.json:LINE:COL", or "--set KEY=VALUE" for a value from the command
 * line, into buf. */
const char *sc_origin(const sc_ctx_t *c, int line, int col, char *buf, size_t len);

/* The values a number may take. hi_silent: hi is only the limit of the C
 * type, not worth mentioning unless the value exceeds it. */
typedef struct sc_range {
  double lo, hi;
  unsigned char lo_open, hi_open, integer, hi_silent;
} sc_range_t;

#define SC_NOLIM ((double)FLT_MAX)

__attribute__((format(printf, 5, 6))) int sc_fail_at(const sc_ctx_t *c, int line, int col,
                                                     const char *path, const char *fmt, ...);
#define sc_fail(c, v, path, ...) sc_fail_at((c), (v)->line, (v)->col, (path), __VA_ARGS__)

const char *sc_key(char *buf, const char *parent, const char *key);
const char *sc_index(char *buf, const char *parent, size_t i);
void sc_warn_unknown(const sc_ctx_t *c, const json_member_t *m, const char *parent,
                     const char *const *known);
int sc_known(const char *key, const char *const *known);
void sc_check_keys(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                   const char *const *known);
int sc_number(const sc_ctx_t *c, const json_value_t *v, const char *path,
              const sc_range_t *r, double *out);
int sc_float(const sc_ctx_t *c, const json_value_t *v, const char *path,
             const sc_range_t *r, float *out);
const char *sc_vec_text(const json_value_t *v, char *buf, size_t n);
int sc_floats(const sc_ctx_t *c, const json_value_t *v, const char *path,
              const sc_range_t *r, size_t n, int scalar_ok, float *out);
int sc_string(const sc_ctx_t *c, const json_value_t *v, const char *path, char *out,
              size_t size);
int sc_enum(const sc_ctx_t *c, const json_value_t *v, const char *path,
            const char *const *names, int n, int *out);
int sc_file(const sc_ctx_t *c, const json_value_t *v, const char *path,
            char out[SCENE_PATH_MAX], char where[SCENE_WHERE_MAX]);
int sc_object(const sc_ctx_t *c, const json_value_t *v, const char *path);
int sc_required(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                const char *key, const json_value_t **out);
int sc_opt_float(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                 const char *key, const sc_range_t *r, float *out);
int sc_opt_floats(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                  const char *key, const sc_range_t *r, size_t n, int scalar_ok,
                  float *out);
int sc_opt_int(const sc_ctx_t *c, const json_value_t *obj, const char *path,
               const char *key, const sc_range_t *r, long long *out);
int sc_opt_bool(const sc_ctx_t *c, const json_value_t *obj, const char *path,
                const char *key, int *out);
int sc_direction(const sc_ctx_t *c, const json_value_t *v, const char *path, float d[3]);

/* scene_keys.c: a value that may be keyframed, {"keys": {"FRAME": VALUE}},
 * each VALUE what the plain key takes (n numbers in range, one number for
 * all n when scalar_ok; a unit vector normalised), linear in the frame
 * between keys and held outside them; a plain value reads as before. */
typedef struct sc_keyed {
  const sc_range_t *range;
  size_t n;
  int scalar_ok, unit;
} sc_keyed_t;
int sc_keyed(const sc_ctx_t *c, const json_value_t *v, const char *path, const sc_keyed_t *k,
             float *out);
int sc_opt_keyed(const sc_ctx_t *c, const json_value_t *obj, const char *parent, const char *key,
                 const sc_keyed_t *k, float *out);

#endif
