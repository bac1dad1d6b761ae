/* march.h: one photon's march through the grid, shared by host and device.
 *
 * In: the photon's index (its light and origin come from photons.h), the
 * refractive field as one float4 per voxel (∇n and n, voxel units), the
 * constant-block pyramid (baker/octree.h), the extinction grid (or constant
 * extinction), and a fixed-point accumulator. Out: the accumulator gains
 * Φ·ℓ·S per voxel crossed (ℓ the path length in that voxel, in voxels, S the
 * fixed-point scale); the photon's fate, steps and path length.
 *
 * Everything is in voxel coordinates (u = (x - origin)/h, voxel i spans
 * [i, i+1)); the ray equation d/ds(n dx/ds) = ∇n is unchanged by the uniform
 * scaling, so with v = n dx/ds and s in voxels:
 *   Euler (the paper's scheme):  x += (Δs/n) v,  v += Δs ∇n   (INTEGRATOR 0;
 *     see PM_EULER_SEMI_IMPLICIT for the other order and why not)
 *   RK4 on  dx/ds = v/n(x),  dv/ds = ∇n(x)                   (INTEGRATOR 1)
 * n and ∇n are trilinear between voxel centres, ∇n from the central
 * differences of kernels/ior.h (ior_gradient_at), precomputed per voxel.
 * Each step's chord is straight and deposited by an exact 3D DDA. In a block
 * the pyramid flags constant (n constant over it and a 2-voxel halo, so n and
 * the interpolated ∇n are exactly constant inside), the photon goes straight to
 * the block's boundary by DDA instead of stepping. With constant n over the
 * whole grid (HAS_REFRACTION 0) the kernel is a pure DDA with no gradient code.
 *
 * Attenuation is exact per voxel: crossing length ℓ in a voxel of extinction
 * σ (per voxel length) deposits Φ0 (1 - e^{-σℓ})/σ, computed in a form stable
 * as σ -> 0 (pm_atten: it tends to Φ0 ℓ), and leaves Φ0 e^{-σℓ}; the energy
 * deposited along a segment is the exact integral of the power.
 *
 * Specialisation (-D flags on the device; fields of pm_params on the host):
 * HAS_REFRACTION, HOMOGENEOUS (σt as parameters, no grid lookups),
 * INTEGRATOR (0 Euler, 1 RK4), PM_CHANNELS (1 when every light has the same
 * colour and the medium is grey: one atomic per voxel instead of three),
 * LIGHT_DIRECTIONAL / LIGHT_SPOT / LIGHT_POINT (photons.h), and PM_MODE:
 *
 * Modes (the adaptive pipeline, baker/adaptive.h, runs the same march):
 *  PM_MODE_REFERENCE  what is described above.
 *  PM_MODE_PILOT      phase 1: the deposits go to the coarse cell of the voxel
 *                     (blocks of 2^coarse_shift voxels a side, its own
 *                     accumulator), and each coarse cell a photon passes gets
 *                     the bit of the photon's light-domain cell in its origin
 *                     mask (kernels/adaptive.h, ad_origin_mark).
 *  PM_MODE_WEIGHTED   phase 2: the photon's light-domain point is warped
 *                     through its light's PDF table (ad_pdf_warp) and its
 *                     power multiplied by w = 1/pdf. Per voxel the
 *                     accumulator holds one more counter after the radiance
 *                     channels: the photon count and the sum of w, packed
 *                     (count << count_shift) + round(w * weight_scale), added
 *                     with one atomic each time a photon enters the voxel
 *                     (consecutive deposits in the same voxel, the small
 *                     steps of a refractive region, count once). One packed
 *                     atomic per passage and none per extra deposit: the
 *                     slides lost time to atomics for exactly these data. */
#ifndef BAKER_MARCH_KERNEL_H
#define BAKER_MARCH_KERNEL_H

#include "adaptive.h"
#include "photons.h"
#include "shared.h"

#define PM_MAX_STEPS 65536 /* photons trapped by total internal reflection */
/* A photon that has travelled this many grid diagonals inside the grid is
 * trapped too: the bound on every photon's path that makes the fixed-point
 * sums overflow-free (baker/march.h). */
