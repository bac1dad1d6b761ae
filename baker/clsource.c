/* clsource.c: kernel sources with their `#include "x.h"` expanded from the
 * embedded kernels/ files, so that a program is one string (what the binary
 * cache hashes) and the compiler's messages still name kernels/<file>:<line>. */
#define _POSIX_C_SOURCE 200809L
#include "clsource.h"

#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

/* Includes nest a few levels at most; deeper means a runaway expansion. */
#define CLH_MAX_INCLUDE_DEPTH 16

/* A growing string, always NUL-terminated. */
typedef struct clh_buf {
  char *p;
  size_t len, cap;
} clh_buf_t;

static int buf_add(clh_buf_t *b, const char *s, size_t n) {
  if (b->len + n + 1 > b->cap) {
    size_t cap = b->cap ? b->cap : 4096;
    while (cap < b->len + n + 1) {
      if (cap > SIZE_MAX / 2) return 0;
      cap *= 2;
    }
    char *q = realloc(b->p, cap);
    if (!q) return 0;
    b->p = q;
    b->cap = cap;
  }
  memcpy(b->p + b->len, s, n);
  b->len += n;
  b->p[b->len] = 0;
  return 1;
}

static int buf_printf(clh_buf_t *b, const char *fmt, ...) {
  char tmp[512];
  va_list ap;
  va_start(ap, fmt);
  int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
  va_end(ap);
  if (n < 0) return 0;
  return buf_add(b, tmp, (size_t)n < sizeof tmp ? (size_t)n : sizeof tmp - 1);
}

/* Kernel files are named as they are included, "kernels/x.h", or bare. */
const clh_source_t *clh_find_source(const clh_source_t *table, const char *name) {
  if (strncmp(name, "kernels/", 8) == 0) name += 8;
  for (const clh_source_t *s = table; s && s->name; s++)
    if (strcmp(s->name, name) == 0) return s;
  return NULL;
}

/* If `line` is `#include "x"`, copies x into name and returns 1. Lines with
 * <...> are left to the compiler (OpenCL C has no system headers to offer). */
static int parse_include(const char *line, const char *end, char *name, size_t cap) {
  const char *p = line;
  while (p < end && (*p == ' ' || *p == '\t')) p++;
  if (p >= end || *p != '#') return 0;
  p++;
  while (p < end && (*p == ' ' || *p == '\t')) p++;
  if (end - p < 7 || strncmp(p, "include", 7) != 0) return 0;
  p += 7;
  while (p < end && (*p == ' ' || *p == '\t')) p++;
  if (p >= end || *p != '"') return 0;
  const char *q = ++p;
  while (q < end && *q != '"') q++;
  if (q >= end || (size_t)(q - p) >= cap) return 0;
  memcpy(name, p, (size_t)(q - p));
  name[q - p] = 0;
  return 1;
}

static const char *base_name(const char *path) {
  const char *s = strrchr(path, '/');
  return s ? s + 1 : path;
}

/* `name` is what messages call the file (kernels/x.h); `stack` holds the
 * plain names being expanded, to catch cycles. `#line` keeps the compiler's
 * messages pointing at kernels/<file>:<line>. */
static int expand_rec(const clh_source_t *table, const char *name, const char *text,
                      const char **stack, int depth, clh_buf_t *out, bk_error_t *err) {
  if (!buf_printf(out, "#line 1 \"%s\"\n", name))
    return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory expanding includes", name);
  int line_no = 1;
  for (const char *line = text; *line;) {
    const char *end = strchr(line, '\n');
    const char *next = end ? end + 1 : line + strlen(line);
    if (!end) end = next;
    char inc[256];
    if (parse_include(line, end, inc, sizeof inc)) {
      const clh_source_t *s = clh_find_source(table, inc);
      if (!s) {
        clh_buf_t known = {0};
        for (const clh_source_t *t = table; t && t->name; t++)
          buf_printf(&known, "%s%s", known.len ? ", " : "", t->name);
        bk_fail(err, BK_ERR_RUNTIME,
                "%s:%d: #include \"%s\": not among the embedded kernel files (%s); add it to "
                "kernels/ and re-run cmake",
                name, line_no, inc, known.p ? known.p : "none");
        free(known.p);
        return BK_ERR_RUNTIME;
      }
      for (int d = 0; d < depth; d++) {
        if (strcmp(stack[d], s->name) == 0) {
          clh_buf_t chain = {0};
          for (int k = 0; k < depth; k++) buf_printf(&chain, "%s -> ", stack[k]);
          buf_printf(&chain, "%s", inc);
          bk_fail(err, BK_ERR_RUNTIME, "%s:%d: #include cycle: %s", name, line_no,
                  chain.p ? chain.p : inc);
          free(chain.p);
          return BK_ERR_RUNTIME;
        }
      }
      if (depth >= CLH_MAX_INCLUDE_DEPTH)
        return bk_fail(err, BK_ERR_RUNTIME, "%s:%d: includes nested deeper than %d", name,
                       line_no, CLH_MAX_INCLUDE_DEPTH);
      char shown[300];
      snprintf(shown, sizeof shown, "kernels/%s", s->name);
      stack[depth] = s->name;
      int rc = expand_rec(table, shown, s->text, stack, depth + 1, out, err);
      if (rc != BK_OK) return rc;
      if (!buf_printf(out, "#line %d \"%s\"\n", line_no + 1, name))
        return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory expanding includes", name);
    } else {
      if (!buf_add(out, line, (size_t)(next - line)) ||
          (*next == 0 && next > line && next[-1] != '\n' && !buf_add(out, "\n", 1)))
        return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory expanding includes", name);
    }
    line_no++;
    line = next;
  }
  return BK_OK;
}

char *clh_expand_with(const clh_source_t *table, const char *name, const char *text,
                      bk_error_t *err) {
  const char *stack[CLH_MAX_INCLUDE_DEPTH + 1];
  clh_buf_t out = {0};
  stack[0] = base_name(name);
  if (expand_rec(table, name, text, stack, 1, &out, err) != BK_OK) {
    free(out.p);
    return NULL;
  }
  return out.p;
}

char *clh_expand_source(const char *file, bk_error_t *err) {
  const clh_source_t *s = clh_find_source(clh_embedded_sources, file);
  if (!s) {
    bk_fail(err, BK_ERR_RUNTIME,
            "kernels/%s: not among the embedded kernel files (add it to kernels/ and re-run "
            "cmake)", file);
    return NULL;
  }
  char name[300];
  snprintf(name, sizeof name, "kernels/%s", s->name);
  return clh_expand_with(clh_embedded_sources, name, s->text, err);
}
