/* ray_core.h: the ray physics every pass shares, host C and OpenCL C alike.
 *
 * The photon march (kernels/photon_march.h) and the camera rays of the view
 * (kernels/view_march.h) walk the same volume by the same rules, so the rules
 * live here once (pbrt-v4's single majorant iterator habit):
 *  - the field {∇n, n}: one float4 per voxel, ∇n the central difference of n
 *    at voxel centres (one-sided on the grid's faces) in 1/voxel, stored
 *    padded with one layer of replicated edge voxels (baker/field.h builds
 *    it); n and ∇n are trilinear between voxel centres, one float4 lookup
 *    per corner (rc_tri_at, rc_gather4, rc_field);
 *  - the ray step of d/ds(n dx/ds) = ∇n with v = n dx/ds, s in voxels:
 *      Euler (the paper's scheme):  x += (Δs/n) v,  v += Δs ∇n
 *      classical RK4 on  dx/ds = v/n(x),  dv/ds = ∇n(x)      (rc_step)
 *  - the exact attenuation of a straight segment of optical depth τ: the
 *    transmittance e^(−τ) and (1 − e^(−τ))/τ, the share of Φ0·ℓ (or of
 *    S·ℓ) that the segment deposits (or emits towards the camera) (rc_atten);
 *  - where a ray enters a box (rc_slab);
 *  - the constant-block pyramid (baker/octree.h): one byte per 2³ block
 *    naming the coarsest block of 2, 8, 32 or 128 voxels a side that holds
 *    it and over which (with a halo) a quantity is constant; a ray goes
 *    straight across such a block (rc_block_level, rc_block_bounds); for
 *    n also a bit per trilinear cell whose {∇n, n} is one value with
 *    ∇n = 0, where a ray goes straight too (rc_cell_flag, rc_cell_run).
 * Everything is in voxel coordinates u = (x − origin)/h: voxel i spans
 * [i, i+1) and its value sits at i + 0.5. */
#ifndef BAKER_RAY_CORE_H
#define BAKER_RAY_CORE_H

#include "kernels/shared.h"

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define RC_SQRT(x) sqrt(x)
#else
#include <math.h>
#include <string.h>
#define RC_SQRT(x) sqrtf(x)
#endif

#define RC_EXP(x) bk_exp(x) /* the same bits on every device (kernels/shared.h) */
#define RC_FAR 3.0e38f

/* Integrators of the ray equation (scene photons.integrator). */
#define RC_EULER 0
#define RC_RK4 1
/* The order of the Euler update. 0 (default): the paper's explicit order,
 * x with the old v. 1: v first, x with the new v (semi-implicit Euler), same
 * cost. Neither keeps |v| = n exactly at a sharp edge, and they err opposite
 * ways (measured, 0.5-voxel steps, 2-voxel smoothing):
 *  - explicit lets photons trapped by total internal reflection leak out: a
 *    point light inside a ball of n = 4 keeps 0 of 400 photons trapped (0
 *    even at 0.1 voxel) where about 92% should stay; RK4 keeps about 80%;
 *  - semi-implicit over-reflects: it keeps 92.5% there at 0.1 voxel, but it
 *    also traps 2.6% of a spot light's photons that enter a ball of n = 1.5
 *    from outside (impossible: they circulate to the path cap and add a third
 *    to the total radiance), where explicit traps none and RK4 0.03%.
 * Light entering objects from outside is the common case, so the default is
 * the paper's order; RK4 is the accurate choice for trapped light. */
#define RC_EULER_SEMI_IMPLICIT 0

/* Pyramid: finest blocks of 2^RC_BLOCK_SHIFT voxels a side; level L >= 1
 * names a block of 2 * 4^(L-1) voxels (2, 8, 32, 128), 0 a varying one. */
#define RC_BLOCK_SHIFT 1
#define RC_LEVELS 4

