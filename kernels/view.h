/* view.h: camera rays of the viewing pass, shared by the host and kernels/view.cl.
 *
 * In: a pinhole camera and the baked fields resampled onto one dense grid,
 * packed by the host as one float4 per voxel {S = σs·L̄ (RGB), σt} (grey) or
 * {S, unused} plus {σt RGB, unused} (RGB), and {∇n, n} (one float4 per
 * voxel, the same field the photon march reads), each stored with one layer
 * of replicated edge voxels around it (view_pad4); per 8³ brick a byte of
 * flags and, with refraction, per voxel the distance to the nearest ∇n ≠ 0
 * (view_flat_field). Out: per pixel
 *   L = ∫ T(t) σs(x) L̄(x) dt + T_end·L_background,  RGBA with A = 1 − mean(T_end).
 * Everything here works in voxel coordinates u (voxel (i,j,k) spans [i, i+1),
 * its value sits at i + 0.5; the box is [0,nx]×[0,ny]×[0,nz]). The host maps
 * the camera into that space; for a similarity transform (rotation + uniform
 * scale) the ray equation keeps its form there, and σ is pre-multiplied by the
 * voxel size so optical depth is σ·(length in voxels).
 *
 * Rays bend by the ray equation d/ds(n dx/ds) = ∇n, with v = n dx/ds:
 *   Euler (the paper's scheme): x += (Δs/n) v,  v += Δs ∇n;  or classic RK4
 * on (x, v). ∇n is the central difference of n at voxel centres (one-sided
 * on the grid's faces: kernels/ior.h, as for the photons), n and ∇n both
 * trilinear in between, so one float4 lookup gives both. Where ∇n = 0 the
 * solution is a straight line and the ray walks it without the ray
 * equation: grid-wide (HAS_REFRACTION = 0), across an 8³ brick whose n, with
 * a 3-voxel margin, is one value, and along a chord that keeps every
 * trilinear stencil it reads where ∇n = 0 (view_flat_at). Where, besides, S
 * and σt are constant over a brick (with the 1-voxel margin trilinear
 * sampling reads; e.g. unlit fog), one step crosses the whole brick, which
 * the exact integration below makes exact; a point on a brick face belongs
 * to the brick the ray enters (the DDA rule). Consecutive straight bricks of
 * varying medium are one chord, sampled at most straight_step apart.
 * Each step of chord length Δ takes σt and S = σs L̄ (interpolated as one
 * field, so a step reads one float4 per trilinear corner) at the chord's
 * midpoint as constant and is integrated exactly:
 *   L += T S (1 − e^(−σt Δ))/σt,  T *= e^(−σt Δ),
 * with (1 − e^(−τ))/τ evaluated stably as τ → 0. A ray stops when it leaves
 * the box or max(T) < VIEW_T_CUTOFF. Outside the box the medium is empty. */
#ifndef BAKER_KERNELS_VIEW_H
#define BAKER_KERNELS_VIEW_H

#include "shared.h"

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define VIEW_DEVICE 1
#else
#define VIEW_DEVICE 0
#endif

#define VIEW_T_CUTOFF 1e-4f      /* below this the rest of the ray is invisible */
#define VIEW_BRICK_SHIFT 3       /* flags per 8³ voxels */
#define VIEW_BRICK_N_CONST 1     /* n is one value over the brick and VIEW_BRICK_MARGIN around */
#define VIEW_BRICK_MEDIUM_CONST 2 /* S and σt are, over the brick and 1 voxel around */
/* Voxels around a brick that must share its n, so that trilinear ∇n (1 voxel
 * of central difference, 0.5 of trilinear support) is zero over the brick. */
#define VIEW_BRICK_MARGIN 3
#define VIEW_DIR_EPS 1e-12f

enum { VIEW_EULER = 0, VIEW_RK4 = 1 };