#define PM_MAX_PATH_DIAGONALS 16.0f
/* A photon whose brightest channel falls below this fraction of its initial
 * power is absorbed: what it would still deposit is at most this fraction. */
#define PM_ABSORB_FRACTION 1e-6f
/* Pyramid (baker/octree.h): one byte per finest block (2^3 voxels) giving
 * the coarsest constant block that contains it, level L spanning
 * 2 * 4^(L-1) voxels (2, 8, 32, 128), 0 where n varies. */
#define PM_BLOCK_SHIFT 1
#define PM_LEVELS 4
#define PM_FAR 3.0e38f
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
#define PM_EULER_SEMI_IMPLICIT 0

/* What happened to a photon (pm_result.fate). */
#define PM_FATE_MISSED 0     /* never hit the grid */
#define PM_FATE_LEFT 1       /* left the grid */
#define PM_FATE_ABSORBED 2   /* power below PM_ABSORB_FRACTION */
#define PM_FATE_STEP_LIMIT 3 /* PM_MAX_STEPS or PM_MAX_PATH_DIAGONALS */

#define PM_MODE_REFERENCE 0
#define PM_MODE_PILOT 1
#define PM_MODE_WEIGHTED 2

#if PH_DEVICE
#ifndef HAS_REFRACTION
#define HAS_REFRACTION 1
#endif
#ifndef HOMOGENEOUS
#define HOMOGENEOUS 0
#endif
#ifndef INTEGRATOR
#define INTEGRATOR 0
#endif
#ifndef PM_CHANNELS
#define PM_CHANNELS 3
#endif
#ifndef PM_MODE
#define PM_MODE PM_MODE_REFERENCE
#endif
typedef uchar pm_uchar;
#define PM_HAS_REFRACTION(P) (HAS_REFRACTION)
#define PM_HOMOGENEOUS(P) (HOMOGENEOUS)
#define PM_INTEGRATOR(P) (INTEGRATOR)
#define PM_NCH(P) (PM_CHANNELS)
#define PM_MODE_OF(P) (PM_MODE)
#define PM_ATOMIC_ADD(p, q) atom_add((p), (q))
#define PM_EXP(x) exp(x)
#define PM_SQRT(x) sqrt(x)
#define PM_FLOOR(x) floor(x)
#define PM_REC_DECL
#define PM_RECORD(x)
#else
#include <math.h>
typedef unsigned char pm_uchar;
#define PM_HAS_REFRACTION(P) ((P)->has_refraction)
#define PM_HOMOGENEOUS(P) ((P)->homogeneous)
#define PM_INTEGRATOR(P) ((P)->integrator)
#define PM_NCH(P) ((int)(P)->channels)
#define PM_MODE_OF(P) ((int)(P)->mode)
/* The host path marches one photon at a time on one thread. */
#define PM_ATOMIC_ADD(p, q) (*(p) += (q))
#define PM_EXP(x) expf(x)
#define PM_SQRT(x) sqrtf(x)
/* floorf is a libm call on baseline x86-64 (no SSE4.1 round); floats beyond
 * 2^23 (and NaN) are returned as they are */
static inline float pm_floorf(float x) {
  if (!(x > -8388608.0f && x < 8388608.0f)) return x;
  float t = (float)(int)x;
  return t > x ? t - 1.0f : t;
}
#define PM_FLOOR(x) pm_floorf(x)
/* Host-only path recording for tests (pm_trace_* in baker/march.h). */
typedef struct pm_path_rec {
  float *points; /* 3 per point, voxel coordinates */
  int max, count;
} pm_path_rec;
static inline void pm_record(pm_path_rec *rec, bk_v3 x) {
  if (!rec) return;
  if (rec->count < rec->max) {
    rec->points[3 * rec->count] = x.x;
    rec->points[3 * rec->count + 1] = x.y;
    rec->points[3 * rec->count + 2] = x.z;
  }
  rec->count++;
}
#define PM_REC_DECL , pm_path_rec *rec
#define PM_RECORD(x) pm_record(rec, (x))
#endif

