/* json.c: recursive-descent JSON parser that records positions (json.h).
 *
 * The parser walks the text once, keeping the line and column of the next
 * character. Every failure goes through jp_fail, which prefixes
 * "FILE:LINE:COL: " and sets the flag that unwinds the recursion. */
#include "json.h"

#include <locale.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

typedef struct jp {
  const char *p, *end;
  const char *file;
  int line, col; /* of *p */
  bk_error_t *err;
} jp_t;

static int jp_peek(const jp_t *j) { return j->p < j->end ? (unsigned char)*j->p : -1; }

static void jp_advance(jp_t *j) {
  unsigned char c = (unsigned char)*j->p++;
  if (c == '\n') {
    j->line++;
    j->col = 1;
  } else if ((c & 0xC0) != 0x80) { /* UTF-8 continuation bytes share a column */
    j->col++;
  }
}

static void jp_skip_ws(jp_t *j) {
  for (int c = jp_peek(j); c == ' ' || c == '\t' || c == '\n' || c == '\r'; c = jp_peek(j))
    jp_advance(j);
}

static int is_word_char(int c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
}

/* Length of the well-formed UTF-8 sequence at s, 0 when it is not one
 * (overlong forms, surrogates and code points above U+10FFFF are refused). */
static int utf8_seq_len(const unsigned char *s, size_t avail) {
  unsigned c = s[0], cp;
  int n;
  if (c < 0x80) return 1;
  if (c >= 0xC2 && c <= 0xDF) n = 2, cp = c & 0x1F;
  else if ((c & 0xF0) == 0xE0) n = 3, cp = c & 0x0F;
  else if (c >= 0xF0 && c <= 0xF4) n = 4, cp = c & 0x07;
  else return 0;
  if ((size_t)n > avail) return 0;
  for (int i = 1; i < n; i++) {
    if ((s[i] & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (s[i] & 0x3F);
  }
  if ((n == 3 && cp < 0x800) || (n == 4 && (cp < 0x10000 || cp > 0x10FFFF)) ||
      (cp >= 0xD800 && cp <= 0xDFFF))
    return 0;
  return n;
}

/* What the parser sees at the cursor, for "found ..." */
static const char *jp_found(const jp_t *j, char *buf, size_t size) {
  int c = jp_peek(j);
  if (c < 0) return "end of file";
  if (c == '\n' || c == '\r') return "end of line";
  if (c < 0x20 || c == 0x7F) {
    snprintf(buf, size, "control character U+%04X", c);
  } else if (is_word_char(c)) { /* a whole word reads better than its first letter */
    size_t n = 0;
    while (n < 24 && j->p + n < j->end && is_word_char((unsigned char)j->p[n])) n++;
    snprintf(buf, size, "'%.*s'", (int)n, j->p);
  } else if (c >= 0x80) {
    int n = utf8_seq_len((const unsigned char *)j->p, (size_t)(j->end - j->p));
    if (n == 0) snprintf(buf, size, "invalid UTF-8 byte 0x%02X", c);
    else snprintf(buf, size, "'%.*s'", n, j->p);
  } else {
    snprintf(buf, size, "'%c'", c);
  }
  return buf;
}

__attribute__((format(printf, 4, 5))) static void *jp_fail(jp_t *j, int line, int col,
                                                           const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  bk_fail(j->err, BK_ERR_INPUT, "%s:%d:%d: %s", j->file, line, col, msg);
  return NULL;
}

static void *jp_oom(jp_t *j) {
  bk_fail(j->err, BK_ERR_RUNTIME, "%s: out of memory while parsing JSON", j->file);
  return NULL;
}

static json_value_t *jv_new(jp_t *j, json_type_t type, int line, int col) {
  json_value_t *v = calloc(1, sizeof *v);
  if (!v) return jp_oom(j);
  v->type = type;
  v->line = line;
  v->col = col;
  return v;
}

/* Grows *items (of `elem` bytes each) so that one more fits. */
static int jp_grow(void **items, size_t count, size_t *cap, size_t elem) {
  if (count < *cap) return 1;
  size_t ncap = *cap ? *cap * 2 : 8, bytes;
  if (!bk_mul_size(ncap, elem, &bytes)) return 0;
  void *bigger = realloc(*items, bytes);
  if (!bigger) return 0;
  *items = bigger;
  *cap = ncap;
  return 1;
}

static int hex4(const char *s) {
  int v = 0;
  for (int i = 0; i < 4; i++) {
    int c = (unsigned char)s[i], d;
    if (c >= '0' && c <= '9') d = c - '0';
    else if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    else return -1;
    v = v * 16 + d;
  }
  return v;
}

static size_t utf8_encode(unsigned cp, char *out) {
  if (cp < 0x80) return out[0] = (char)cp, 1;
  if (cp < 0x800) {
    out[0] = (char)(0xC0 | (cp >> 6));
    out[1] = (char)(0x80 | (cp & 0x3F));
    return 2;
  }
  if (cp < 0x10000) {
    out[0] = (char)(0xE0 | (cp >> 12));
    out[1] = (char)(0x80 | ((cp >> 6) & 0x3F));
    out[2] = (char)(0x80 | (cp & 0x3F));
    return 3;
  }
  out[0] = (char)(0xF0 | (cp >> 18));
  out[1] = (char)(0x80 | ((cp >> 12) & 0x3F));
  out[2] = (char)(0x80 | ((cp >> 6) & 0x3F));
  out[3] = (char)(0x80 | (cp & 0x3F));
  return 4;
}

/* A "\uXXXX" at the cursor (the backslash already consumed: cursor on 'u'). */
static int jp_unicode_escape(jp_t *j, int line, int col) {
  char buf[64];
  jp_advance(j); /* 'u' */
  int v = j->end - j->p >= 4 ? hex4(j->p) : -1;
  if (v < 0) {
    jp_fail(j, line, col, "expected 4 hex digits after '\\u', found %s", jp_found(j, buf, sizeof buf));
    return -1;
  }
  for (int i = 0; i < 4; i++) jp_advance(j);
  return v;
}

/* Decodes the string at the cursor (on its opening quote) into a new buffer. */
static char *jp_string(jp_t *j, size_t *out_len) {
  int line = j->line, col = j->col;
  char buf[64];
  /* the decoded text is never longer than the raw text up to the closing quote */
  const char *q = j->p + 1;
  while (q < j->end && *q != '"') q += (*q == '\\' && q + 1 < j->end) ? 2 : 1;
  char *s = malloc((size_t)(q - j->p) + 1), *o = s;
  if (!s) return jp_oom(j);
  jp_advance(j); /* opening quote */
  for (;;) {
    int c = jp_peek(j);
    if (c < 0 || c == '\n' || c == '\r') {
      jp_fail(j, line, col, "unterminated string: expected a closing '\"', found %s",
              c < 0 ? "end of file" : "end of line");
      goto error;
    }
    if (c == '"') break;
    if (c < 0x20) {
      jp_fail(j, j->line, j->col, "expected an escape sequence such as \\t, found a raw %s in a string",
              jp_found(j, buf, sizeof buf));
      goto error;
    }
    if (c >= 0x80) {
      int n = utf8_seq_len((const unsigned char *)j->p, (size_t)(j->end - j->p));
      if (n == 0) {
        jp_fail(j, j->line, j->col, "invalid UTF-8 byte 0x%02X in a string", c);
        goto error;
      }
      for (int i = 0; i < n; i++, jp_advance(j)) *o++ = *j->p;
      continue;
    }
    if (c != '\\') {
      *o++ = (char)c;
      jp_advance(j);
      continue;
    }
    int eline = j->line, ecol = j->col;
    jp_advance(j); /* backslash */
    static const char escapes[] = "\"\\/bfnrt", decoded[] = "\"\\/\b\f\n\r\t";
    const char *simple = jp_peek(j) > 0 ? strchr(escapes, jp_peek(j)) : NULL;
    if (simple) {
      *o++ = decoded[simple - escapes];
      jp_advance(j);
      continue;
    }
    if (jp_peek(j) != 'u') {
      jp_fail(j, eline, ecol, "expected one of \\\" \\\\ \\/ \\b \\f \\n \\r \\t \\u after '\\', found %s",
              jp_found(j, buf, sizeof buf));
      goto error;
    }
    int cp = jp_unicode_escape(j, eline, ecol);
    if (cp < 0) goto error;
    if (cp >= 0xDC00 && cp <= 0xDFFF) {
      jp_fail(j, eline, ecol, "expected a high surrogate before \\u%04X, found it alone", cp);
      goto error;
    }
    if (cp >= 0xD800 && cp <= 0xDBFF) { /* UTF-16 pair: the low half must follow */
      int lo = -1;
      if (j->end - j->p >= 2 && j->p[0] == '\\' && j->p[1] == 'u') {
        jp_advance(j);
        lo = jp_unicode_escape(j, eline, ecol);
        if (lo < 0) goto error;
      }
      if (lo < 0xDC00 || lo > 0xDFFF) {
        jp_fail(j, eline, ecol, "expected a low surrogate \\uDC00-\\uDFFF after \\u%04X, found %s",
                cp, lo < 0 ? "none" : "another character");
        goto error;
      }
      cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
    }
    o += utf8_encode((unsigned)cp, o);
  }
  jp_advance(j); /* closing quote */
  *o = 0;
  *out_len = (size_t)(o - s);
  return s;
error:
  free(s);
  return NULL;
}

static int is_digit(int c) { return c >= '0' && c <= '9'; }

/* One or more digits; `where` completes "expected a digit ...". */
static int jp_digits(jp_t *j, const char *where) {
  char buf[64];
  if (!is_digit(jp_peek(j))) {
    jp_fail(j, j->line, j->col, "expected a digit %s, found %s", where, jp_found(j, buf, sizeof buf));
    return 0;
  }
  while (is_digit(jp_peek(j))) jp_advance(j);
  return 1;
}

static json_value_t *jp_number(jp_t *j) {
  const char *start = j->p;
  json_value_t *v = jv_new(j, JSON_NUMBER, j->line, j->col);
  if (!v) return NULL;
  if (jp_peek(j) == '-') jp_advance(j);
  if (jp_peek(j) == '0') {
    jp_advance(j);
    if (is_digit(jp_peek(j))) {
      jp_fail(j, v->line, v->col, "expected a number, found one with a leading zero");
      goto error;
    }
  } else if (!jp_digits(j, "after '-'")) {
    goto error;
  }
  if (jp_peek(j) == '.') {
    jp_advance(j);
    if (!jp_digits(j, "after '.'")) goto error;
  }
  if (jp_peek(j) == 'e' || jp_peek(j) == 'E') {
    jp_advance(j);
    if (jp_peek(j) == '+' || jp_peek(j) == '-') jp_advance(j);
    if (!jp_digits(j, "in the exponent")) goto error;
  }
  v->string_len = (size_t)(j->p - start);
  if (!(v->string = malloc(v->string_len + 1))) {
    jp_oom(j);
    goto error;
  }
  memcpy(v->string, start, v->string_len);
  v->string[v->string_len] = 0;
  /* strtod follows the locale's decimal point; JSON's is always '.' */
  char *end, local[512];
  v->number = strtod(v->string, &end); /* 1e400 gives inf: callers refuse it */
  if (*end && v->string_len < sizeof local) {
    memcpy(local, v->string, v->string_len + 1);
    char *dot = strchr(local, '.');
    if (dot) *dot = localeconv()->decimal_point[0];
    v->number = strtod(local, NULL);
  }
  return v;
error:
  json_free(v);
  return NULL;
}

static json_value_t *jp_value(jp_t *j, int depth, const char *after);

static json_value_t *jp_array(jp_t *j, int depth) {
  char buf[64];
  size_t cap = 0;
  json_value_t *v = jv_new(j, JSON_ARRAY, j->line, j->col);
  if (!v) return NULL;
  jp_advance(j); /* '[' */
  jp_skip_ws(j);
  if (jp_peek(j) == ']') {
    jp_advance(j);
    return v;
  }
  for (const char *after = " or ']'";;) {
    json_value_t *item = jp_value(j, depth + 1, after);
    if (!item) goto error;
    if (!jp_grow((void **)&v->items, v->count, &cap, sizeof *v->items)) {
      json_free(item);
      jp_oom(j);
      goto error;
    }
    v->items[v->count++] = item;
    jp_skip_ws(j);
    if (jp_peek(j) == ']') break;
    if (jp_peek(j) != ',') {
      jp_fail(j, j->line, j->col, "expected ',' or ']' after array element, found %s",
              jp_found(j, buf, sizeof buf));
      goto error;
    }
    jp_advance(j);
    after = " after ','";
  }
  jp_advance(j); /* ']' */
  return v;
error:
  json_free(v);
  return NULL;
}

static json_value_t *jp_object(jp_t *j, int depth) {
  char buf[64];
  size_t cap = 0;
  json_member_t m = {0};
  json_value_t *v = jv_new(j, JSON_OBJECT, j->line, j->col);
  if (!v) return NULL;
  jp_advance(j); /* '{' */
  jp_skip_ws(j);
  if (jp_peek(j) == '}') {
    jp_advance(j);
    return v;
  }
  for (const char *after = " or '}'";;) {
    jp_skip_ws(j);
    if (jp_peek(j) != '"') {
      jp_fail(j, j->line, j->col, "expected a string key%s, found %s", after,
              jp_found(j, buf, sizeof buf));
      goto error;
    }
    m.line = j->line;
    m.col = j->col;
    if (!(m.key = jp_string(j, &m.key_len))) goto error;
    /* linear search: scene objects have a handful of keys */
    for (size_t i = 0; i < v->count; i++) {
      const json_member_t *o = &v->members[i];
      if (o->key_len == m.key_len && memcmp(o->key, m.key, m.key_len) == 0) {
        jp_fail(j, m.line, m.col, "duplicate key \"%s\" (first given at %d:%d)", m.key, o->line,
                o->col);
        goto error;
      }
    }
    jp_skip_ws(j);
    if (jp_peek(j) != ':') {
      jp_fail(j, j->line, j->col, "expected ':' after object key, found %s",
              jp_found(j, buf, sizeof buf));
      goto error;
    }
    jp_advance(j);
    if (!(m.value = jp_value(j, depth + 1, " after ':'"))) goto error;
    if (!jp_grow((void **)&v->members, v->count, &cap, sizeof *v->members)) {
      jp_oom(j);
      goto error;
    }
    v->members[v->count++] = m;
    m = (json_member_t){0};
    jp_skip_ws(j);
    if (jp_peek(j) == '}') break;
    if (jp_peek(j) != ',') {
      jp_fail(j, j->line, j->col, "expected ',' or '}' after object member, found %s",
              jp_found(j, buf, sizeof buf));
      goto error;
    }
    jp_advance(j);
    after = " after ','";
  }
  jp_advance(j); /* '}' */
  return v;
error:
  free(m.key);
  json_free(m.value);
  json_free(v);
  return NULL;
}

/* `after` completes "expected a value..." with where the parser stood. */
static json_value_t *jp_value(jp_t *j, int depth, const char *after) {
  char buf[64];
  jp_skip_ws(j);
  int c = jp_peek(j), line = j->line, col = j->col;
  if ((c == '[' || c == '{') && depth >= JSON_MAX_DEPTH)
    return jp_fail(j, line, col, "expected at most %d nested arrays and objects, found deeper nesting",
                   JSON_MAX_DEPTH);
  if (c == '[') return jp_array(j, depth);
  if (c == '{') return jp_object(j, depth);
  if (c == '-' || is_digit(c)) return jp_number(j);
  if (c == '"') {
    json_value_t *v = jv_new(j, JSON_STRING, line, col);
    if (v && !(v->string = jp_string(j, &v->string_len))) {
      json_free(v);
      return NULL;
    }
    return v;
  }
  static const char *const words[] = {"null", "false", "true"};
  size_t n = 0;
  while (j->p + n < j->end && is_word_char((unsigned char)j->p[n])) n++;
  for (int w = 0; w < 3; w++) {
    if (n == strlen(words[w]) && memcmp(j->p, words[w], n) == 0) {
      json_value_t *v = jv_new(j, w == 0 ? JSON_NULL : JSON_BOOL, line, col);
      if (v) v->boolean = (w == 2);
      for (size_t i = 0; i < n; i++) jp_advance(j);
      return v;
    }
  }
  return jp_fail(j, line, col, "expected a value%s, found %s", after, jp_found(j, buf, sizeof buf));
}

json_value_t *json_parse(const char *text, size_t len, const char *filename, bk_error_t *err) {
  char buf[64];
  jp_t j = {text, text + len, filename ? filename : "<json>", 1, 1, err};
  if (len >= 3 && memcmp(text, "\xEF\xBB\xBF", 3) == 0) j.p += 3; /* a BOM is allowed, ignored */
  json_value_t *root = jp_value(&j, 0, "");
  if (!root) return NULL;
  jp_skip_ws(&j);
  if (j.p < j.end) {
    jp_fail(&j, j.line, j.col, "expected end of file after the JSON document, found %s",
            jp_found(&j, buf, sizeof buf));
    json_free(root);
    return NULL;
  }
  return root;
}

void json_free(json_value_t *v) {
  if (!v) return;
  for (size_t i = 0; v->type == JSON_ARRAY && i < v->count; i++) json_free(v->items[i]);
  for (size_t i = 0; v->type == JSON_OBJECT && i < v->count; i++) {
    free(v->members[i].key);
    json_free(v->members[i].value);
  }
  free(v->items);
  free(v->members);
  free(v->string);
  free(v);
}

const json_member_t *json_object_member(const json_value_t *obj, const char *key) {
  if (!obj || obj->type != JSON_OBJECT) return NULL;
  size_t n = strlen(key);
  for (size_t i = 0; i < obj->count; i++)
    if (obj->members[i].key_len == n && memcmp(obj->members[i].key, key, n) == 0)
      return &obj->members[i];
  return NULL;
}

json_value_t *json_object_get(const json_value_t *obj, const char *key) {
  const json_member_t *m = json_object_member(obj, key);
  return m ? m->value : NULL;
}

const char *json_type_phrase(const json_value_t *v) {
  if (!v) return "nothing";
  switch (v->type) {
  case JSON_NULL: return "null";
  case JSON_BOOL: return v->boolean ? "true" : "false";
  case JSON_NUMBER: return "a number";
  case JSON_STRING: return "a string";
  case JSON_ARRAY: return "an array";
  case JSON_OBJECT: return "an object";
  }
  return "an unknown value";
}