/* Kernel argument, by value: only 4-byte members, so host and device agree. */
typedef struct view_params {
  bk_v3 cam_pos;      /* voxel coordinates */
  bk_v3 cam_forward;  /* voxel-space image of the world forward vector */
  bk_v3 cam_right;    /* ... of right · tan(fov_y/2) · aspect */
  bk_v3 cam_up;       /* ... of up · tan(fov_y/2) */
  bk_v3 background;   /* RGB radiance behind the volume */
  bk_v3 sigma_t;      /* RGB and HOMOGENEOUS: σt per voxel length */
  int width, height;
  int nx, ny, nz;
  int bx, by, bz;     /* brick counts, ceil(n / 8) */
  int max_steps;      /* per ray (curved rays trapped by total internal reflection) */
  float step;         /* voxels, curved march */
  float straight_step;/* voxels, most, where n is constant (a brick's or the grid's) */
} view_params_t;
BK_STATIC_ASSERT(sizeof(view_params_t) == 6 * 12 + 11 * 4, "view_params_t is a kernel argument");

/* Feature switches; the kernel passes compile-time constants so the unused
 * paths vanish, the host tests pass any combination. */
typedef struct view_flags {
  int refraction;     /* n varies: march the ray equation */
  int grey;           /* σt is lane w of `medium`, else the `sigma_t` array */
  int integrator;     /* VIEW_EULER or VIEW_RK4 */
  int homogeneous;    /* RGB σt constant: params.sigma_t, no `sigma_t` lookups */
} view_flags;

typedef struct view_fields {
  BK_GLOBAL const float *medium;          /* 4 per voxel: S = σs L̄ (RGB), σt if grey */
  BK_GLOBAL const float *sigma_t;         /* 4 per voxel: σt (RGB), when not grey */
  BK_GLOBAL const float *ng;              /* 4 per voxel: ∇n (per voxel length), n >= 1 */
  BK_GLOBAL const unsigned char *bricks;  /* VIEW_BRICK_* flags per brick */
  BK_GLOBAL const unsigned char *flat;    /* refraction: per voxel, see view_flat_at */
} view_fields;

BK_INLINE float view_minf(float a, float b) { return a < b ? a : b; }
BK_INLINE float view_maxf(float a, float b) { return a > b ? a : b; }
BK_INLINE float view_max3(bk_v3 a) { return view_maxf(a.x, view_maxf(a.y, a.z)); }
/* floor and ceil to int for |x| < 2^31: PoCL's floor() is a generic
 * sequence with three branches, the hottest thing in a sample. */
BK_INLINE int view_floori(float x) {
  int i = (int)x;
  return (float)i > x ? i - 1 : i;
}
BK_INLINE int view_ceili(float x) {
  int i = (int)x;
  return (float)i < x ? i + 1 : i;
}

/* Direction (voxel space, unit length) through image point (fx, fy) in
 * pixels, y down from the top row: pixel centres are at px + 0.5. */
BK_INLINE bk_v3 view_camera_dir(const view_params_t *p, float fx, float fy) {
  float sx = 2.0f * fx / (float)p->width - 1.0f;
  float sy = 1.0f - 2.0f * fy / (float)p->height;
  bk_v3 d = v3_madd(v3_madd(p->cam_forward, p->cam_right, sx), p->cam_up, sy);
  return v3_normalize(d);
}

/* Slab test against [0, bmax]: the part of o + t d with t >= 0 in the box. */
BK_INLINE int view_box_hit(bk_v3 o, bk_v3 d, bk_v3 bmax, float *t0, float *t1) {
  float tn = 0.0f, tf = 1e30f;
  float oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z}, bb[3] = {bmax.x, bmax.y, bmax.z};
  for (int a = 0; a < 3; a++) {
    if (dd[a] > -VIEW_DIR_EPS && dd[a] < VIEW_DIR_EPS) {
      if (oo[a] < 0.0f || oo[a] > bb[a]) return 0;
      continue;
    }
    float inv = 1.0f / dd[a];
    float ta = (0.0f - oo[a]) * inv, tb = (bb[a] - oo[a]) * inv;
    tn = view_maxf(tn, view_minf(ta, tb));
    tf = view_minf(tf, view_maxf(ta, tb));
  }
  *t0 = tn;
  *t1 = tf;
  return tf > tn;
}

