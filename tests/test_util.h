/* test_util.h: the check macros and file helpers the tests share.
 *
 * In: a condition (and for most styles a printf-style explanation). Out: on
 * failure one line on stderr naming file:line, then either a count in
 * tu_failures (the test goes on and main returns non-zero) or exit(1). The
 * styles differ only in the words of that line, kept as each test had them:
 *   TU_EXPECT(cond, fmt, ...)       "FAIL file:line: cond: msg", counted
 *   TU_REQUIRE(cond, fmt, ...)      "FAIL file:line: cond: msg", exit(1)
 *   TU_EXPECT_MSG(cond, fmt, ...)   "FAIL file:line: msg", counted
 *   TU_REQUIRE_MSG(cond, fmt, ...)  "FAIL file:line: msg", exit(1)
 *   TU_CHECK_PLAIN(cond)            "file:line: check failed: cond", counted
 *   TU_CHECK_NEAR(a, b, tol)        "file:line: a = x, expected y (tol t)", counted
 * A test aliases the one it uses with an object-like macro
 * (`#define CHECK TU_EXPECT`), so that #cond is the text as written.
 * Also: tu_path/tu_write_text for files under tu_dir, and tu_rel_l2, the
 * relative L2 error sqrt(sum (x - t)^2 / sum t^2). */
#ifndef TEST_UTIL_H
#define TEST_UTIL_H

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

static int tu_failures __attribute__((unused));
/* directory the test writes its files into (under the build directory) */
static const char *tu_dir __attribute__((unused));

static inline void tu_fail(int fatal, const char *file, int line, const char *cond,
                           const char *fmt, ...) __attribute__((format(printf, 5, 6)));
static inline void tu_fail(int fatal, const char *file, int line, const char *cond,
                           const char *fmt, ...) {
  if (cond)
    fprintf(stderr, "FAIL %s:%d: %s: ", file, line, cond);
  else
    fprintf(stderr, "FAIL %s:%d: ", file, line);
  va_list ap;
  va_start(ap, fmt);
  vfprintf(stderr, fmt, ap);
  va_end(ap);
  fputc('\n', stderr);
  if (fatal) exit(1);
  tu_failures++;
}

#define TU_EXPECT(cond, ...) \
  do { if (!(cond)) tu_fail(0, __FILE__, __LINE__, #cond, __VA_ARGS__); } while (0)
#define TU_REQUIRE(cond, ...) \
  do { if (!(cond)) tu_fail(1, __FILE__, __LINE__, #cond, __VA_ARGS__); } while (0)
#define TU_EXPECT_MSG(cond, ...) \
  do { if (!(cond)) tu_fail(0, __FILE__, __LINE__, NULL, __VA_ARGS__); } while (0)
#define TU_REQUIRE_MSG(cond, ...) \
  do { if (!(cond)) tu_fail(1, __FILE__, __LINE__, NULL, __VA_ARGS__); } while (0)

#define TU_CHECK_PLAIN(cond)                                                   \
  do {                                                                         \
    if (!(cond)) {                                                             \
      fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
      tu_failures++;                                                           \
    }                                                                          \
  } while (0)
#define TU_CHECK_NEAR(a, b, tol)                                                        \
  do {                                                                                  \
    double a_ = (a), b_ = (b);                                                          \
    if (!(fabs(a_ - b_) <= (tol))) {                                                    \
      fprintf(stderr, "%s:%d: %s = %.9g, expected %.9g (tol %g)\n", __FILE__, __LINE__, \
              #a, a_, b_, (double)(tol));                                               \
      tu_failures++;                                                                    \
    }                                                                                   \
  } while (0)

/* tu_dir/name into path (len bytes). */
static inline void tu_path(char *path, size_t len, const char *name) {
  snprintf(path, len, "%s/%s", tu_dir, name);
}

/* Writes text to tu_dir/name and leaves its path in path; a file that cannot
 * be opened is a counted failure. */
static inline void tu_write_text(const char *name, const char *text, char *path, size_t len) {
  tu_path(path, len, name);
  FILE *f = fopen(path, "wb");
  if (!f) {
    perror(path);
    tu_failures++;
    return;
  }
  fputs(text, f);
  fclose(f);
}

/* Relative L2 error of x against the truth t over n values:
 * sqrt(sum (x - t)^2 / sum t^2). */
static inline double tu_rel_l2(const float *x, const float *t, size_t n) {
  double num = 0.0, den = 0.0;
  for (size_t i = 0; i < n; i++) {
    double d = (double)x[i] - t[i];
    num += d * d;
    den += (double)t[i] * t[i];
  }
  return sqrt(num / den);
}

#endif