/* floor and ceil to int, exact for |x| < 2^31: one compare instead of a libm call on
 * the host and of PoCL's generic floor on the device. */
BK_INLINE int rc_floori(float x) {
  int i = (int)x;
  return (float)i > x ? i - 1 : i;
}

BK_INLINE int rc_ceili(float x) {
  int i = (int)x;
  return (float)i < x ? i + 1 : i;
}

/* Float length and direction on both sides (shared.h's v3_length is double
 * on the host). */
BK_INLINE float rc_length(bk_v3 a) { return RC_SQRT(a.x * a.x + a.y * a.y + a.z * a.z); }
BK_INLINE bk_v3 rc_normalize(bk_v3 a) {
  float l = rc_length(a);
  return l > 0.0f ? v3_scale(a, 1.0f / l) : a;
}

/* ---- segment attenuation ------------------------------------------------ */

/* Optical depth t = σℓ of a straight segment: returns r = (1 − e^(−t))/t
 * and sets *trans = e^(−t). Below t = 0.03 a series (error < t^6/720 ~
 * 1e-12) keeps r exact as t → 0 and needs no transcendental (fog: t ~ 0.01
 * per voxel); above, 1 − e^(−t) loses at most an ulp of 1, < 2e-6 of r. */
BK_INLINE float rc_atten(float t, float *trans) {
  if (t < 0.03f) {
    float r = 1.0f - t * (0.5f - t * (1.0f / 6.0f - t * (1.0f / 24.0f - t * (1.0f / 120.0f))));
    *trans = 1.0f - t * r;
    return r;
  }
  float e = RC_EXP(-t);
  *trans = e;
  return (1.0f - e) / t;
}

/* ---- ray-box entry ------------------------------------------------------- */

/* The part t in [*t0, *t1) of the ray o + t d, t >= 0, inside the box
 * [lo, hi]. Returns 0 when the ray misses it. An axis along which d is zero
 * constrains o alone. */
BK_INLINE int rc_slab(bk_v3 o, bk_v3 d, bk_v3 lo, bk_v3 hi, float *t0, float *t1) {
  float a0 = 0.0f, a1 = RC_FAR;
  const float ov[3] = {o.x, o.y, o.z}, dv[3] = {d.x, d.y, d.z};
  const float lv[3] = {lo.x, lo.y, lo.z}, hv[3] = {hi.x, hi.y, hi.z};
  for (int a = 0; a < 3; a++) {
    if (dv[a] == 0.0f) {
      if (ov[a] < lv[a] || ov[a] > hv[a]) return 0;
      continue;
    }
    float inv = 1.0f / dv[a];
    float ta = (lv[a] - ov[a]) * inv, tb = (hv[a] - ov[a]) * inv;
    a0 = fmax(a0, fmin(ta, tb));
    a1 = fmin(a1, fmax(ta, tb));
  }
  *t0 = a0;
  *t1 = a1;
  return a0 < a1;
}

/* ---- the padded float4 fields -------------------------------------------- */

/* Padded layout: (nx+2)(ny+2)(nz+2) float4, voxel (i,j,k) at (i+1, j+1, k+1),
 * the outer layer a copy of the edge voxels. Trilinear sampling then needs
 * no per-corner clamps and equals sampling clamped to the edge voxels. */
typedef struct rc_dims {
  int nx, ny, nz;
} rc_dims;

BK_INLINE bk_long rc_pad_sy(rc_dims n) { return (bk_long)n.nx + 2; }
BK_INLINE bk_long rc_pad_sz(rc_dims n) { return ((bk_long)n.nx + 2) * ((bk_long)n.ny + 2); }
BK_INLINE bk_long rc_pad_index(rc_dims n, int i, int j, int k) {
  return (bk_long)(i + 1) + rc_pad_sy(n) * (bk_long)(j + 1) + rc_pad_sz(n) * (bk_long)(k + 1);
}