/* Shortens the segment a -> *b (a inside the box) to where it leaves the box;
 * returns 1 when it did. */
BK_INLINE int view_clip_segment(bk_v3 a, bk_v3 *b, bk_v3 bmax) {
  float t = 1.0f;
  float aa[3] = {a.x, a.y, a.z}, bb[3] = {b->x, b->y, b->z}, mm[3] = {bmax.x, bmax.y, bmax.z};
  for (int i = 0; i < 3; i++) {
    float dlt = bb[i] - aa[i];
    if (bb[i] < 0.0f && dlt < 0.0f) t = view_minf(t, (0.0f - aa[i]) / dlt);
    if (bb[i] > mm[i] && dlt > 0.0f) t = view_minf(t, (mm[i] - aa[i]) / dlt);
  }
  if (t >= 1.0f) return 0;
  t = view_maxf(t, 0.0f);
  *b = v3_madd(a, v3_sub(*b, a), t);
  return 1;
}

/* The 4-float fields (medium, σt, ng) are stored padded: one layer of
 * replicated edge voxels around the box, (nx+2)·(ny+2)·(nz+2) voxels, voxel
 * (i,j,k) at padded index (i+1, j+1, k+1) (view_pad4 on the host). Trilinear
 * sampling then needs no per-corner clamps and equals sampling clamped to
 * the edge voxels (as bk_sample_trilinear). Points far outside the box (RK4
 * stages) are clamped onto the padding, where the value is the edge's. */
BK_INLINE bk_long view_pad_sy(const view_params_t *p) { return (bk_long)p->nx + 2; }
BK_INLINE bk_long view_pad_sz(const view_params_t *p) {
  return ((bk_long)p->nx + 2) * ((bk_long)p->ny + 2);
}

/* Trilinear stencil at voxel coordinate u: the lower corner's padded index
 * and the fractions; computed once, applied to every field. The value of
 * voxel i sits at u = i + 0.5, padded index i + 1, so the lower corner is
 * floor(u + 0.5), a truncation once clamped to >= 0. */
typedef struct view_tri {
  bk_long base;
  float tx, ty, tz;
} view_tri;

/* Clamps to [0, hi]; NaN goes to 0, so no lookup ever leaves the array. */
BK_INLINE float view_clamp_pad(float x, float hi) {
  x = x > 0.0f ? x : 0.0f;
  return x < hi ? x : hi;
}

BK_INLINE view_tri view_tri_at(const view_params_t *p, bk_v3 u) {
  view_tri t;
#if VIEW_DEVICE
  /* the same operations on the three axes at once (bit-identical results) */
  float4 f = (float4)(u.x, u.y, u.z, 0.0f) + 0.5f;
  f = select((float4)(0.0f), f, f > 0.0f);
  float4 hi = (float4)((float)p->nx, (float)p->ny, (float)p->nz, 0.0f) + 0.99f;
  f = select(hi, f, f < hi);
  int4 i = convert_int4(f);
  float4 fr = f - convert_float4(i);
  t.tx = fr.x;
  t.ty = fr.y;
  t.tz = fr.z;
  t.base = (bk_long)i.x + view_pad_sy(p) * i.y + view_pad_sz(p) * i.z;
#else
  float fx = view_clamp_pad(u.x + 0.5f, (float)p->nx + 0.99f);
  float fy = view_clamp_pad(u.y + 0.5f, (float)p->ny + 0.99f);
  float fz = view_clamp_pad(u.z + 0.5f, (float)p->nz + 0.99f);
  int i0 = (int)fx, j0 = (int)fy, k0 = (int)fz;
  t.tx = fx - (float)i0;
  t.ty = fy - (float)j0;
  t.tz = fz - (float)k0;
  t.base = (bk_long)i0 + view_pad_sy(p) * j0 + view_pad_sz(p) * k0;
#endif
  return t;
}

/* Trilinear value of a 4-float-per-voxel array (one vector load per corner). */
typedef struct view_f4 {
  float x, y, z, w;
} view_f4;

