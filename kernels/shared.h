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
BK_INLINE float bk_clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }
BK_INLINE int bk_clampi(int x, int lo, int hi) { return x < lo ? lo : (x > hi ? hi : x); }

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
