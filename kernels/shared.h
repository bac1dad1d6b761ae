/* shared.h: math shared by the host C code and the OpenCL kernels.
 *
 * Everything here compiles both as OpenCL C 1.2 and as C11, so the host tests
 * run the very functions the device runs (Cycles kernel/types.h habit).
 * Vectors are a plain struct rather than float3 so the layout is identical on
 * both sides; PoCL vectorises across work-items anyway. Structs that cross the
 * host/device boundary are pinned with BK_STATIC_ASSERT on the host. */
#ifndef BAKER_SHARED_H
#define BAKER_SHARED_H

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define BK_INLINE static inline
#define BK_ALWAYS_INLINE static inline __attribute__((always_inline))
#define BK_GLOBAL __global
#define BK_CONSTANT __constant
#define BK_STATIC_ASSERT(cond, msg)
typedef uchar bk_uchar;
typedef uint bk_uint;
typedef ulong bk_ulong;
typedef long bk_long;
#else
#include <math.h>
#include <stdint.h>
#define BK_INLINE static inline
#define BK_ALWAYS_INLINE static inline __attribute__((always_inline))
#define BK_GLOBAL
#define BK_CONSTANT
#define BK_STATIC_ASSERT(cond, msg) _Static_assert(cond, msg)
typedef uint8_t bk_uchar;
typedef uint32_t bk_uint;
typedef uint64_t bk_ulong;
typedef int64_t bk_long;
#endif

typedef struct bk_v3 {
  float x, y, z;
} bk_v3;

/* Chris Wellons' lowbias32: a full-avalanche 32-bit mix, for the counter-based
 * random numbers of the device (kernels/scatter.h) and the host (baker/photons.c). */