#if VIEW_DEVICE
typedef float4 view_vec4;
#define VIEW_LOAD4(f, i) vload4((size_t)(i), (f))
#define VIEW_LERP4(a, b, t) ((a) + (t) * ((b) - (a)))
#else
typedef view_f4 view_vec4;
BK_INLINE view_vec4 view_load4_host(const float *f, bk_long i) {
  view_vec4 r = {f[4 * i], f[4 * i + 1], f[4 * i + 2], f[4 * i + 3]};
  return r;
}
BK_INLINE view_vec4 view_lerp4_host(view_vec4 a, view_vec4 b, float t) {
  view_vec4 r = {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z),
                 a.w + t * (b.w - a.w)};
  return r;
}
#define VIEW_LOAD4(f, i) view_load4_host((f), (i))
#define VIEW_LERP4(a, b, t) view_lerp4_host((a), (b), (t))
#endif

BK_INLINE view_f4 view_gather4(const view_params_t *p, BK_GLOBAL const float *f,
                               const view_tri *t) {
  const bk_long b = t->base, dy = view_pad_sy(p), dz = view_pad_sz(p);
  view_vec4 c00 = VIEW_LERP4(VIEW_LOAD4(f, b), VIEW_LOAD4(f, b + 1), t->tx);
  view_vec4 c10 = VIEW_LERP4(VIEW_LOAD4(f, b + dy), VIEW_LOAD4(f, b + dy + 1), t->tx);
  view_vec4 c01 = VIEW_LERP4(VIEW_LOAD4(f, b + dz), VIEW_LOAD4(f, b + dz + 1), t->tx);
  view_vec4 c11 = VIEW_LERP4(VIEW_LOAD4(f, b + dz + dy), VIEW_LOAD4(f, b + dz + dy + 1), t->tx);
  view_vec4 c0 = VIEW_LERP4(c00, c10, t->ty), c1 = VIEW_LERP4(c01, c11, t->ty);
  view_vec4 r = VIEW_LERP4(c0, c1, t->tz);
  view_f4 o = {r.x, r.y, r.z, r.w};
  return o;
}

/* n and ∇n (per voxel length) at u: one trilinear float4 lookup. */
BK_INLINE float view_n_grad(const view_params_t *p, BK_GLOBAL const float *ng, bk_v3 u,
                            bk_v3 *grad) {
  view_tri t = view_tri_at(p, u);
  view_f4 q = view_gather4(p, ng, &t);
  *grad = v3(q.x, q.y, q.z);
  return q.w;
}

/* One step of arc length h of the ray equation from (x, v), v = n dx/ds. */
BK_INLINE void view_step_euler(const view_params_t *p, BK_GLOBAL const float *ng, float h,
                               bk_v3 *x, bk_v3 *v) {
  bk_v3 g;
  float n = view_n_grad(p, ng, *x, &g);
  *x = v3_madd(*x, *v, h / n);
  *v = v3_madd(*v, g, h);
}

BK_INLINE void view_step_rk4(const view_params_t *p, BK_GLOBAL const float *ng, float h,
                             bk_v3 *x, bk_v3 *v) {
  bk_v3 g1, g2, g3, g4;
  bk_v3 x1 = *x, v1 = *v;
  float n1 = view_n_grad(p, ng, x1, &g1);
  bk_v3 k1 = v3_scale(v1, 1.0f / n1);
  bk_v3 x2 = v3_madd(x1, k1, 0.5f * h), v2 = v3_madd(v1, g1, 0.5f * h);
  float n2 = view_n_grad(p, ng, x2, &g2);
  bk_v3 k2 = v3_scale(v2, 1.0f / n2);
  bk_v3 x3 = v3_madd(x1, k2, 0.5f * h), v3_ = v3_madd(v1, g2, 0.5f * h);
  float n3 = view_n_grad(p, ng, x3, &g3);
  bk_v3 k3 = v3_scale(v3_, 1.0f / n3);
  bk_v3 x4 = v3_madd(x1, k3, h), v4 = v3_madd(v1, g3, h);
  float n4 = view_n_grad(p, ng, x4, &g4);
  bk_v3 k4 = v3_scale(v4, 1.0f / n4);
  const float w = h / 6.0f;
  *x = v3_madd(x1, v3_add(v3_add(k1, k4), v3_scale(v3_add(k2, k3), 2.0f)), w);
  *v = v3_madd(v1, v3_add(v3_add(g1, g4), v3_scale(v3_add(g2, g3), 2.0f)), w);
}

