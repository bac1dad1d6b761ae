/* frames.c: frame ranges ("A-BxS") and frame patterns (####, $F4) in paths. */
#include "base/frames.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

/* One integer with an optional sign and nothing before it (strtol would
 * also skip white space, which a range never contains). */
static int parse_int(const char *s, const char **end, int *out) {
  const char *p = s;
  if (*p == '-' || *p == '+') p++;
  if (!isdigit((unsigned char)*p)) return 0;
  errno = 0;
  char *e;
  long v = strtol(s, &e, 10);
  if (errno == ERANGE || v < INT_MIN || v > INT_MAX) return 0;
  *out = (int)v;
  *end = e;
  return 1;
}

int frames_parse(const char *spec, const char *where, frames_range_t *out, bk_error_t *err) {
  const char *p = spec;
  int a, b, s = 1;
  if (!where) where = "frames";
  if (!spec || !parse_int(p, &p, &a)) goto bad;
  b = a;
  if (*p == '-') {
    if (!parse_int(p + 1, &p, &b)) goto bad;
    if (*p == 'x' || *p == 'X') {
      if (!parse_int(p + 1, &p, &s)) goto bad;
    }
  }
  if (*p != 0) goto bad;
  if (b < a)
    return bk_fail(err, BK_ERR_INPUT, "%s: frame range \"%s\" ends (%d) before it starts (%d)",
                   where, spec, b, a);
  if (s < 1)
    return bk_fail(err, BK_ERR_INPUT, "%s: frame range \"%s\": step must be >= 1, got %d", where,
                   spec, s);
  long long count = ((long long)b - a) / s + 1;
  if (count > FRAMES_MAX_COUNT)
    return bk_fail(err, BK_ERR_INPUT, "%s: frame range \"%s\" has %lld frames (more than %d)",
                   where, spec, count, FRAMES_MAX_COUNT);
  out->first = a;
  out->last = b;
  out->step = s;
  return BK_OK;
bad:
  return bk_fail(err, BK_ERR_INPUT,
                 "%s: expected a frame range \"A\", \"A-B\" or \"A-BxS\" (e.g. 1-100x2), got \"%s\"",
                 where, spec ? spec : "(null)");
}

int frames_count(const frames_range_t *r) {
  return (int)(((long long)r->last - r->first) / r->step + 1);
}

/* Length of the frame token at p (0 if none) and its padding (0 = none). */
static size_t token_at(const char *p, int *pad) {
  if (*p == '#') {
    size_t n = 0;
    while (p[n] == '#') n++;
    *pad = (int)n;
    return n;
  }
  if (p[0] == '$' && p[1] == 'F') {
    char c = p[2];
    if (c >= '1' && c <= '9') {
      *pad = c - '0';
      return 3;
    }
    if (isalpha((unsigned char)c) || c == '_' || isdigit((unsigned char)c)) return 0; /* $FPS, $F0.. */
    *pad = 0;
    return 2;
  }
  return 0;
}

int frames_has_pattern(const char *path) {
  int pad;
  for (const char *p = path; *p; p++)
    if (token_at(p, &pad)) return 1;
  return 0;
}

int frames_expand(const char *pattern, int frame, char *out, size_t len, bk_error_t *err) {
  size_t o = 0;
  for (const char *p = pattern; *p;) {
    int pad = 0;
    size_t tok = token_at(p, &pad);
    char piece[64];
    size_t n;
    if (tok) {
      int w = snprintf(piece, sizeof piece, "%0*d", pad, frame);
      if (w < 0 || (size_t)w >= sizeof piece)
        return bk_fail(err, BK_ERR_INPUT, "%s: frame pattern pads to %d digits (at most %d)",
                       pattern, pad, (int)sizeof piece - 2);
      n = (size_t)w;
      p += tok;
    } else {
      piece[0] = *p++;
      n = 1;
    }
    if (o + n + 1 > len)
      return bk_fail(err, BK_ERR_INPUT, "%s: path too long with frame %d (limit %zu bytes)",
                     pattern, frame, len ? len - 1 : 0);
    memcpy(out + o, piece, n);
    o += n;
  }
  if (len == 0) return bk_fail(err, BK_ERR_INPUT, "%s: no room for the path", pattern);
  out[o] = 0;
  return BK_OK;
}