BK_INLINE bk_uint bk_mix32(bk_uint x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

BK_INLINE bk_v3 v3(float x, float y, float z) { bk_v3 r; r.x = x; r.y = y; r.z = z; return r; }
BK_INLINE bk_v3 v3_add(bk_v3 a, bk_v3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
BK_INLINE bk_v3 v3_sub(bk_v3 a, bk_v3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
BK_INLINE bk_v3 v3_mul(bk_v3 a, bk_v3 b) { return v3(a.x * b.x, a.y * b.y, a.z * b.z); }
BK_INLINE bk_v3 v3_scale(bk_v3 a, float s) { return v3(a.x * s, a.y * s, a.z * s); }
BK_INLINE bk_v3 v3_madd(bk_v3 a, bk_v3 b, float s) { return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
BK_INLINE float v3_dot(bk_v3 a, bk_v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
BK_INLINE bk_v3 v3_cross(bk_v3 a, bk_v3 b) {
  return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
BK_INLINE float v3_length(bk_v3 a) { return sqrt(v3_dot(a, a)); }
BK_INLINE bk_v3 v3_normalize(bk_v3 a) {
  float l = v3_length(a);
  return l > 0.0f ? v3_scale(a, 1.0f / l) : a;
}
/* exp, log, sin and cos from +, −, ×, IEEE ÷ and exact scalings only
 * (Cephes' single-precision reductions and polynomials, within 2 ulp), so
 * that every device and the host round them alike: a device's own exp or
 * sin may differ by the 3-4 ulp OpenCL allows, which a GPU bake showed as
 * grids 2e-5 apart from PoCL's (docs/gpu.md). The march kernels keep
 * FP_CONTRACT OFF, so no compiler fuses a product into a sum there. */
#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define BK_FLOOR(x) floor(x)
#define BK_AS_FLOAT(u) as_float(u)
#define BK_AS_UINT(f) as_uint(f)
#else
#define BK_FLOOR(x) floorf(x)
BK_INLINE float bk_as_float(bk_uint u) { union { bk_uint u; float f; } v; v.u = u; return v.f; }
BK_INLINE bk_uint bk_as_uint(float f) { union { bk_uint u; float f; } v; v.f = f; return v.u; }
#define BK_AS_FLOAT(u) bk_as_float(u)
#define BK_AS_UINT(f) bk_as_uint(f)
#endif

/* Not inlined in kernels: inlined, it made PoCL's single-scattering march
 * 16-25% slower than the builtin exp did; called, as fast (docs/gpu.md). */
#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define BK_EXP_LINKAGE static __attribute__((noinline))
#else
#define BK_EXP_LINKAGE BK_INLINE
#endif

/* 2^k for -126 <= k <= 127, exactly, from its bits (no ldexp call) */
BK_INLINE float bk_pow2i(int k) { return BK_AS_FLOAT((bk_uint)(k + 127) << 23); }

BK_EXP_LINKAGE float bk_exp(float x) {
  /* selects, not branches: one path for every work-item */
  float xc = x < -104.0f ? -104.0f : (x > 89.0f ? 89.0f : x);
  float n = BK_FLOOR(xc * 1.44269504088896341f + 0.5f); /* round(x / ln 2) */
  float r = xc - n * 0.693359375f; /* ln 2 in two parts: n * hi is exact */
  r = r - n * -2.12194440e-4f;
  float z = r * r;
  float p = 1.9875691500e-4f;
  p = p * r + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  float y = p * z + r + 1.0f;
  /* y 2^k in two scalings, -75 <= k/2 <= 64: the first is exact, the
   * second rounds once (to a denormal, 0 or inf at the ends) */
  int k = (int)n, k1 = k >> 1;
  float e = y * bk_pow2i(k1) * bk_pow2i(k - k1);
  return x < -103.97208f ? 0.0f : (x != x ? x : e);
}

/* Natural log of x > 0 (x <= 0 or NaN: NaN; +inf: +inf). */
BK_INLINE float bk_ln(float x) {
  if (!(x > 0.0f)) return x == 0.0f ? -1e38f * 1e38f : (x - x) / (x - x);
  if (x > 3.4028234e38f) return x;
  int e = 0;
  if (x < 1.17549435e-38f) { /* denormal: into the normal range, exactly */
    x *= 16777216.0f;
    e = -24;
  }
  bk_uint bits = BK_AS_UINT(x); /* x = m 2^e with m in [1/2, 1) */
  e += (int)((bits >> 23) & 255u) - 126;
  x = BK_AS_FLOAT((bits & 0x807fffffu) | 0x3f000000u);
  if (x < 0.707106781f) {
    x += x;
    e--;
  }
  float f = x - 1.0f, z = f * f;
  float p = 7.0376836292e-2f;
  p = p * f - 1.1514610310e-1f;
  p = p * f + 1.1676998740e-1f;
  p = p * f - 1.2420140846e-1f;
  p = p * f + 1.4249322787e-1f;
  p = p * f - 1.6668057665e-1f;
  p = p * f + 2.0000714765e-1f;
  p = p * f - 2.4999993993e-1f;
  p = p * f + 3.3333331174e-1f;
  float fe = (float)e;
  float y = p * f * z + fe * -2.12194440e-4f - 0.5f * z;
  return f + y + fe * 0.693359375f;
}

/* sin and cos of 0 <= a < 8192 (the callers pass an azimuth in [0, 2π)):
 * reduced by π/4 in three exact parts, then Cephes' polynomials. */
BK_INLINE void bk_sincos(float a, float *s, float *c) {
  float j = BK_FLOOR(a * 1.27323954473516f); /* 4/π */
  j += (float)((int)j & 1);                  /* even octant: |r| <= π/4 */
  float r = ((a - j * 0.78515625f) - j * 2.4187564849853515625e-4f) - j * 3.77489497744594108e-8f;
  float z = r * r;
  float ps = ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f) * z * r + r;
  float pc = ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f) *
             z * z - 0.5f * z + 1.0f;
  int q = ((int)j >> 1) & 3; /* quadrant */
  float sv = (q & 1) ? pc : ps, cv = (q & 1) ? ps : pc;
  *s = (q & 2) ? -sv : sv;
  *c = (q == 1 || q == 2) ? -cv : cv;
}

BK_INLINE float bk_clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }
BK_INLINE int bk_clampi(int x, int lo, int hi) { return x < lo ? lo : (x > hi ? hi : x); }
BK_INLINE int bk_mini(int a, int b) { return a < b ? a : b; }

/* Grid description passed to kernels: world <-> voxel coordinates.
 * Voxel coordinate u = (x - origin) / voxel_size, so voxel (i,j,k) spans
 * [i, i+1) and its centre is at i + 0.5. */
typedef struct bk_grid {
  int nx, ny, nz, pad0;
  float origin_x, origin_y, origin_z, voxel_size;
} bk_grid;
BK_STATIC_ASSERT(sizeof(bk_grid) == 32, "bk_grid layout is shared with kernels");

BK_INLINE int bk_grid_index(const bk_grid g, int i, int j, int k) {
  return i + g.nx * (j + g.ny * k);
}

#endif