/* Brick index along one axis. A point on a face belongs to the brick the
 * ray moves into (the DDA rule), so a ray on a face never stalls there. */
BK_INLINE int view_brick_axis(float u, float d, int n) {
  int i = d < 0.0f ? view_ceili(u) - 1 : view_floori(u);
  return bk_clampi(i, 0, n - 1) >> VIEW_BRICK_SHIFT;
}

/* The brick holding u for a ray moving along d (the DDA rule): its indices
 * in b and its VIEW_BRICK_* flags (returned). */
BK_INLINE int view_brick_find(const view_params_t *p, BK_GLOBAL const unsigned char *bricks,
                              bk_v3 u, bk_v3 d, int b[3]) {
  b[0] = view_brick_axis(u.x, d.x, p->nx);
  b[1] = view_brick_axis(u.y, d.y, p->ny);
  b[2] = view_brick_axis(u.z, d.z, p->nz);
  return bricks[b[0] + p->bx * (b[1] + p->by * b[2])];
}

/* 1/d per axis, 0 where d is (nearly) zero: that axis is never crossed. */
BK_INLINE bk_v3 view_inv_dir(bk_v3 d) {
  return v3(d.x > -VIEW_DIR_EPS && d.x < VIEW_DIR_EPS ? 0.0f : 1.0f / d.x,
            d.y > -VIEW_DIR_EPS && d.y < VIEW_DIR_EPS ? 0.0f : 1.0f / d.y,
            d.z > -VIEW_DIR_EPS && d.z < VIEW_DIR_EPS ? 0.0f : 1.0f / d.z);
}

/* Moves *u along unit d (inverse inv, view_inv_dir) to where it leaves brick
 * b (view_brick_find) and returns the distance. The leaving coordinate is set
 * exactly onto the face, so the next lookup finds the next brick. */
BK_INLINE float view_brick_exit(const view_params_t *p, const int b[3], bk_v3 *u, bk_v3 d,
                                bk_v3 inv) {
  const int B = 1 << VIEW_BRICK_SHIFT;
  float uu[3] = {u->x, u->y, u->z}, ii[3] = {inv.x, inv.y, inv.z};
  int nn[3] = {p->nx, p->ny, p->nz};
  float t = 1e30f, face = 0.0f;
  int axis = -1;
  for (int a = 0; a < 3; a++) {
    if (ii[a] == 0.0f) continue;
    float lo = (float)(b[a] * B);
    float f = ii[a] > 0.0f ? view_minf(lo + (float)B, (float)nn[a]) : lo;
    float ta = view_maxf((f - uu[a]) * ii[a], 0.0f);
    if (ta < t) t = ta, face = f, axis = a;
  }
  if (axis < 0) return 0.0f; /* d is zero: nothing to cross */
  *u = v3_madd(*u, d, t);
  if (axis == 0) u->x = face;
  else if (axis == 1) u->y = face;
  else u->z = face;
  return t;
}

/* For optical depth τ: the step's transmittance e^(−τ) (*trans) and
 * (1 − e^(−τ))/τ (returned). Thin steps, the usual case, take the series
 * 1 − τ/2 + τ²/6 − τ³/24 (error below τ⁴/120 < 1e-8) and no transcendental;
 * thicker ones exp, where 1 − e^(−τ) loses at most ~1e-6 relative. */
#define VIEW_TAU_SERIES 0.03f
BK_INLINE float view_seg_terms(float tau, float *trans) {
  if (tau < VIEW_TAU_SERIES) {
    float w = 1.0f - tau * (0.5f - tau * (1.0f / 6.0f - tau * (1.0f / 24.0f)));
    *trans = 1.0f - tau * w;
    return w;
  }
  float e = (float)exp(-tau);
  *trans = e;
  return (1.0f - e) / tau;
}
BK_INLINE float view_seg_weight(float tau) {
  float t;
  return view_seg_terms(tau, &t);
}