/* Parameters of one march, shared by every photon. Pinned at 128 bytes. */
typedef struct pm_params {
  bk_grid grid;
  float sigma_t[3];      /* HOMOGENEOUS: extinction per voxel length (σt h) */
  float step;            /* Δs, voxels */
  float fixed_scale;     /* S: accumulator quanta per W·voxel */
  float path_cap;        /* PM_MAX_PATH_DIAGONALS grid diagonals, voxels */
  float absorb_fraction; /* PM_ABSORB_FRACTION */
  bk_uint photon_total;
  bk_uint light_count;
  bk_uint channels;       /* 1 or 3 */
  bk_uint has_refraction; /* host path only: the device uses the -D flags */
  bk_uint homogeneous;
  bk_uint integrator;
  int pyr_nx, pyr_ny, pyr_nz; /* finest pyramid blocks along each axis */
  bk_uint mode;               /* PM_MODE_*: host path only (the device uses -D PM_MODE) */
  int coarse_shift;           /* pilot: deposits and marks at voxel >> coarse_shift */
  int cnx, cny, cnz;          /* pilot: the coarse grid */
  float weight_scale;         /* weighted: quanta of the packed weight sum per unit w */
  bk_uint count_shift;        /* weighted: the count's lowest bit in the packed counter */
  bk_uint pad0;
} pm_params;
BK_STATIC_ASSERT(sizeof(pm_params) == 128, "pm_params layout is shared with kernels");

/* One photon's outcome. */
typedef struct pm_result {
  bk_uint fate;   /* PM_FATE_* */
  bk_uint steps;  /* march iterations: integrator steps and straight block crossings */
  bk_uint voxels; /* voxel crossings (deposits) */
  float path;     /* path length inside the grid, voxels */
} pm_result;
BK_STATIC_ASSERT(sizeof(pm_result) == 16, "pm_result layout is shared with kernels");

typedef struct pm_photon {
  bk_v3 x;    /* position, voxel coordinates */
  int c[3];   /* the voxel it is in (kept by the DDA, never re-derived from x) */
  bk_v3 v;    /* n dx/ds */
  float power[3];
  float threshold;
  float path;
  bk_uint voxels;
  int light, cell;  /* pilot: the photon's light and light-domain cell */
  bk_ulong packed;  /* weighted: (1 << count_shift) + round(w weight_scale) */
  bk_long last;     /* the last voxel (pilot: coarse cell) counted or marked */
} pm_photon;

/* Crossing a voxel at optical depth t = σℓ: returns r = (1 - e^{-t})/t, the
 * fraction of Φ0 ℓ deposited, and sets *trans = e^{-t}. Below t = 0.03 a
 * series (error < t^6/720 ~ 1e-12) keeps r exact as t -> 0 and needs no
 * transcendental at all (fog: t ~ 0.01 per voxel); above, 1 - e^{-t} loses at
 * most an ulp of 1, < 2e-6 of r. */
BK_INLINE float pm_atten(float t, float *trans) {
  if (t < 0.03f) {
    float r = 1.0f - t * (0.5f - t * (1.0f / 6.0f - t * (1.0f / 24.0f - t * (1.0f / 120.0f))));
    *trans = 1.0f - t * r;
    return r;
  }
  float e = PM_EXP(-t);
  *trans = e;
  return (1.0f - e) / t;
}

/* Adds value (already multiplied by the fixed-point scale) to one counter,
 * rounded to the nearest quantum. */
BK_INLINE void pm_deposit(BK_GLOBAL bk_ulong *acc, float value) {
  bk_ulong q = (bk_ulong)(value + 0.5f);
  if (q) PM_ATOMIC_ADD(acc, q);
}

BK_INLINE bk_long pm_index(const bk_grid g, int i, int j, int k) {
  return (bk_long)i + (bk_long)g.nx * ((bk_long)j + (bk_long)g.ny * (bk_long)k);
}

/* n and ∇n (voxel units) at voxel coordinate u: trilinear between voxel
 * centres over the float4 field (gx, gy, gz, n), clamped to the edge voxels
 * (the same weights as bk_sample_trilinear, as nested lerps). */