/* The trilinear stencil at u: the lower corner's padded index and the
 * fractions, computed once and applied to every field at that point. The
 * lower corner is voxel floor(u − 0.5), padded index + 1, clamped onto the
 * padding (there both corners hold the edge value, so the fraction no longer
 * matters). */
typedef struct rc_tri {
  bk_long base;
  int ix, iy, iz; /* the lower corner's padded coordinates (base's) */
  float tx, ty, tz;
} rc_tri;

BK_INLINE rc_tri rc_tri_at(rc_dims n, bk_v3 u) {
#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
  /* the same operations on the three axes at once (bit-identical results;
   * a true vector compare is -1) */
  float4 f = (float4)(u.x, u.y, u.z, 0.0f) - 0.5f;
  int4 i = convert_int4(f);
  i += convert_float4(i) > f;
  float4 fr = f - convert_float4(i);
  i = clamp(i + 1, (int4)(0), (int4)(n.nx, n.ny, n.nz, 0));
  rc_tri t;
  t.tx = fr.x;
  t.ty = fr.y;
  t.tz = fr.z;
  t.ix = i.x, t.iy = i.y, t.iz = i.z;
  t.base = (bk_long)i.x + rc_pad_sy(n) * i.y + rc_pad_sz(n) * i.z;
  return t;
#else
  float fx = u.x - 0.5f, fy = u.y - 0.5f, fz = u.z - 0.5f;
  int i = rc_floori(fx), j = rc_floori(fy), k = rc_floori(fz);
  rc_tri t;
  t.tx = fx - (float)i;
  t.ty = fy - (float)j;
  t.tz = fz - (float)k;
  i = bk_clampi(i + 1, 0, n.nx);
  j = bk_clampi(j + 1, 0, n.ny);
  k = bk_clampi(k + 1, 0, n.nz);
  t.ix = i, t.iy = j, t.iz = k;
  t.base = (bk_long)i + rc_pad_sy(n) * j + rc_pad_sz(n) * k;
  return t;
#endif
}

typedef struct rc_f4 {
  float x, y, z, w;
} rc_f4;

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
typedef float4 rc_vec4;
#define RC_LOAD4(f, i) vload4((size_t)(i), (f))
#define RC_LERP4(a, b, t) ((a) + (t) * ((b) - (a)))
#else
typedef rc_f4 rc_vec4;
BK_INLINE rc_vec4 rc_load4_host(const float *f, bk_long i) {
  rc_vec4 r = {f[4 * i], f[4 * i + 1], f[4 * i + 2], f[4 * i + 3]};
  return r;
}
BK_INLINE rc_vec4 rc_lerp4_host(rc_vec4 a, rc_vec4 b, float t) {
  rc_vec4 r = {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z),
               a.w + t * (b.w - a.w)};
  return r;
}
#define RC_LOAD4(f, i) rc_load4_host((f), (i))
#define RC_LERP4(a, b, t) rc_lerp4_host((a), (b), (t))
#endif

/* The trilinear mix at stencil t's fractions of an array of VEC entries
 * (LOAD, LERP of that width) whose lower corner is entry b and whose y and
 * z strides are dy and dz entries: x, then y, then z, into r. One order of
 * operations for every width, so a lane's value does not depend on it. */
#define RC_TRILINEAR(VEC, LOAD, LERP, f, b, dy, dz, t, r)                                     \
  do {                                                                                        \
    VEC c00_ = LERP(LOAD(f, b), LOAD(f, b + 1), (t)->tx);                                     \
    VEC c10_ = LERP(LOAD(f, b + dy), LOAD(f, b + dy + 1), (t)->tx);                           \
    VEC c01_ = LERP(LOAD(f, b + dz), LOAD(f, b + dz + 1), (t)->tx);                           \
    VEC c11_ = LERP(LOAD(f, b + dz + dy), LOAD(f, b + dz + dy + 1), (t)->tx);                 \
    VEC c0_ = LERP(c00_, c10_, (t)->ty), c1_ = LERP(c01_, c11_, (t)->ty);                     \
    r = LERP(c0_, c1_, (t)->tz);                                                              \
  } while (0)