/* Integrates one segment of length len (voxels) whose medium is sampled at
 * its midpoint um, into L and T. Grey media evaluate one channel, not three,
 * and keep their transmittance in T->x alone (the caller copies it to y, z). */
BK_INLINE void view_segment(const view_params_t *p, view_fields f, view_flags fl, bk_v3 um,
                            float len, bk_v3 *L, bk_v3 *T) {
  view_tri t = view_tri_at(p, um);
  view_f4 m = view_gather4(p, f.medium, &t);
  bk_v3 src = v3(m.x, m.y, m.z);
  if (fl.grey) {
    float trans, wg = view_seg_terms(m.w * len, &trans);
    *L = v3_madd(*L, src, T->x * wg * len);
    T->x *= trans;
    return;
  }
  bk_v3 st = p->sigma_t, w, tr;
  if (!fl.homogeneous) {
    view_f4 q = view_gather4(p, f.sigma_t, &t);
    st = v3(q.x, q.y, q.z);
  }
  w.x = view_seg_terms(st.x * len, &tr.x);
  w.y = view_seg_terms(st.y * len, &tr.y);
  w.z = view_seg_terms(st.z * len, &tr.z);
  *L = v3_add(*L, v3_scale(v3_mul(v3_mul(*T, src), w), len));
  *T = v3_mul(*T, tr);
}

/* The largest transmittance left, for the cutoff: grey media keep it in x. */
BK_INLINE float view_t_max(view_flags fl, bk_v3 T) { return fl.grey ? T.x : view_max3(T); }

/* Where ∇n is zero around a voxel: `flat` holds per voxel the Chebyshev
 * distance D (voxels, at most VIEW_FLAT_MAX) to the nearest voxel whose ∇n
 * is not zero. A straight chord of length D − 2.5 from any point of the
 * voxel keeps every trilinear stencil it reads (±1 voxel) where ∇n = 0, so
 * the ray equation's solution is that chord, exactly. */
#define VIEW_FLAT_MAX 8
#define VIEW_FLAT_MARGIN 2.5f

BK_INLINE int view_flat_at(const view_params_t *p, BK_GLOBAL const unsigned char *flat, bk_v3 u) {
  int i = bk_clampi(view_floori(u.x), 0, p->nx - 1), j = bk_clampi(view_floori(u.y), 0, p->ny - 1);
  int k = bk_clampi(view_floori(u.z), 0, p->nz - 1);
  return flat[(bk_long)i + (bk_long)p->nx * ((bk_long)j + (bk_long)p->ny * k)];
}

/* The whole camera ray of pixel (px, py): rgba and the number of steps.
 * The ray is cut into chords, each integrated by uniform steps:
 *  - a brick of constant medium where ∇n = 0: one step across it;
 *  - consecutive bricks of constant n and varying medium (the whole box
 *    without refraction) are gathered into one chord stepped at most
 *    straight_step apart: per step one trilinear lookup and one segment;
 *  - inside refracting bricks, a flat chord (view_flat_at) stepped as
 *    finely as the curved steps around it, without their ∇n lookups;
 *  - elsewhere, one curved step of the ray equation (Euler or RK4).
 * All segments go through one call site so the compiler keeps L and T in
 * registers. */