BK_INLINE float pm_sample_ng(BK_GLOBAL const float *ng, const bk_grid g, bk_v3 u, bk_v3 *grad) {
  float fx = u.x - 0.5f, fy = u.y - 0.5f, fz = u.z - 0.5f;
  float flx = PM_FLOOR(fx), fly = PM_FLOOR(fy), flz = PM_FLOOR(fz);
  int i0 = (int)flx, j0 = (int)fly, k0 = (int)flz;
  float tx = fx - flx, ty = fy - fly, tz = fz - flz;
  int i1 = bk_clampi(i0 + 1, 0, g.nx - 1), j1 = bk_clampi(j0 + 1, 0, g.ny - 1),
      k1 = bk_clampi(k0 + 1, 0, g.nz - 1);
  i0 = bk_clampi(i0, 0, g.nx - 1);
  j0 = bk_clampi(j0, 0, g.ny - 1);
  k0 = bk_clampi(k0, 0, g.nz - 1);
  const bk_long sy = (bk_long)g.nx, sz = (bk_long)g.nx * (bk_long)g.ny;
  const bk_long b = pm_index(g, i0, j0, k0);
  const bk_long dx = i1 - i0, dy = (j1 - j0) * sy, dz = (k1 - k0) * sz;
  BK_GLOBAL const float *q000 = ng + 4 * b, *q100 = ng + 4 * (b + dx), *q010 = ng + 4 * (b + dy),
                        *q110 = ng + 4 * (b + dx + dy), *q001 = ng + 4 * (b + dz),
                        *q101 = ng + 4 * (b + dx + dz), *q011 = ng + 4 * (b + dy + dz),
                        *q111 = ng + 4 * (b + dx + dy + dz);
  float s[4];
  for (int c = 0; c < 4; c++) {
    float c00 = q000[c] + tx * (q100[c] - q000[c]), c10 = q010[c] + tx * (q110[c] - q010[c]);
    float c01 = q001[c] + tx * (q101[c] - q001[c]), c11 = q011[c] + tx * (q111[c] - q011[c]);
    float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    s[c] = c0 + tz * (c1 - c0);
  }
  *grad = v3(s[0], s[1], s[2]);
  return s[3];
}

/* Length and direction in float on both sides (shared.h's v3_length is
 * double on the host). */
BK_INLINE float pm_length(bk_v3 a) { return PM_SQRT(a.x * a.x + a.y * a.y + a.z * a.z); }
BK_INLINE bk_v3 pm_normalize(bk_v3 a) {
  float l = pm_length(a);
  return l > 0.0f ? v3_scale(a, 1.0f / l) : a;
}

/* Counters per voxel in the accumulator of a mode (the pilot's are per
 * coarse cell). */
BK_INLINE int pm_acc_stride(int mode, int channels) {
  return mode == PM_MODE_WEIGHTED ? channels + 1 : channels;
}

/* The photon crosses length seg (voxels) of voxel idx (at c): deposits the
 * exact integral of its attenuated power and attenuates it. Returns 1 when
 * it is absorbed (every channel below its threshold). */
BK_INLINE int pm_cross_voxel(const pm_params *P, BK_GLOBAL const float *sigma,
                             BK_GLOBAL bk_ulong *acc, BK_GLOBAL bk_ulong *masks, pm_photon *ph,
                             bk_long idx, const int *c, float seg) {
  const int nch = PM_NCH(P);
  const int stride = pm_acc_stride(PM_MODE_OF(P), nch);
  bk_long didx = idx; /* where the deposit goes */
#if !PH_DEVICE || PM_MODE == PM_MODE_PILOT
  if (PM_MODE_OF(P) == PM_MODE_PILOT) {
    const int s = P->coarse_shift;
    didx = (bk_long)(c[0] >> s) +
           (bk_long)P->cnx * ((bk_long)(c[1] >> s) + (bk_long)P->cny * (bk_long)(c[2] >> s));
    if (didx != ph->last) {
      ph->last = didx;
      ad_origin_mark(masks, ad_origin_index(didx, ph->light, (bk_long)P->cnx * P->cny * P->cnz),
                     ph->cell);
    }
  }
#endif
#if !PH_DEVICE || PM_MODE == PM_MODE_WEIGHTED
  if (PM_MODE_OF(P) == PM_MODE_WEIGHTED && idx != ph->last) {
    ph->last = idx;
    PM_ATOMIC_ADD(acc + stride * idx + nch, ph->packed);
  }
#endif
  float pmax = 0.0f;
  for (int ch = 0; ch < nch; ch++) {
    float sg, trans;
    if (PM_HOMOGENEOUS(P)) sg = P->sigma_t[ch];
    else sg = sigma[nch * idx + ch];
    float r = pm_atten(sg * seg, &trans);
    pm_deposit(acc + stride * didx + ch, ph->power[ch] * seg * r * P->fixed_scale);
    ph->power[ch] *= trans;
    pmax = ph->power[ch] > pmax ? ph->power[ch] : pmax;
  }
  ph->path += seg;
  ph->voxels++;
  return pmax < ph->threshold;
}

