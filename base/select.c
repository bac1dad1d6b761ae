/* select.c: an order statistic in two passes (see select.h). A full
 * quickselect reorders a copy of every value; here one pass counts the
 * values by their 12 highest order bits, and the selection runs only over
 * the bucket that holds the rank, usually a small share of the values
 * (the 99.9th percentile of a grid's luminance: a few hundred of 262k). */
#include "select.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define SELECT_BITS 12
#define SELECT_BUCKETS (1u << SELECT_BITS)

/* f's bits as an unsigned key in the floats' order (negatives reversed). */
static uint32_t order_key(float f) {
  uint32_t u;
  memcpy(&u, &f, sizeof u);
  return u & 0x80000000u ? ~u : u | 0x80000000u;
}

static uint32_t bucket_of(float f) { return order_key(f) >> (32 - SELECT_BITS); }

/* The k-th smallest of a[0..n) (n > 0), reordering a: Hoare quickselect
 * with a median-of-three pivot, O(n) on average. */
static float select_kth(float *a, size_t n, size_t k) {
  ptrdiff_t lo = 0, hi = (ptrdiff_t)n - 1, kk = (ptrdiff_t)k;
  while (lo < hi) {
    float x = a[lo], y = a[lo + (hi - lo) / 2], z = a[hi];
    float pivot = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
    ptrdiff_t i = lo, j = hi;
    while (i <= j) {
      while (a[i] < pivot) i++;
      while (a[j] > pivot) j--;
      if (i <= j) {
        float t = a[i];
        a[i] = a[j];
        a[j] = t;
        i++;
        j--;
      }
    }
    if (kk <= j) hi = j;
    else if (kk >= i) lo = i;
    else return a[kk];
  }
  return a[kk];
}

float bk_rank_value(const float *v, size_t n, size_t rank) {
  if (n == 0 || rank >= n) return NAN;
  size_t *count = calloc(SELECT_BUCKETS, sizeof *count);
  if (!count) return NAN;
  for (size_t i = 0; i < n; i++) count[bucket_of(v[i])]++;
  uint32_t b = 0;
  size_t below = 0;
  while (below + count[b] <= rank) below += count[b++];
  float *in = malloc(count[b] * sizeof *in), r = NAN;
  if (in) {
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
      if (bucket_of(v[i]) == b) in[m++] = v[i];
    r = select_kth(in, m, rank - below);
  }
  free(in);
  free(count);
  return r;
}

float bk_quantile(const float *v, size_t n, double q) {
  return n ? bk_rank_value(v, n, (size_t)floor(q * (double)(n - 1))) : NAN;
}