/* Trilinear value of a float4 array (RC_TRILINEAR). */
BK_INLINE rc_f4 rc_trilinear4(BK_GLOBAL const float *f, bk_long b, bk_long dy, bk_long dz,
                              const rc_tri *t) {
  rc_vec4 r;
  RC_TRILINEAR(rc_vec4, RC_LOAD4, RC_LERP4, f, b, dy, dz, t, r);
  rc_f4 o = {r.x, r.y, r.z, r.w};
  return o;
}

/* Trilinear value of a padded float4 field at stencil t. */
BK_INLINE rc_f4 rc_gather4(rc_dims n, BK_GLOBAL const float *f, const rc_tri *t) {
  return rc_trilinear4(f, t->base, rc_pad_sy(n), rc_pad_sz(n), t);
}

/* The same for a padded float2 field (the view's medium under grey light:
 * {S, σt}). */
typedef struct rc_f2 {
  float x, y;
} rc_f2;

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
typedef float2 rc_vec2;
#define RC_LOAD2(f, i) vload2((size_t)(i), (f))
#define RC_LERP2(a, b, t) ((a) + (t) * ((b) - (a)))
#else
typedef rc_f2 rc_vec2;
BK_INLINE rc_vec2 rc_load2_host(const float *f, bk_long i) {
  rc_vec2 r = {f[2 * i], f[2 * i + 1]};
  return r;
}
BK_INLINE rc_vec2 rc_lerp2_host(rc_vec2 a, rc_vec2 b, float t) {
  rc_vec2 r = {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)};
  return r;
}
#define RC_LOAD2(f, i) rc_load2_host((f), (i))
#define RC_LERP2(a, b, t) rc_lerp2_host((a), (b), (t))
#endif

BK_INLINE rc_f2 rc_gather2(rc_dims n, BK_GLOBAL const float *f, const rc_tri *t) {
  rc_vec2 r;
  RC_TRILINEAR(rc_vec2, RC_LOAD2, RC_LERP2, f, t->base, rc_pad_sy(n), rc_pad_sz(n), t, r);
  rc_f2 o = {r.x, r.y};
  return o;
}

/* The {∇n, n} field is stored sparse (baker/field.h builds it): the
 * padded grid in bricks of RC_BRICK³ stencil corners, each brick stored
 * with the RC_BRICK + 1 corners per axis its stencils read, or not at all
 * when every one of those holds ∇n = 0 and the same n (a constant stretch
 * of medium or glass, most of a grid): a stencil in such a brick reads
 * that n, and its trilinear mix of equal values is exactly that value
 * again. Floats, ints stored by their bits:
 *   [0..2] bricks per axis, [3] bricks stored,
 *   per brick (x fastest) its slot or -1, then per brick its constant n,
 *   then the stored bricks, (RC_BRICK + 1)³ float4 each, x fastest.
 * Dispersion puts three such fields one after the other (rc_field_channel). */
#define RC_BRICK 8
#define RC_BRICK_SIDE (RC_BRICK + 1)
#define RC_BRICK_FLOATS (4 * RC_BRICK_SIDE * RC_BRICK_SIDE * RC_BRICK_SIDE)

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define RC_AS_INT(f) as_int(f)
#else
BK_INLINE int rc_as_int_host(float f) {
  int i;
  memcpy(&i, &f, sizeof i);
  return i;
}
#define RC_AS_INT(f) rc_as_int_host(f)
#endif

/* Floats of a sparse field with `stored` bricks over grid n. */
BK_INLINE bk_long rc_field_floats(rc_dims n, bk_long stored) {
  const bk_long b = (bk_long)(n.nx / RC_BRICK + 1) * (n.ny / RC_BRICK + 1) * (n.nz / RC_BRICK + 1);
  return 4 + 2 * b + stored * RC_BRICK_FLOATS;
}