#define PM_DDA_REACHED 0    /* travelled the whole length */
#define PM_DDA_LEFT_BLOCK 1 /* the next voxel is outside [lo, hi) but in the grid */
#define PM_DDA_LEFT_GRID 2
#define PM_DDA_ABSORBED 3

/* Walks from ph->x (in voxel ph->c) along unit direction d for length len
 * (PM_FAR: until it leaves the block), depositing the exact length spent in
 * each voxel (Amanatides & Woo) with exact attenuation. Stops early when the
 * next voxel is outside the block [lo, hi) (voxel indices, within the grid) or
 * outside the grid, or when the photon is absorbed. Updates x, c, power, path. */
BK_INLINE int pm_dda(const pm_params *P, BK_GLOBAL const float *sigma,
                     BK_GLOBAL bk_ulong *acc, BK_GLOBAL bk_ulong *masks, pm_photon *ph, bk_v3 d,
                     float len, const int *lo, const int *hi) {
  const int n[3] = {P->grid.nx, P->grid.ny, P->grid.nz};
  const float dv[3] = {d.x, d.y, d.z}, x0[3] = {ph->x.x, ph->x.y, ph->x.z};
  int c[3] = {ph->c[0], ph->c[1], ph->c[2]}, stp[3];
  float tmax[3], tdelta[3];
  /* the voxel's linear index follows the crossings: no multiplies per voxel */
  const bk_long stride[3] = {1, (bk_long)n[0], (bk_long)n[0] * (bk_long)n[1]};
  bk_long idx = pm_index(P->grid, c[0], c[1], c[2]), didx[3];
  if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) return PM_DDA_REACHED; /* v = 0: stays */
  for (int a = 0; a < 3; a++) {
    if (dv[a] > 0.0f) {
      stp[a] = 1;
      tdelta[a] = 1.0f / dv[a];
      tmax[a] = ((float)(c[a] + 1) - x0[a]) * tdelta[a];
    } else if (dv[a] < 0.0f) {
      stp[a] = -1;
      tdelta[a] = -1.0f / dv[a];
      tmax[a] = (x0[a] - (float)c[a]) * tdelta[a];
    } else {
      stp[a] = 0;
      tdelta[a] = PM_FAR;
      tmax[a] = PM_FAR;
    }
    /* x may sit a rounding error outside voxel c: keep the crossing in range */
    tmax[a] = bk_clampf(tmax[a], 0.0f, tdelta[a]);
    didx[a] = stp[a] * stride[a];
  }
  float t = 0.0f;
  int status;
  for (;;) {
    int a = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
    float tn = tmax[a];
    int last = tn >= len;
    float seg = (last ? len : tn) - t;
    if (seg > 0.0f && pm_cross_voxel(P, sigma, acc, masks, ph, idx, c, seg)) {
      status = PM_DDA_ABSORBED;
      t = last ? len : tn;
      break;
    }
    if (last) {
      status = PM_DDA_REACHED;
      t = len;
      break;
    }
    t = tn;
    c[a] += stp[a];
    idx += didx[a];
    tmax[a] += tdelta[a];
    if (c[a] < 0 || c[a] >= n[a]) {
      status = PM_DDA_LEFT_GRID;
      break;
    }
    if (c[a] < lo[a] || c[a] >= hi[a]) {
      status = PM_DDA_LEFT_BLOCK;
      break;
    }
  }
  ph->x = v3(x0[0] + t * dv[0], x0[1] + t * dv[1], x0[2] + t * dv[2]);
  ph->c[0] = c[0];
  ph->c[1] = c[1];
  ph->c[2] = c[2];
  return status;
}

