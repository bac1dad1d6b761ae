/* view_march.h: camera rays of the viewing pass, shared by the host and
 * kernels/view.cl.
 *
 * In: a pinhole camera and the baked fields resampled onto one dense grid,
 * in the ray core's padded float4 layout (kernels/ray_core.h): {S = σs·L̄
 * (RGB), σt} (grey) or {S, unused} plus {σt RGB, unused} (RGB), and the
 * {∇n, n} field the photon march reads; and two constant-block pyramids
 * (baker/octree.h): one of n (with refraction), one of the medium (S and σt,
 * with the 1-voxel halo trilinear sampling reads). Out: per pixel
 *   L = ∫ T(t) σs(x) L̄(x) dt + T_end·L_background,  RGBA with A = 1 − mean(T_end).
 * Everything is in voxel coordinates u (voxel (i,j,k) spans [i, i+1), its
 * value sits at i + 0.5; the box is [0,nx]×[0,ny]×[0,nz]). The host maps the
 * camera into that space; for a similarity transform (rotation + uniform
 * scale) the ray equation keeps its form there, and σ is pre-multiplied by
 * the voxel size so optical depth is σ·(length in voxels).
 *
 * Rays bend by the ray equation with the ray core's step (Euler or RK4) and
 * field. Where n is constant the solution is a straight line and the ray
 * walks it without the ray equation: grid-wide (HAS_REFRACTION = 0), across
 * a brick (a level-2 block of the pyramid, 8³ voxels) whose n is constant
 * with its halo, and inside refracting bricks across the finer constant
 * blocks of 2³. Where, besides, S and σt are constant over a brick (e.g.
 * unlit fog), one step crosses the largest block (8³ to 128³) over which
 * both are constant, which the exact integration below makes exact; a point
 * on a block face belongs to the block the ray enters (the DDA rule).
 * Consecutive straight blocks of varying medium are one chord, sampled at
 * most straight_step apart; the chord crosses n's constant block (up to
 * VIEW_RUN_LEVEL, 32³) in one turn, constant-medium bricks inside it
 * stepped with the rest: a turn (finding a block and its exit) costs about
 * as much as ten straight steps (docs/bench.md).
 * Each step of chord length Δ takes σt and S (interpolated as one field, so
 * a step reads one float4 per trilinear corner) at the chord's midpoint as
 * constant and integrates exactly with the ray core's attenuation:
 *   L += T S Δ (1 − e^(−σt Δ))/(σt Δ),  T *= e^(−σt Δ).
 * A ray stops when it leaves the box or max(T) < VIEW_T_CUTOFF. Outside the
 * box the medium is empty.
 *
 * Towards the bake's camera (params.camera_phase: the file's
 * `radiance_camera` was baked for a camera at cam_pos): on the chords that
 * still run along the camera ray's first direction, i.e. straight from that
 * point, S → S · c with c = C / Y(L̄) (aniso_s's 4th float), the light each
 * voxel scatters that way of every order, in place of the lobes below.
 *
 * Anisotropic phase (flags.aniso, from `radiance_flux`, `phase_g`,
 * `radiance_uncollided` and `radiance_flux_uncollided`): the radiance at a
 * point is taken as the share u = Y0 / Y(L̄) of uncollided light, an HG
 * lobe of its own flux F0 (a beam along F̂0 for one light), and the
 * scattered rest, an HG lobe of its flux F − F0 (mean cosine m_s =
 * |F − F0| / (Y(L̄) − Y0)). The Henyey–Greenstein phase g convolves each
 * into an HG lobe of g times its mean cosine (exact in the first moment,
 * and for the single scattering of one light: u = 1; exact for every moment
 * when the scattered light's lobe is HG-shaped about its mean). The fields
 * hold per voxel (index space) aniso = {g F0 / Y0, u} and
 * aniso_s = {g (F − F0) / (Y(L̄) − Y0), 0} (baker/view_volume.c), so toward
 * the camera, i.e. along −d for a ray of direction d,
 *   S → S · (u P(aniso) + (1 − u) P(aniso_s)),
 *   P(A) = 4π p_HG(|A|, Â·(−d)) = (1 − |A|²) / (1 + |A|² + 2 A·d)^(3/2). */
