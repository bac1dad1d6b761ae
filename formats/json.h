/* json.h: a small, strict JSON parser (RFC 8259) that remembers where every
 * value and every object key stood in the text.
 *
 * In: the bytes of a document and a file name for messages. Out: a tree of
 * json_value_t, each value and each member key carrying its 1-based line and
 * column (columns count UTF-8 characters, a tab is one column), so that a
 * caller validating the tree (the scene loader) can point its own messages at
 * the offending value. Strings are decoded to UTF-8 (\uXXXX escapes and
 * surrogate pairs included). Syntax errors, duplicate keys and nesting deeper
 * than JSON_MAX_DEPTH are refused with "FILE:LINE:COL: expected ..., found ...".
 * No general-purpose library on the system keeps per-value positions, hence
 * this one. */
#ifndef BAKER_JSON_H
#define BAKER_JSON_H

#include <stddef.h>

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Deep enough for any scene (grid.bounds is 3 levels); shallow enough that a
 * hostile "[[[[..." cannot exhaust the stack of the recursive parser. */
#define JSON_MAX_DEPTH 64

typedef enum {
  JSON_NULL = 0,
  JSON_BOOL,
  JSON_NUMBER,
  JSON_STRING,
  JSON_ARRAY,
  JSON_OBJECT
} json_type_t;

typedef struct json_value json_value_t;

typedef struct json_member {
  char *key;        /* decoded UTF-8, NUL-terminated */
  size_t key_len;   /* may differ from strlen(key) when it holds \u0000 */
  int line, col;    /* position of the key's opening quote */
  json_value_t *value;
} json_member_t;

struct json_value {
  json_type_t type;
  int line, col;    /* position of the value's first character */
  int boolean;      /* JSON_BOOL */
  double number;    /* JSON_NUMBER; +-inf when the text overflows a double */
  /* JSON_STRING: decoded text. JSON_NUMBER: the number as written, so that
   * messages can quote it ("found 1e400"). NUL-terminated in both cases. */
  char *string;
  size_t string_len;
  size_t count;             /* elements (JSON_ARRAY) or members (JSON_OBJECT) */
  json_value_t **items;     /* JSON_ARRAY */
  json_member_t *members;   /* JSON_OBJECT, in document order */
};

/* Parses text[0..len). Returns the root, or NULL with err filled:
 * BK_ERR_INPUT for a malformed document, BK_ERR_RUNTIME when out of memory.
 * `filename` only appears in messages. */
json_value_t *json_parse(const char *text, size_t len, const char *filename, bk_error_t *err);
void json_free(json_value_t *v); /* NULL-safe, frees the whole tree */

/* The member named `key` of an object, or NULL (also when obj is not an
 * object). json_object_member gives the member itself, with the key's position. */
json_value_t *json_object_get(const json_value_t *obj, const char *key);
const json_member_t *json_object_member(const json_value_t *obj, const char *key);

/* "a number", "a string", "an array", "an object", "true", "false", "null":
 * for "expected X, found Y" messages. */
const char *json_type_phrase(const json_value_t *v);

#ifdef __cplusplus
}
#endif
#endif