/* Channel c's field of a dispersive volume's three. */
BK_INLINE BK_GLOBAL const float *rc_field_channel(rc_dims n, BK_GLOBAL const float *ng, int c) {
  for (int k = 0; k < c; k++) ng += rc_field_floats(n, RC_AS_INT(ng[3]));
  return ng;
}

/* The trilinear {∇n, n} at stencil t. */
BK_INLINE rc_f4 rc_field_gather(BK_GLOBAL const float *ng, const rc_tri *t) {
  const int bx = RC_AS_INT(ng[0]), by = RC_AS_INT(ng[1]), bz = RC_AS_INT(ng[2]);
  const bk_long b = (bk_long)(t->ix / RC_BRICK) +
                    (bk_long)bx * ((t->iy / RC_BRICK) + (bk_long)by * (t->iz / RC_BRICK));
  const bk_long bricks = (bk_long)bx * by * bz;
  const int slot = RC_AS_INT(ng[4 + b]);
  if (slot < 0) {
    rc_f4 o = {0.0f, 0.0f, 0.0f, ng[4 + bricks + b]};
    return o;
  }
  BK_GLOBAL const float *f = ng + 4 + 2 * bricks + (bk_long)slot * RC_BRICK_FLOATS;
  const bk_long dy = RC_BRICK_SIDE, dz = RC_BRICK_SIDE * RC_BRICK_SIDE;
  const bk_long c = (bk_long)(t->ix % RC_BRICK) + dy * (t->iy % RC_BRICK) + dz * (t->iz % RC_BRICK);
  return rc_trilinear4(f, c, dy, dz, t);
}

/* n (returned) and ∇n (1/voxel) at u from the {∇n, n} field. */
BK_INLINE float rc_field(rc_dims n, BK_GLOBAL const float *ng, bk_v3 u, bk_v3 *grad) {
  rc_tri t = rc_tri_at(n, u);
  rc_f4 q = rc_field_gather(ng, &t);
  *grad = v3(q.x, q.y, q.z);
  return q.w;
}

/* d n / d(axis) at index c of an axis of `count` voxels whose stride is
 * `stride` floats: central inside, one-sided on the faces, 0 along an axis
 * one voxel thick. In 1/m for inv_h = 1/h. */
BK_INLINE float rc_diff_axis(BK_GLOBAL const float *n, bk_long base, bk_long stride, int c,
                             int count, float inv_h) {
  if (count < 2) return 0.0f;
  if (c == 0) return (n[base + stride] - n[base]) * inv_h;
  if (c == count - 1) return (n[base] - n[base - stride]) * inv_h;
  return (n[base + stride] - n[base - stride]) * (0.5f * inv_h);
}

/* ∇n in 1/m at the centre of voxel (i,j,k) of n (one float per voxel,
 * x-fastest) on voxels of size 1/inv_h. The field stores it per voxel
 * length (baker/field.c multiplies by h). */
BK_INLINE bk_v3 rc_gradient_at(rc_dims d, float inv_h, BK_GLOBAL const float *n, int i, int j,
                               int k) {
  const bk_long sy = (bk_long)d.nx, sz = (bk_long)d.nx * (bk_long)d.ny;
  const bk_long b = (bk_long)i + sy * j + sz * k;
  return v3(rc_diff_axis(n, b, 1, i, d.nx, inv_h), rc_diff_axis(n, b, sy, j, d.ny, inv_h),
            rc_diff_axis(n, b, sz, k, d.nz, inv_h));
}

/* ---- the ray step ---------------------------------------------------------- */

/* One step of arc length h (voxels) of the ray equation from (x, v): the new
 * (x1, v1), by Euler or RK4. */