#ifndef BAKER_VIEW_MARCH_H
#define BAKER_VIEW_MARCH_H

#include "kernels/ray_core.h"

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define VIEW_DEVICE 1
#else
#define VIEW_DEVICE 0
#endif

#define VIEW_T_CUTOFF 1e-4f      /* below this the rest of the ray is invisible */
#define VIEW_BRICK_LEVEL 2        /* bricks are the pyramid's blocks of 8³ */
#define VIEW_RUN_LEVEL 3          /* a chord of varying medium crosses blocks of n of up to 32³ */
#define VIEW_DIR_EPS 1e-12f
#define VIEW_ANISO_MAX 0.999f     /* |g·m|: a lobe narrower than this is a spike */
/* cos of the most a chord may turn from its camera ray's first direction and
 * still take the camera's factor (params.camera_phase): 0.08 degrees */
#define VIEW_CAMERA_COS 0.999999f

enum { VIEW_EULER = RC_EULER, VIEW_RK4 = RC_RK4 };

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
  int camera_phase;   /* aniso_s's 4th float is the factor towards cam_pos (radiance_camera) */
  int pad1, pad2;
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
  int dispersion;     /* n per channel: ng holds R's, G's and B's fields in turn */
  int aniso;          /* the `aniso` field shapes the source by the camera direction */
  int grey_light;     /* grey too, and S the same in R, G, B: `medium` is {S, σt}, 2 floats */
} view_flags;

typedef struct view_fields {
  BK_GLOBAL const float *medium;          /* 4 per voxel: S = σs L̄ (RGB), σt if grey;
                                           * grey_light: 2, {S, σt} */
  BK_GLOBAL const float *sigma_t;         /* 4 per voxel: σt (RGB), when not grey */
  BK_GLOBAL const float *ng;              /* 4 per voxel: ∇n (per voxel length), n >= 1 */
  BK_GLOBAL const bk_uchar *npyr;         /* refraction: constant-block pyramid of n */
  BK_GLOBAL const bk_uchar *mpyr;         /* constant-block pyramid of S, σt (and A) */
  BK_GLOBAL const float *aniso;           /* 4 per voxel: {g F0 / Y0, u}, when fl.aniso */
  BK_GLOBAL const float *aniso_s;         /* 4 per voxel: {g m_s F̂_s, 0}, when fl.aniso */
} view_fields;

/* P(A) = 4π p_HG(|A|, Â·(−d)): a lobe's factor toward a camera looking along d. */
BK_INLINE float view_phase_factor(bk_v3 a, bk_v3 d) {
  float k2 = v3_dot(a, a), den = 1.0f + k2 + 2.0f * v3_dot(a, d);
  return (1.0f - k2) / (den * RC_SQRT(den));
}


/* Direction (voxel space, unit length) through image point (fx, fy) in
 * pixels, y down from the top row: pixel centres are at px + 0.5. */
BK_INLINE bk_v3 view_camera_dir(const view_params_t *p, float fx, float fy) {
  float sx = 2.0f * fx / (float)p->width - 1.0f;
  float sy = 1.0f - 2.0f * fy / (float)p->height;
  bk_v3 d = v3_madd(v3_madd(p->cam_forward, p->cam_right, sx), p->cam_up, sy);
  return v3_normalize(d);
}

/* Shortens the segment a -> *b (a inside the box) to where it leaves the box;
 * returns 1 when it did. */