#if !PH_DEVICE || HAS_REFRACTION
/* One step of Δs of the ray equation from (x, v): the new (x1, v1). */
BK_INLINE void pm_integrate(const pm_params *P, BK_GLOBAL const float *ng, bk_v3 x, bk_v3 v,
                            bk_v3 *x1, bk_v3 *v1) {
  const float h = P->step;
  bk_v3 g1;
  float n1 = pm_sample_ng(ng, P->grid, x, &g1);
  if (PM_INTEGRATOR(P) == 0) {
#if PM_EULER_SEMI_IMPLICIT
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
  float n2 = pm_sample_ng(ng, P->grid, xa, &g2);
  bk_v3 kx2 = v3_scale(va, 1.0f / n2), kv2 = g2;
  bk_v3 xb = v3_madd(x, kx2, 0.5f * h), vb = v3_madd(v, kv2, 0.5f * h);
  float n3 = pm_sample_ng(ng, P->grid, xb, &g3);
  bk_v3 kx3 = v3_scale(vb, 1.0f / n3), kv3 = g3;
  bk_v3 xc = v3_madd(x, kx3, h), vc = v3_madd(v, kv3, h);
  float n4 = pm_sample_ng(ng, P->grid, xc, &g4);
  bk_v3 kx4 = v3_scale(vc, 1.0f / n4), kv4 = g4;
  bk_v3 sx = v3_add(v3_add(kx1, kx4), v3_scale(v3_add(kx2, kx3), 2.0f));
  bk_v3 sv = v3_add(v3_add(kv1, kv4), v3_scale(v3_add(kv2, kv3), 2.0f));
  *x1 = v3_madd(x, sx, h / 6.0f);
  *v1 = v3_madd(v, sv, h / 6.0f);
}
#endif

/* Marches photon `index` (0 <= index < photon_total) to its end. masks: the
 * pilot's origin masks (PM_MODE_PILOT); tables: one PDF table of
 * AD_TABLE_FLOATS(AD_CELLS_X, AD_CELLS_Y) floats per light (PM_MODE_WEIGHTED);
 * unused otherwise. */
BK_INLINE void pm_march_photon(BK_CONSTANT const pm_params *Pc, BK_CONSTANT const ph_light *lights,
                               BK_GLOBAL const float *ng, BK_GLOBAL const pm_uchar *pyr,
                               BK_GLOBAL const float *sigma, BK_GLOBAL bk_ulong *acc,
                               BK_GLOBAL bk_ulong *masks, BK_GLOBAL const float *tables,
                               bk_uint index, pm_result *res PM_REC_DECL) {
  /* a private copy: the compiler cannot know the deposits leave P alone and
   * would reload it after every atomic */
  const pm_params Pv = *Pc;
  const pm_params *P = &Pv;
  const bk_grid g = P->grid;
  const int gl[3] = {0, 0, 0}, gh[3] = {g.nx, g.ny, g.nz};
  bk_uint l = 0;
  while (l + 1 < P->light_count && index >= lights[l].first + lights[l].count) l++;
  BK_CONSTANT const ph_light *L = lights + l;
  res->fate = PM_FATE_MISSED;
  res->steps = 0;
  res->voxels = 0;
  res->path = 0.0f;

  bk_v3 o, d;
  float t0, a, b, w = 1.0f;
  ph_point(L, index - L->first, &a, &b);
#if !PH_DEVICE || PM_MODE == PM_MODE_WEIGHTED
  if (PM_MODE_OF(P) == PM_MODE_WEIGHTED) {
    ad_sample s = ad_pdf_warp(tables + l * AD_TABLE_FLOATS(AD_CELLS_X, AD_CELLS_Y), AD_CELLS_X,
                              AD_CELLS_Y, a, b);
    a = s.x;
    b = s.y;
    w = 1.0f / s.pdf;
  }
#endif
  ph_map(L, a, b, &o, &d);
  PM_RECORD(o);
  if (!ph_enter_grid(g, o, d, &t0)) return;
  pm_photon ph;
  ph.light = (int)l;
  ph.cell = ad_cell_of(a, b);
  ph.last = -1;
  ph.packed = ((bk_ulong)1 << P->count_shift) + (bk_ulong)(w * P->weight_scale + 0.5f);
  ph.x = v3_madd(o, d, t0);
  ph.c[0] = bk_clampi((int)PM_FLOOR(ph.x.x), 0, g.nx - 1);
  ph.c[1] = bk_clampi((int)PM_FLOOR(ph.x.y), 0, g.ny - 1);
  ph.c[2] = bk_clampi((int)PM_FLOOR(ph.x.z), 0, g.nz - 1);
  ph.v = d;
  ph.power[0] = L->power[0] * w;
  ph.power[1] = L->power[1] * w;
  ph.power[2] = L->power[2] * w;
  float pmax = ph.power[0];
  for (int ch = 1; ch < PM_NCH(P); ch++) pmax = ph.power[ch] > pmax ? ph.power[ch] : pmax;
  ph.threshold = P->absorb_fraction * pmax;
  ph.path = 0.0f;
  ph.voxels = 0;
  PM_RECORD(ph.x);

#if !PH_DEVICE || HAS_REFRACTION
  if (PM_HAS_REFRACTION(P)) {
    bk_v3 g0;
    ph.v = v3_scale(d, pm_sample_ng(ng, g, ph.x, &g0));
  }
#endif

  bk_uint steps = 0;
  bk_uint fate = PM_FATE_LEFT;
  for (;;) {
    if (steps >= PM_MAX_STEPS || ph.path >= P->path_cap) {
      fate = PM_FATE_STEP_LIMIT;
      break;
    }
    steps++;
    int r;
#if !PH_DEVICE || HAS_REFRACTION
    if (PM_HAS_REFRACTION(P)) {
      int level = pyr[(ph.c[0] >> PM_BLOCK_SHIFT) +
                      P->pyr_nx * ((ph.c[1] >> PM_BLOCK_SHIFT) + P->pyr_ny * (ph.c[2] >> PM_BLOCK_SHIFT))];
      if (level > 0) {
        /* constant block: straight to its boundary */
        int shift = PM_BLOCK_SHIFT + 2 * (level - 1), lo[3], hi[3];
        for (int a = 0; a < 3; a++) {
          lo[a] = (ph.c[a] >> shift) << shift;
          hi[a] = lo[a] + (1 << shift) < gh[a] ? lo[a] + (1 << shift) : gh[a];
        }
        r = pm_dda(P, sigma, acc, masks, &ph, pm_normalize(ph.v), PM_FAR, lo, hi);
      } else {
        bk_v3 x1, v1;
        pm_integrate(P, ng, ph.x, ph.v, &x1, &v1);
        bk_v3 seg = v3_sub(x1, ph.x);
        float len = pm_length(seg);
        r = PM_DDA_REACHED;
        if ((int)PM_FLOOR(x1.x) == ph.c[0] && (int)PM_FLOOR(x1.y) == ph.c[1] &&
            (int)PM_FLOOR(x1.z) == ph.c[2]) {
          /* most steps of half a voxel stay in their voxel: no DDA set-up */
          if (len > 0.0f && pm_cross_voxel(P, sigma, acc, masks, &ph,
                                           pm_index(g, ph.c[0], ph.c[1], ph.c[2]), ph.c, len))
            r = PM_DDA_ABSORBED;
        } else if (len > 0.0f) {
          r = pm_dda(P, sigma, acc, masks, &ph, v3_scale(seg, 1.0f / len), len, gl, gh);
        }
        if (r == PM_DDA_REACHED) ph.x = x1;
        ph.v = v1;
      }
    } else
#endif
    {
      r = pm_dda(P, sigma, acc, masks, &ph, ph.v, PM_FAR, gl, gh);
    }
    PM_RECORD(ph.x);
    if (r == PM_DDA_LEFT_GRID) {
      fate = PM_FATE_LEFT;
      break;
    }
    if (r == PM_DDA_ABSORBED) {
      fate = PM_FATE_ABSORBED;
      break;
    }
  }
  res->fate = fate;
  res->steps = steps;
  res->voxels = ph.voxels;
  res->path = ph.path;
}

#endif