BK_INLINE void rc_step(rc_dims n, BK_GLOBAL const float *ng, int integrator, float h, bk_v3 x,
                       bk_v3 v, bk_v3 *x1, bk_v3 *v1) {
  bk_v3 g1;
  float n1 = rc_field(n, ng, x, &g1);
  if (integrator == RC_EULER) {
#if RC_EULER_SEMI_IMPLICIT
    *v1 = v3_madd(v, g1, h);
    *x1 = v3_madd(x, *v1, h / n1);
#else
    *x1 = v3_madd(x, v, h / n1);
    *v1 = v3_madd(v, g1, h);
#endif
    return;
  }
  /* classical RK4 on y = (x, v), y' = (v / n(x), ∇n(x)) */
  bk_v3 kx1 = v3_scale(v, 1.0f / n1), kv1 = g1, g2, g3, g4;
  bk_v3 xa = v3_madd(x, kx1, 0.5f * h), va = v3_madd(v, kv1, 0.5f * h);
  float n2 = rc_field(n, ng, xa, &g2);
  bk_v3 kx2 = v3_scale(va, 1.0f / n2), kv2 = g2;
  bk_v3 xb = v3_madd(x, kx2, 0.5f * h), vb = v3_madd(v, kv2, 0.5f * h);
  float n3 = rc_field(n, ng, xb, &g3);
  bk_v3 kx3 = v3_scale(vb, 1.0f / n3), kv3 = g3;
  bk_v3 xc = v3_madd(x, kx3, h), vc = v3_madd(v, kv3, h);
  float n4 = rc_field(n, ng, xc, &g4);
  bk_v3 kx4 = v3_scale(vc, 1.0f / n4), kv4 = g4;
  bk_v3 sx = v3_add(v3_add(kx1, kx4), v3_scale(v3_add(kx2, kx3), 2.0f));
  bk_v3 sv = v3_add(v3_add(kv1, kv4), v3_scale(v3_add(kv2, kv3), 2.0f));
  *x1 = v3_madd(x, sx, h / 6.0f);
  *v1 = v3_madd(v, sv, h / 6.0f);
}

/* One axis of the DDA's set-up: the step along it, the path between two
 * crossings of its voxel planes and the path to the first (clamped: x may sit
 * a rounding error outside voxel c). Called once per axis with constant
 * indices, so that the caller's arrays stay in registers. */
BK_INLINE void rc_dda_axis(float d, float x, int c, int *step, float *tdelta, float *tmax) {
  if (d > 0.0f) {
    *step = 1;
    *tdelta = 1.0f / d;
    *tmax = ((float)(c + 1) - x) * *tdelta;
  } else if (d < 0.0f) {
    *step = -1;
    *tdelta = -1.0f / d;
    *tmax = (x - (float)c) * *tdelta;
  } else {
    *step = 0;
    *tdelta = RC_FAR;
    *tmax = RC_FAR;
  }
  *tmax = bk_clampf(*tmax, 0.0f, *tdelta);
}

/* ---- the constant-block pyramid ------------------------------------------ */

/* Finest blocks along each axis of a grid of `voxels` voxels. */
BK_INLINE int rc_blocks(int voxels) { return (voxels + (1 << RC_BLOCK_SHIFT) - 1) >> RC_BLOCK_SHIFT; }

/* The level of the block holding voxel c (inside the grid): 0 where the
 * quantity varies. */
BK_INLINE int rc_block_level(BK_GLOBAL const bk_uchar *pyr, rc_dims n, const int *c) {
  const bk_long bx = rc_blocks(n.nx), by = rc_blocks(n.ny);
  return pyr[(c[0] >> RC_BLOCK_SHIFT) + bx * ((c[1] >> RC_BLOCK_SHIFT) + by * (c[2] >> RC_BLOCK_SHIFT))];
}

/* The voxel range [lo, hi) of the level-`level` (>= 1) block holding voxel c,
 * clipped to the grid. */