BK_INLINE int view_clip_segment(bk_v3 a, bk_v3 *b, bk_v3 bmax) {
  float t = 1.0f;
  float aa[3] = {a.x, a.y, a.z}, bb[3] = {b->x, b->y, b->z}, mm[3] = {bmax.x, bmax.y, bmax.z};
  for (int i = 0; i < 3; i++) {
    float dlt = bb[i] - aa[i];
    if (bb[i] < 0.0f && dlt < 0.0f) t = fmin(t, (0.0f - aa[i]) / dlt);
    if (bb[i] > mm[i] && dlt > 0.0f) t = fmin(t, (mm[i] - aa[i]) / dlt);
  }
  if (t >= 1.0f) return 0;
  t = fmax(t, 0.0f);
  *b = v3_madd(a, v3_sub(*b, a), t);
  return 1;
}

BK_INLINE rc_dims view_dims(const view_params_t *p) {
  rc_dims n = {p->nx, p->ny, p->nz};
  return n;
}

/* The voxel holding u for a ray moving along d: a point on a face belongs
 * to the voxel the ray moves into (the DDA rule), so a ray on a block's face
 * never stalls there. */
BK_INLINE void view_voxel_at(rc_dims n, bk_v3 u, bk_v3 d, int c[3]) {
  const float uu[3] = {u.x, u.y, u.z}, dd[3] = {d.x, d.y, d.z};
  const int nn[3] = {n.nx, n.ny, n.nz};
  for (int a = 0; a < 3; a++) {
    int i = rc_floori(uu[a]);
    if (dd[a] < 0.0f && (float)i == uu[a]) i--;
    c[a] = bk_clampi(i, 0, nn[a] - 1);
  }
}

/* 1/d per axis, 0 where d is (nearly) zero: that axis is never crossed. */
BK_INLINE bk_v3 view_inv_dir(bk_v3 d) {
  return v3(d.x > -VIEW_DIR_EPS && d.x < VIEW_DIR_EPS ? 0.0f : 1.0f / d.x,
            d.y > -VIEW_DIR_EPS && d.y < VIEW_DIR_EPS ? 0.0f : 1.0f / d.y,
            d.z > -VIEW_DIR_EPS && d.z < VIEW_DIR_EPS ? 0.0f : 1.0f / d.z);
}

/* Moves *u along unit d (inverse inv, view_inv_dir) to where it leaves the
 * block [lo, hi) and returns the distance. The leaving coordinate is set
 * exactly onto the face, so the next lookup finds the next block. */
BK_INLINE float view_block_exit(const int *lo, const int *hi, bk_v3 *u, bk_v3 d, bk_v3 inv) {
  const float uu[3] = {u->x, u->y, u->z}, ii[3] = {inv.x, inv.y, inv.z};
  float t = RC_FAR, face = 0.0f;
  int axis = -1;
  for (int a = 0; a < 3; a++) {
    if (ii[a] == 0.0f) continue;
    float f = (float)(ii[a] > 0.0f ? hi[a] : lo[a]);
    float ta = fmax((f - uu[a]) * ii[a], 0.0f);
    if (ta < t) t = ta, face = f, axis = a;
  }
  if (axis < 0) return 0.0f; /* d is zero: nothing to cross */
  *u = v3_madd(*u, d, t);
  if (axis == 0) u->x = face;
  else if (axis == 1) u->y = face;
  else u->z = face;
  return t;
}

/* The last segment's optical depth per channel and its rc_atten results
 * (grey media: x alone): along a chord through uniform fog every step has
 * the same depth, and reusing the results gives the same bits without the
 * series or the exponential (6-9% of the view's march). */
typedef struct view_atten {
  bk_v3 tau, weight, trans;
} view_atten;

/* at's weights and transmittances for the depths tau (channels: 1 or 3). */
BK_INLINE void view_atten_at(view_atten *at, bk_v3 tau, int channels) {
  if (tau.x == at->tau.x && (channels == 1 || (tau.y == at->tau.y && tau.z == at->tau.z))) return;
  at->tau = tau;
  at->weight.x = rc_atten(tau.x, &at->trans.x);
  if (channels == 1) return;
  at->weight.y = rc_atten(tau.y, &at->trans.y);
  at->weight.z = rc_atten(tau.z, &at->trans.z);
}

