/* scatter.h: the physics of a scattering event, shared by host and device:
 * the counter-based random numbers, the free flight, the Henyey–Greenstein
 * phase function and Russian roulette. kernels/scatter_march.h strings the
 * march's legs together with them; only kernels built with
 * -DMULTIPLE_SCATTERING=1 include any of it.
 *
 * The estimator. Each leg of a photon is marched exactly as a single-
 * scattering photon is (kernels/photon_march.h): it deposits the exact
 * integral of its uncollided power Φ(s) = W e^(−τ(s)) over every voxel it
 * crosses, to the grid's edge. Before the leg starts it draws a target
 * optical depth τ* = −ln(1 − ξ); the point where the leg's optical depth
 * τ̄ (the mean over the channels of σt, or σt itself for one channel)
 * reaches τ* is its collision, of density σ̄t e^(−τ̄) ds. The next leg starts
 * there with weight W'_c = Φ_c(s*) σs_c / (σ̄t e^(−τ*)), a new direction from
 * the phase function, and its own τ*. Its expected source is
 * ∫ Φ_c(s) σs_c(s) ds ⊗ p: the scattering source of the leg, so every
 * order's deposit is unbiased, and the first leg's deposit is the single-
 * scattering result bit for bit. For one channel W' = W σs/σt (the albedo).
 *
 * Russian roulette after each event: the leg survives with probability
 * q = min(1, max_c W'_c / W0) (W0 the photon's initial brightest channel)
 * and is then divided by q, so a grey photon keeps its initial power and
 * dies with the albedo's probability (unbiased; a chain ends on its own even
 * without a cap on events). A channel weight above W0 (only when the
 * channels' extinctions differ by much, through e^(τ̄ − τ_c)) is clamped to W0:
 * the fixed-point scale of baker/march.h assumes no photon exceeds it.
 *
 * Random numbers: a hash of (seed, photon index, 4·leg + k), k = 0 the free
 * flight, 1 and 2 the direction, 3 the roulette. No state, so a bake is
 * reproducible on any device and in any launch order. */
#ifndef BAKER_SCATTER_H
#define BAKER_SCATTER_H

#include "kernels/ray_core.h"

#define MS_LOG(x) bk_ln(x) /* the same bits on every device (kernels/shared.h) */

/* Parameters of multiple scattering, shared by every photon. */
typedef struct ms_params {
  float sigma_s[3];     /* scattering per voxel length, when uniform (!grid) */
  float g;              /* Henyey–Greenstein asymmetry, when uniform */
  bk_uint max_bounces;  /* scattering events per photon, at most */
  bk_uint seed;         /* photons.seed */
  bk_uint grid;         /* host path: σs (and g) per voxel from the scatter grid */
  bk_uint g_grid;       /* host path: the scatter grid holds g after σs */
} ms_params;
BK_STATIC_ASSERT(sizeof(ms_params) == 32, "ms_params layout is shared with kernels");

/* Per photon, for the bake's accounting (sums over the channels, W and
 * W·voxel): the power that entered the grid and left it, the deposits of
 * the first leg and of the later ones, the scattering events. */
typedef struct ms_tally {
  float entered, escaped, first, later;
  bk_uint events, pad0, pad1, pad2;
} ms_tally;
BK_STATIC_ASSERT(sizeof(ms_tally) == 32, "ms_tally layout is shared with kernels");

/* The state of a leg's free flight, carried by the photon. */
#define MS_IDLE 0    /* no collision sampled on this leg (the last one) */
#define MS_FLYING 1  /* looking for the collision at optical depth tau */
#define MS_PENDING 2 /* found in the last voxel crossed, at offset s: placed by the caller */
#define MS_HIT 3     /* found and placed */
typedef struct ms_flight {
  bk_uint state;
  float tau;      /* MS_FLYING: optical depth still to go; then the sampled τ* */
  float tau_star; /* the sampled τ* */
  float s;        /* MS_PENDING: offset of the collision in the segment, voxels */
  float path;     /* the photon's path (pm_photon.path) at the collision */
  float power[3]; /* Φ_c at the collision */
  float sigma;    /* σ̄t at the collision, per voxel length */
  int c[3];       /* its voxel */
  bk_long idx;
  bk_v3 x, d;     /* MS_HIT: position (voxels) and direction of travel */
  float deposit;  /* the leg's deposits, W·voxel summed over channels */
} ms_flight;