BK_INLINE void rc_block_bounds(rc_dims n, int level, const int *c, int *lo, int *hi) {
  const int shift = RC_BLOCK_SHIFT + 2 * (level - 1), size = 1 << shift;
  const int nn[3] = {n.nx, n.ny, n.nz};
  for (int a = 0; a < 3; a++) {
    lo[a] = (c[a] >> shift) << shift;
    hi[a] = lo[a] + size < nn[a] ? lo[a] + size : nn[a];
  }
}

/* The byte of the cell flags that holds cell (px, py, pz)'s bit (px & 7):
 * one byte per 8 cells along x, (nx + 1) x (ny + 1) x (nz + 1) cells. The
 * last cell's byte + 1 is the flags' size. */
BK_INLINE bk_long rc_cell_byte(rc_dims n, int px, int py, int pz) {
  return (px >> 3) + (((bk_long)n.nx + 8) >> 3) * (py + ((bk_long)n.ny + 1) * pz);
}

/* The flag of the trilinear cell whose padded lower-corner index is
 * (px, py, pz), each in [0, n]: set when the cell is constant, in the cell
 * flags that follow the pyramid's levels (baker/octree.h, oct_add_cells).
 * A ray is straight in such a cell. */
BK_INLINE int rc_cell_flag(BK_GLOBAL const bk_uchar *pyr, rc_dims n, int px, int py, int pz) {
  const bk_long blocks = (bk_long)rc_blocks(n.nx) * rc_blocks(n.ny) * rc_blocks(n.nz);
  return pyr[blocks + rc_cell_byte(n, px, py, pz)] >> (px & 7) & 1;
}

/* Whether the cell holding u (rc_tri_at's, clamped onto the padding) is
 * constant. */
BK_INLINE int rc_cell_constant(BK_GLOBAL const bk_uchar *pyr, rc_dims n, bk_v3 u) {
  return rc_cell_flag(pyr, n, bk_clampi(rc_floori(u.x - 0.5f) + 1, 0, n.nx),
                      bk_clampi(rc_floori(u.y - 0.5f) + 1, 0, n.ny),
                      bk_clampi(rc_floori(u.z - 0.5f) + 1, 0, n.nz));
}

/* Past a cell's exit face by this much (voxels, 2^-10), so that the next
 * lookup lands in the next cell whatever the rounding of x (an ulp of
 * coordinates below 4096); a run shorter than this is not taken. */
#define RC_CELL_PAST 0.0009765625f

/* The path from u along the unit direction d across the run of constant
 * cells that u starts, to the face where the next cell varies or the
 * padded lattice ends (up to half a voxel past the grid's face: clip it).
 * The cells are walked as voxels are (their lattice is the voxels' shifted
 * by half a voxel), a flag read per cell. The photon march deposits that
 * chord (pm_cell_walk); the view integrates it (view_next_chord). */
BK_INLINE float rc_cell_run(BK_GLOBAL const bk_uchar *pyr, rc_dims n3, bk_v3 u, bk_v3 d) {
  /* the cell's padded corner index p (as rc_tri_at's, unclamped) and, per
   * axis, its low face p - 0.5 */
  const float x[3] = {u.x, u.y, u.z}, dv[3] = {d.x, d.y, d.z};
  const int n[3] = {n3.nx, n3.ny, n3.nz};
  int p[3], stp[3];
  float tmax[3], tdelta[3];
  for (int a = 0; a < 3; a++) {
    p[a] = rc_floori(x[a] - 0.5f) + 1;
    rc_dda_axis(dv[a], x[a] + 0.5f, p[a], &stp[a], &tdelta[a], &tmax[a]);
  }
  for (;;) {
    const int a = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
    const float len = tmax[a];
    p[a] += stp[a];
    if (p[a] < 0 || p[a] > n[a] || !rc_cell_flag(pyr, n3, p[0], p[1], p[2])) return len;
    tmax[a] += tdelta[a];
  }
}

#endif