BK_INLINE void view_march_pixel(const view_params_t *p, view_fields f, view_flags fl, int px,
                                int py, float rgba[4], bk_uint *steps_out) {
  bk_v3 o = p->cam_pos;
  bk_v3 d = view_camera_dir(p, (float)px + 0.5f, (float)py + 0.5f);
  bk_v3 L = v3(0.0f, 0.0f, 0.0f), T = v3(1.0f, 1.0f, 1.0f);
  bk_v3 bmax = v3((float)p->nx, (float)p->ny, (float)p->nz);
  bk_uint steps = 0;
  float t0, t1;
  if (view_box_hit(o, d, bmax, &t0, &t1)) {
    bk_v3 x = v3_madd(o, d, t0), dir = d, v = d, inv = view_inv_dir(d);
    if (fl.refraction) {
      bk_v3 g;
      v = v3_scale(d, view_n_grad(p, f.ng, x, &g));
    }
    bk_v3 run_a = x; /* a pending straight chord of varying medium from run_a along dir */
    float run = 0.0f;
    int done = 0;
    for (int it = 0; !done && steps < (bk_uint)p->max_steps && it < p->max_steps; it++) {
      bk_v3 ca = x, cd = dir; /* this iteration's chord: ca + cd·[0, clen] in cn steps */
      float clen = 0.0f;
      int cn = 1, flush = 0;
      int bb[3];
      int bf = view_brick_find(p, f.bricks, x, dir, bb);
      if (!fl.refraction || (bf & VIEW_BRICK_N_CONST)) {
        bk_v3 xn = x;
        float h = view_brick_exit(p, bb, &xn, dir, inv);
        if (!(h > 0.0f)) { /* on the grid's far face: out */
          done = flush = 1;
        } else if (!(bf & VIEW_BRICK_MEDIUM_CONST)) {
          if (run == 0.0f) run_a = x;
          run += h;
          x = xn;
          continue;
        } else if (run > 0.0f) {
          flush = 1; /* the pending chord first; this brick on the next turn */
        } else {
          clen = h;
          x = xn;
        }
      } else {
        int D = view_flat_at(p, f.flat, x);
        if (D >= 3) { /* ∇n = 0 for a while: a straight chord */
          bk_v3 xn = v3_madd(x, dir, (float)D - VIEW_FLAT_MARGIN), xb = x;
          int last = view_clip_segment(x, &xn, bmax);
          float h = v3_length(v3_sub(xn, x)), hb;
          if ((bf & VIEW_BRICK_MEDIUM_CONST) &&
              (hb = view_brick_exit(p, bb, &xb, dir, inv)) > 0.0f) {
            if (hb < h) xn = xb, h = hb, last = 0; /* up to the brick's face, in one step */
            if (run > 0.0f) {
              flush = 1;
            } else {
              clen = h;
              x = xn;
              done = last;
            }
          } else if (run > 0.0f) {
            flush = 1;
          } else { /* its own chord, sampled as finely as the curved steps around it */
            clen = h;
            cn = view_ceili(h / view_minf(p->step, p->straight_step));
            if (cn < 1) cn = 1;
            x = xn;
            done = last;
          }
        } else if (run > 0.0f) {
          flush = 1;
        } else {
          bk_v3 xn = x, vn = v;
          if (fl.integrator == VIEW_RK4)
            view_step_rk4(p, f.ng, p->step, &xn, &vn);
          else
            view_step_euler(p, f.ng, p->step, &xn, &vn);
          done = view_clip_segment(x, &xn, bmax);
          bk_v3 seg = v3_sub(xn, x);
          clen = v3_length(seg);
          if (clen > 0.0f) cd = v3_scale(seg, 1.0f / clen);
          x = xn;
          v = vn;
          dir = v3_normalize(v);
          inv = view_inv_dir(dir);
        }
      }
      if (flush) {
        ca = run_a;
        clen = run;
        cn = view_ceili(run / p->straight_step);
        if (cn < 1) cn = 1;
        run = 0.0f;
      }
      if (clen > 0.0f) {
        const float h = clen / (float)cn;
        for (int i = 0; i < cn; i++) {
          view_segment(p, f, fl, v3_madd(ca, cd, ((float)i + 0.5f) * h), h, &L, &T);
          steps++;
          if (view_t_max(fl, T) < VIEW_T_CUTOFF) {
            done = 1;
            break;
          }
        }
      }
    }
  }
  if (fl.grey) T.y = T.z = T.x;
  L = v3_add(L, v3_mul(T, p->background));
  rgba[0] = L.x;
  rgba[1] = L.y;
  rgba[2] = L.z;
  rgba[3] = 1.0f - (T.x + T.y + T.z) / 3.0f;
  *steps_out = steps;
}

#endif