/* A uniform number in [0, 1) from (seed, photon, counter). */
BK_INLINE float ms_uniform(bk_uint seed, bk_uint photon, bk_uint counter) {
  bk_uint h = bk_mix32(counter ^ bk_mix32(photon ^ bk_mix32(seed + 0x9e3779b9u)));
  return (float)(h >> 8) * (1.0f / 16777216.0f);
}

/* Starts a leg's free flight: τ* = −ln(1 − ξ), finite since ξ < 1. */
BK_INLINE void ms_flight_begin(ms_flight *f, float xi) {
  f->state = MS_FLYING;
  f->tau_star = -MS_LOG(1.0f - xi);
  f->tau = f->tau_star;
  f->deposit = 0.0f;
}

/* The leg crosses length seg (voxels) of a voxel of mean extinction sbar
 * (per voxel length) with power `power` and path `path` on entry: records
 * the collision when τ* falls in it. sigma_t: the channels' extinctions,
 * for Φ_c at the collision. */
BK_INLINE void ms_flight_cross(ms_flight *f, const float *power, float path, const float *sigma_t,
                               int nch, float sbar, float seg, bk_long idx, const int *c) {
  if (f->state != MS_FLYING) return;
  float t = sbar * seg;
  if (!(f->tau < t)) {
    f->tau -= t;
    return;
  }
  float s = f->tau / sbar;
  for (int ch = 0; ch < nch; ch++) f->power[ch] = power[ch] * RC_EXP(-sigma_t[ch] * s);
  f->sigma = sbar;
  f->s = s;
  f->path = path + s;
  f->idx = idx;
  f->c[0] = c[0];
  f->c[1] = c[1];
  f->c[2] = c[2];
  f->state = MS_PENDING;
}

/* The caller knows where the segment started and where it went. */
BK_INLINE void ms_flight_place(ms_flight *f, bk_v3 start, bk_v3 d) {
  if (f->state != MS_PENDING) return;
  f->x = v3_madd(start, d, f->s);
  f->d = d;
  f->state = MS_HIT;
}

/* A unit vector making angle acos(cos_t) with unit d, at azimuth 2π u. */
BK_INLINE bk_v3 ms_rotate(bk_v3 d, float cos_t, float u) {
  float sin_t = RC_SQRT(fmax(0.0f, 1.0f - cos_t * cos_t));
  float phi = 6.28318530718f * u;
  /* Duff et al.'s branchless orthonormal basis */
  float sgn = d.z >= 0.0f ? 1.0f : -1.0f;
  float a = -1.0f / (sgn + d.z), b = d.x * d.y * a;
  bk_v3 t1 = v3(1.0f + sgn * d.x * d.x * a, sgn * b, -sgn * d.x);
  bk_v3 t2 = v3(b, sgn + d.y * d.y * a, -d.y);
  bk_v3 r = v3_scale(d, cos_t);
  float sp, cp;
  bk_sincos(phi, &sp, &cp);
  r = v3_madd(r, t1, sin_t * cp);
  r = v3_madd(r, t2, sin_t * sp);
  return rc_normalize(r);
}

/* The cosine between the old and the new direction under Henyey–Greenstein
 * with asymmetry g (g > 0 forward), by inversion; isotropic when |g| is tiny. */
BK_INLINE float ms_hg_cos(float g, float u) {
  if (fabs(g) < 1e-3f) return 1.0f - 2.0f * u;
  float k = (1.0f - g * g) / (1.0f - g + 2.0f * g * u);
  return bk_clampf((1.0f + g * g - k * k) / (2.0f * g), -1.0f, 1.0f);
}

/* The weight of the next leg per channel (see the top) with Russian
 * roulette: returns 0 when the chain ends. sigma_s: σs_c at the collision
 * (per voxel length); w0: the photon's initial brightest channel. */
BK_INLINE int ms_next_weight(const ms_flight *f, const float *sigma_s, int nch, float w0,
                             float u_roulette, float *w) {
  float inv_pdf = RC_EXP(f->tau_star) / f->sigma, wmax = 0.0f;
  for (int ch = 0; ch < nch; ch++) {
    w[ch] = fmin(f->power[ch] * sigma_s[ch] * inv_pdf, w0);
    wmax = fmax(wmax, w[ch]);
  }
  float q = fmin(1.0f, wmax / w0);
  if (!(u_roulette < q)) return 0;
  for (int ch = 0; ch < nch; ch++) w[ch] /= q;
  return 1;
}

#endif