/* Integrates one segment of length len (voxels) whose medium is sampled at
 * its midpoint um, into L and T; from_cam: the segment runs straight from
 * the bake's camera (params.camera_phase). Grey media evaluate one channel,
 * not three, and keep their transmittance in T->x alone (the caller copies
 * it to y, z). */
BK_INLINE void view_segment(const view_params_t *p, view_fields f, view_flags fl, bk_v3 um,
                            bk_v3 d, float len, int from_cam, view_atten *at, bk_v3 *L,
                            bk_v3 *T) {
  const rc_dims n = view_dims(p);
  rc_tri t = rc_tri_at(n, um);
  rc_f4 m;
  if (fl.grey_light) { /* half the bytes; each lane the same operations */
    rc_f2 q = rc_gather2(n, f.medium, &t);
    m.x = m.y = m.z = q.x;
    m.w = q.y;
  } else {
    m = rc_gather4(n, f.medium, &t);
  }
  bk_v3 src = v3(m.x, m.y, m.z);
  if (fl.aniso) {
    rc_f4 b = rc_gather4(n, f.aniso_s, &t);
    if (from_cam) {
      src = v3_scale(src, b.w);
    } else {
      rc_f4 a = rc_gather4(n, f.aniso, &t);
      src = v3_scale(src, a.w * view_phase_factor(v3(a.x, a.y, a.z), d) +
                              (1.0f - a.w) * view_phase_factor(v3(b.x, b.y, b.z), d));
    }
  }
  if (fl.grey) {
    view_atten_at(at, v3(m.w * len, 0.0f, 0.0f), 1);
    *L = v3_madd(*L, src, T->x * at->weight.x * len);
    T->x *= at->trans.x;
    return;
  }
  bk_v3 st = p->sigma_t;
  if (!fl.homogeneous) {
    rc_f4 q = rc_gather4(n, f.sigma_t, &t);
    st = v3(q.x, q.y, q.z);
  }
  view_atten_at(at, v3(st.x * len, st.y * len, st.z * len), 3);
  *L = v3_add(*L, v3_scale(v3_mul(v3_mul(*T, src), at->weight), len));
  *T = v3_mul(*T, at->trans);
}

/* The largest transmittance left, for the cutoff: grey media keep it in x. */
BK_INLINE float view_t_max(view_flags fl, bk_v3 T) {
  return fl.grey ? T.x : fmax(T.x, fmax(T.y, T.z));
}

/* The state of one camera ray. A chord is a straight piece ca + cd·[0, clen]
 * integrated in cn equal steps; `run` collects consecutive straight bricks
 * of varying medium into one pending chord from run_a along dir. */
typedef struct view_ray {
  bk_v3 x, v, dir, inv; /* position, n dx/ds, unit direction and its inverse */
  bk_v3 run_a;
  float run;
  bk_v3 ca, cd;
  float clen;
  int cn, flush, done;
} view_ray;

/* A straight stretch where n is constant over the block [lo, hi) that holds
 * the ray: with constant medium over the brick (mconst), one step across
 * the smaller of the two; else, in a brick (fine 0), the brick joins the
 * pending chord; in a finer block of a refracting brick (fine 1), a chord of
 * its own sampled as finely as the curved steps around it. */
/* This turn's chord: straight from r->x to xn, `len` long, in one step or
 * (fine) as finely as the curved steps around it. */
BK_INLINE void view_take_chord(const view_params_t *p, view_ray *r, bk_v3 xn, float len, int fine) {
  r->clen = len;
  if (fine) r->cn = rc_ceili(len / fmin(p->step, p->straight_step));
  if (r->cn < 1) r->cn = 1;
  r->x = xn;
}

BK_INLINE void view_straight(const view_params_t *p, view_ray *r, const int *lo, const int *hi,
                             int mconst, int fine) {
  bk_v3 xn = r->x;
  float h = view_block_exit(lo, hi, &xn, r->dir, r->inv);
  if (!(h > 0.0f)) { /* on the grid's far face: out */
    r->done = r->flush = 1;
  } else if (!mconst && !fine) {
    if (r->run == 0.0f) r->run_a = r->x;
    r->run += h;
    r->x = xn;
  } else if (r->run > 0.0f) {
    r->flush = 1; /* the pending chord first; this block on the next turn */
  } else {
    view_take_chord(p, r, xn, h, fine);
  }
}

