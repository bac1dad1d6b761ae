/* view_arrays.c: the view's dense arrays (view_arrays.h). */
#define _DEFAULT_SOURCE /* madvise */
#define _POSIX_C_SOURCE 200809L
#include "view_arrays.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "base/parallel.h"
#include "vdbio.h"

static void zero_bytes(void *p, size_t lo, size_t hi) { memset((char *)p + lo, 0, hi - lo); }

void *view_alloc_unset(size_t count, size_t size, const char *what, bk_error_t *err) {
  size_t bytes;
  void *p = NULL;
  if (!bk_mul_size(count, size, &bytes) || posix_memalign(&p, VIEW_ALIGN, bytes ? bytes : 1)) {
    bk_fail(err, BK_ERR_RUNTIME, "%s: cannot allocate %zu x %zu bytes", what, count, size);
    return NULL;
  }
  return p;
}

void *view_alloc(size_t count, size_t size, const char *what, bk_error_t *err) {
  void *p = view_alloc_unset(count, size, what, err);
  if (p) bk_parallel(count * size, (size_t)1 << 20, zero_bytes, p); /* first touches on every core */
  return p;
}

/* A grid mapped from the reader's memfd (vdbio_array_free) gives its
 * pages back with MADV_REMOVE, a heap array with MADV_DONTNEED. */
void view_release_bytes(const void *a, size_t lo, size_t hi) {
  const uintptr_t page = VIEW_ALIGN, p0 = ((uintptr_t)a + lo + page - 1) & ~(page - 1);
  const uintptr_t p1 = ((uintptr_t)a + hi) & ~(page - 1);
  if (p1 <= p0) return;
  if (madvise((void *)p0, p1 - p0, MADV_REMOVE) != 0) madvise((void *)p0, p1 - p0, MADV_DONTNEED);
}

void view_release_slices(const float *a, int ch, size_t slice, size_t k0, size_t k1) {
  if (a) view_release_bytes(a, ch * sizeof(float) * k0 * slice, ch * sizeof(float) * k1 * slice);
}

size_t view_padded_row(int nx, int ny, size_t row) {
  const size_t j = row % (size_t)ny, k = row / (size_t)ny;
  return 1 + ((size_t)nx + 2) * (j + 1 + ((size_t)ny + 2) * (k + 1));
}

/* view_check_values in chunks side by side (counts and a minimum: the same
 * in any order). */
typedef struct check_ctx {
  const float *a;
  int nonneg;
  size_t bad[VIEW_CHUNKS], neg[VIEW_CHUNKS];
  float most_neg[VIEW_CHUNKS];
} check_ctx_t;

static void check_chunk(void *arg, size_t k, size_t lo, size_t hi) {
  check_ctx_t *x = arg;
  size_t bad = 0, neg = 0;
  float most_neg = 0.0f;
  for (size_t i = lo; i < hi; i++) {
    const float a = x->a[i];
    if (!isfinite(a)) bad++;
    else if (x->nonneg && a < 0.0f) {
      neg++;
      most_neg = a < most_neg ? a : most_neg;
    }
  }
  x->bad[k] = bad, x->neg[k] = neg, x->most_neg[k] = most_neg;
}

int view_check_values(const char *path, const char *name, const float *a, size_t n,
                        int nonneg, bk_error_t *err) {
  check_ctx_t x;
  memset(&x, 0, sizeof x);
  x.a = a, x.nonneg = nonneg;
  bk_parallel_chunks(n, VIEW_CHUNKS, check_chunk, &x);
  size_t bad = 0, neg = 0;
  float most_neg = 0.0f;
  for (int k = 0; k < VIEW_CHUNKS; k++) {
    bad += x.bad[k], neg += x.neg[k];
    most_neg = x.most_neg[k] < most_neg ? x.most_neg[k] : most_neg;
  }
  if (bad)
    return bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" holds %zu NaN or infinite values",
                   path, name, bad);
  if (neg)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: grid \"%s\" holds %zu negative values (down to %g); expected "
                   "coefficients >= 0", path, name, neg, most_neg);
  return BK_OK;
}

int view_expand_to_rgb(float **a, size_t n, bk_error_t *err) {
  float *o = bk_calloc(n, 3 * sizeof(float), "view: coefficients", err);
  if (!o) return BK_ERR_RUNTIME;
  for (size_t i = 0; i < n; i++) o[3 * i] = o[3 * i + 1] = o[3 * i + 2] = (*a)[i];
  vdbio_array_free(*a);
  *a = o;
  return BK_OK;
}

int view_is_constant(const float *a, size_t n, int ch, float c[3]) {
  for (int k = 0; k < 3; k++) c[k] = a[ch == 1 ? 0 : k];
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < ch; k++)
      if (a[i * ch + k] != c[k]) return 0;
  return 1;
}
