/* frames.c: frame ranges ("A-BxS"), frame lists ("1-3,7,10-20:2") and frame patterns (####, $F4) in paths. */
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

/* One range "A", "A-B", "A-BxS" or "A-B:S" at p; *end is left after it. 0 when the text is no range. */
static int parse_range(const char *p, const char **end, frames_range_t *r) {
  int a, b, s = 1;
  if (!parse_int(p, &p, &a)) return 0;
  b = a;
  if (*p == '-') {
    if (!parse_int(p + 1, &p, &b)) return 0;
    if (*p == 'x' || *p == 'X' || *p == ':') {
      if (!parse_int(p + 1, &p, &s)) return 0;
    }
  }
  *r = (frames_range_t){a, b, s};
  *end = p;
  return 1;
}

/* B >= A, S >= 1 and not too many frames; `text` is the element as typed. */
static int check_range(const frames_range_t *r, const char *where, const char *text, int len,
                       bk_error_t *err) {
  if (r->last < r->first)
    return bk_fail(err, BK_ERR_INPUT, "%s: frame range \"%.*s\" ends (%d) before it starts (%d)",
                   where, len, text, r->last, r->first);
  if (r->step < 1)
    return bk_fail(err, BK_ERR_INPUT, "%s: frame range \"%.*s\": step must be >= 1, got %d",
                   where, len, text, r->step);
  long long count = ((long long)r->last - r->first) / r->step + 1;
  if (count > FRAMES_MAX_COUNT)
    return bk_fail(err, BK_ERR_INPUT, "%s: frame range \"%.*s\" has %lld frames (more than %d)",
                   where, len, text, count, FRAMES_MAX_COUNT);
  return BK_OK;
}

#define FRAMES_SYNTAX "\"A\", \"A-B\", \"A-BxS\" or \"A-B:S\""

int frames_parse(const char *spec, const char *where, frames_range_t *out, bk_error_t *err) {
  const char *p = spec;
  frames_range_t r;
  if (!where) where = "frames";
  if (!spec || !parse_range(spec, &p, &r) || *p != 0)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: expected a frame range " FRAMES_SYNTAX " (e.g. 1-100x2), got \"%s\"",
                   where, spec ? spec : "(null)");
  int rc = check_range(&r, where, spec, (int)strlen(spec), err);
  if (!rc) *out = r;
  return rc;
}

/* Keeps the first place of each frame: sorts (frame, place) pairs, marks the
 * later places of equal frames, and compacts in the original order. */
typedef struct frame_place { int frame, place; } frame_place_t;
static int by_frame(const void *a, const void *b) {
  const frame_place_t *x = a, *y = b;
  if (x->frame != y->frame) return x->frame < y->frame ? -1 : 1;
  return x->place < y->place ? -1 : x->place > y->place;
}
static int drop_repeats(frames_list_t *l, bk_error_t *err) {
  frame_place_t *fp = bk_calloc((size_t)l->count, sizeof *fp, "frame list", err);
  unsigned char *repeat = bk_calloc((size_t)l->count, 1, "frame list", err);
  if (!fp || !repeat) {
    free(fp);
    free(repeat);
    return BK_ERR_RUNTIME;
  }
  for (int i = 0; i < l->count; i++) fp[i] = (frame_place_t){l->frames[i], i};
  qsort(fp, (size_t)l->count, sizeof *fp, by_frame);
  for (int i = 1; i < l->count; i++)
    if (fp[i].frame == fp[i - 1].frame) repeat[fp[i].place] = 1;
  int n = 0;
  for (int i = 0; i < l->count; i++)
    if (!repeat[i]) l->frames[n++] = l->frames[i];
  l->count = n;
  free(fp);
  free(repeat);
  return BK_OK;
}

/* Appends the frames of r to l (capacity *cap), refusing a list that grows
 * past FRAMES_MAX_COUNT. */
static int append_range(frames_list_t *l, int *cap, const frames_range_t *r, const char *where,
                        const char *spec, bk_error_t *err) {
  int n = frames_count(r);
  if ((long long)l->count + n > FRAMES_MAX_COUNT)
    return bk_fail(err, BK_ERR_INPUT, "%s: frame list \"%.200s\" has more than %d frames", where,
                   spec, FRAMES_MAX_COUNT);
  if (l->count + n > *cap) {
    int want = *cap ? *cap : 16;
    while (want < l->count + n) want = want > FRAMES_MAX_COUNT / 2 ? FRAMES_MAX_COUNT : want * 2;
    int *bigger = realloc(l->frames, (size_t)want * sizeof *bigger);
    if (!bigger) return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory for the frame list", where);
    l->frames = bigger;
    *cap = want;
  }
  for (int i = 0; i < n; i++) l->frames[l->count++] = frames_at(r, i);
  return BK_OK;
}

static int parse_elements(const char *spec, const char *where, frames_list_t *l, bk_error_t *err) {
  int cap = 0, rc;
  const char *p = spec;
  for (;;) {
    while (*p == ' ' || *p == '\t') p++;
    const char *start = p;
    frames_range_t r;
    int ok = parse_range(p, &p, &r);
    while (ok && (*p == ' ' || *p == '\t')) p++;
    if (!ok || (*p != ',' && *p != 0))
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: expected a frame list of " FRAMES_SYNTAX " separated by commas (e.g. "
                     "1-3,7,10-20x2 or 1-20:2); element \"%.*s\" of \"%.200s\" is none of them",
                     where, (int)strcspn(start, ","), start, spec);
    if ((rc = check_range(&r, where, start, (int)strcspn(start, ", \t"), err)) ||
        (rc = append_range(l, &cap, &r, where, spec, err)))
      return rc;
    if (*p == 0) return BK_OK;
    p++; /* the comma */
  }
}

int frames_parse_list(const char *spec, const char *where, frames_list_t *out, bk_error_t *err) {
  if (!where) where = "frames";
  *out = (frames_list_t){NULL, 0};
  int rc = spec ? parse_elements(spec, where, out, err)
                : bk_fail(err, BK_ERR_INPUT, "%s: no frame list given", where);
  if (!rc) rc = drop_repeats(out, err);
  if (rc) frames_list_free(out);
  return rc;
}

void frames_list_free(frames_list_t *l) {
  free(l->frames);
  l->frames = NULL;
  l->count = 0;
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