/* One curved step of the ray equation, clipped to the box. */
BK_INLINE void view_curved(const view_params_t *p, view_fields f, view_flags fl, view_ray *r) {
  if (r->run > 0.0f) {
    r->flush = 1;
    return;
  }
  const bk_v3 bmax = v3((float)p->nx, (float)p->ny, (float)p->nz);
  bk_v3 xn, vn;
  rc_step(view_dims(p), f.ng, fl.integrator, p->step, r->x, r->v, &xn, &vn);
  r->done = view_clip_segment(r->x, &xn, bmax);
  bk_v3 seg = v3_sub(xn, r->x);
  r->clen = rc_length(seg);
  if (r->clen > 0.0f) r->cd = v3_scale(seg, 1.0f / r->clen);
  r->x = xn;
  r->v = vn;
  r->dir = rc_normalize(vn);
  r->inv = view_inv_dir(r->dir);
}

/* Across a run of the field's constant cells (rc_cell_run, `len` past its
 * exit face), where n is one value and ∇n = 0: the exact straight ray, a
 * chord sampled as finely as the curved steps around it. */
BK_INLINE void view_cell_chord(const view_params_t *p, view_ray *r, float len) {
  if (r->run > 0.0f) {
    r->flush = 1;
    return;
  }
  bk_v3 xn = v3_madd(r->x, r->dir, len);
  r->done = view_clip_segment(r->x, &xn, v3((float)p->nx, (float)p->ny, (float)p->nz));
  view_take_chord(p, r, xn, rc_length(v3_sub(xn, r->x)), 1);
}

/* Chooses this turn's chord for the ray at r->x (see view_march_pixel). */
BK_INLINE void view_next_chord(const view_params_t *p, view_fields f, view_flags fl, view_ray *r) {
  const rc_dims n = view_dims(p);
  int c[3], lo[3], hi[3];
  r->ca = r->x;
  r->cd = r->dir;
  r->clen = 0.0f;
  r->cn = 1;
  r->flush = 0;
  view_voxel_at(n, r->x, r->dir, c);
  const int mlevel = rc_block_level(f.mpyr, n, c), mconst = mlevel >= VIEW_BRICK_LEVEL;
  const int nlevel = fl.refraction ? rc_block_level(f.npyr, n, c) : RC_LEVELS;
  if (nlevel >= VIEW_BRICK_LEVEL) {
    /* constant medium: the largest block where both are constant, in one
     * step; else the pending chord goes on across n's constant block */
    const int level = bk_mini(nlevel, mconst ? mlevel : VIEW_RUN_LEVEL);
    rc_block_bounds(n, level, c, lo, hi);
    view_straight(p, r, lo, hi, mconst, 0);
  } else if (nlevel > 0) {
    rc_block_bounds(n, nlevel, c, lo, hi);
    view_straight(p, r, lo, hi, mconst, 1);
  } else {
    const float cells = rc_cell_constant(f.npyr, n, r->x) ? rc_cell_run(f.npyr, n, r->x, r->dir) : 0.0f;
    if (cells > RC_CELL_PAST) view_cell_chord(p, r, cells + RC_CELL_PAST);
    else view_curved(p, f, fl, r);
  }
  if (r->flush) {
    r->ca = r->run_a;
    r->cd = r->dir;
    r->clen = r->run;
    r->cn = rc_ceili(r->run / p->straight_step);
    if (r->cn < 1) r->cn = 1;
    r->run = 0.0f;
  }
}

