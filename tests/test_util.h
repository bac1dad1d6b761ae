/* test_util.h: the check macros and file helpers the tests share.
 *
 * One vocabulary for every test:
 *   EXPECT(cond)  EXPECT(cond, fmt, ...)    on failure a line, counted in
 *                                           tu_failures (main returns non-zero)
 *   REQUIRE(cond) REQUIRE(cond, fmt, ...)   on failure a line, then exit(1)
 *   EXPECT_NEAR(a, b, tol)                  |a - b| <= tol, counted
 * The line reads "FAIL file:line: cond: explanation" (or "... a = x,
 * expected y (tol t)"); fmt must be a string literal.
 * Also: tu_path/tu_write_text for files under tu_dir, and tu_rel_l2, the
 * relative L2 error sqrt(sum (x - t)^2 / sum t^2). */
#ifndef TEST_UTIL_H
#define TEST_UTIL_H

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int tu_failures __attribute__((unused));
/* directory the test writes its files into (under the build directory) */
static const char *tu_dir __attribute__((unused));

static inline void tu_fail(int fatal, const char *file, int line, const char *cond,
                           const char *fmt, ...) __attribute__((format(printf, 5, 6)));
static inline void tu_fail(int fatal, const char *file, int line, const char *cond,
                           const char *fmt, ...) {
  fprintf(stderr, "FAIL %s:%d: %s", file, line, cond);
  if (strcmp(fmt, ": ") != 0) { /* an explanation follows the separator */
    va_list ap;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
  }
  fputc('\n', stderr);
  if (fatal) exit(1);
  tu_failures++;
}

/* the separator ": " is glued to the format, so the explanation may be left out */
#define EXPECT(cond, ...) \
  do { if (!(cond)) tu_fail(0, __FILE__, __LINE__, #cond, ": " __VA_ARGS__); } while (0)
#define REQUIRE(cond, ...) \
  do { if (!(cond)) tu_fail(1, __FILE__, __LINE__, #cond, ": " __VA_ARGS__); } while (0)
#define EXPECT_NEAR(a, b, tol)                                                               \
  do {                                                                                     \
    double a_ = (a), b_ = (b);                                                             \
    if (!(fabs(a_ - b_) <= (tol))) {                                                       \
      fprintf(stderr, "FAIL %s:%d: %s = %.9g, expected %.9g (tol %g)\n", __FILE__, __LINE__, \
              #a, a_, b_, (double)(tol));                                                  \
      tu_failures++;                                                                       \
    }                                                                                      \
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