/* The whole camera ray of pixel (px, py): L (background included), T_end,
 * and the number of steps (returned).
 * The ray is cut into chords, each integrated by uniform steps:
 *  - a block of constant medium where n is constant: one step across it;
 *  - consecutive blocks of constant n and varying medium (the whole box
 *    without refraction) are gathered into one chord stepped at most
 *    straight_step apart: per step one trilinear lookup and one segment;
 *  - inside refracting bricks, a finer constant block of n, or a run of
 *    the field's constant cells, is a straight chord stepped as finely as
 *    the curved steps around it;
 *  - elsewhere, one curved step of the ray equation (Euler or RK4).
 * All segments go through one call site so the compiler keeps L and T in
 * registers. */
BK_INLINE bk_uint view_march_ray(const view_params_t *p, view_fields f, view_flags fl, int px,
                                 int py, bk_v3 *L_out, bk_v3 *T_out) {
  bk_v3 d = view_camera_dir(p, (float)px + 0.5f, (float)py + 0.5f);
  bk_v3 L = v3(0.0f, 0.0f, 0.0f), T = v3(1.0f, 1.0f, 1.0f);
  bk_uint steps = 0;
  float t0, t1;
  if (rc_slab(p->cam_pos, d, v3(0.0f, 0.0f, 0.0f), v3((float)p->nx, (float)p->ny, (float)p->nz),
              &t0, &t1)) {
    view_ray r;
    view_atten at; /* no depth is negative: the first segment computes */
    at.tau = at.weight = at.trans = v3(-1.0f, -1.0f, -1.0f);
    r.x = v3_madd(p->cam_pos, d, t0);
    r.dir = r.v = d;
    r.inv = view_inv_dir(d);
    r.run_a = r.x;
    r.run = 0.0f;
    r.done = 0;
    if (fl.refraction) {
      bk_v3 g;
      r.v = v3_scale(d, rc_field(view_dims(p), f.ng, r.x, &g));
    }
    for (int it = 0; !r.done && steps < (bk_uint)p->max_steps && it < p->max_steps; it++) {
      view_next_chord(p, f, fl, &r);
      if (!(r.clen > 0.0f)) continue;
      const float h = r.clen / (float)r.cn;
      const int from_cam = p->camera_phase && v3_dot(r.cd, d) >= VIEW_CAMERA_COS;
      for (int i = 0; i < r.cn; i++) {
        view_segment(p, f, fl, v3_madd(r.ca, r.cd, ((float)i + 0.5f) * h), r.cd, h, from_cam, &at,
                     &L, &T);
        steps++;
        if (view_t_max(fl, T) < VIEW_T_CUTOFF) {
          r.done = 1;
          break;
        }
      }
    }
  }
  if (fl.grey) T.y = T.z = T.x;
  *L_out = v3_add(L, v3_mul(T, p->background));
  *T_out = T;
  return steps;
}

/* Pixel (px, py): L and A = 1 − mean(T_end). With dispersion each channel
 * bends with its own n: three rays, each through its channel's field, each
 * giving its channel of L and of T (steps: the three together). */
BK_INLINE void view_march_pixel(const view_params_t *p, view_fields f, view_flags fl, int px,
                                int py, float rgba[4], bk_uint *steps_out) {
  bk_v3 L, T;
  if (!fl.dispersion) {
    *steps_out = view_march_ray(p, f, fl, px, py, &L, &T);
  } else {
    const rc_dims n = view_dims(p);
    BK_GLOBAL const float *ng = f.ng;
    bk_v3 Lc, Tc;
    *steps_out = view_march_ray(p, f, fl, px, py, &Lc, &Tc);
    L.x = Lc.x;
    T.x = Tc.x;
    f.ng = rc_field_channel(n, ng, 1);
    *steps_out += view_march_ray(p, f, fl, px, py, &Lc, &Tc);
    L.y = Lc.y;
    T.y = Tc.y;
    f.ng = rc_field_channel(n, ng, 2);
    *steps_out += view_march_ray(p, f, fl, px, py, &Lc, &Tc);
    L.z = Lc.z;
    T.z = Tc.z;
  }
  rgba[0] = L.x;
  rgba[1] = L.y;
  rgba[2] = L.z;
  rgba[3] = 1.0f - (T.x + T.y + T.z) / 3.0f;
}

#endif
