/* scatter_march.h: one photon of a multiple-scattering march, host and
 * device: a chain of legs, each marched exactly as a single-scattering
 * photon (pm_march_leg, kernels/photon_march.h) while it samples its free
 * flight, and joined by scattering events (kernels/scatter.h: estimator,
 * roulette, random numbers).
 *
 * Specialisation (-D on the device; ms_params fields on the host):
 * MULTIPLE_SCATTERING (kernels/march_ms.cl; the events per photon are a
 * parameter, so a change of photons.bounces needs no new build), MS_SIGMA_GRID
 * (σs varies: read per voxel from the volume's σs, per metre, like σt in
 * photon_march.h, else ms_params.sigma_s), MS_G_GRID (g varies: read from
 * the volume's g), MS_HG (g ≠ 0 somewhere: without it the phase is
 * isotropic and no g is read). */
#ifndef BAKER_SCATTER_MARCH_H
#define BAKER_SCATTER_MARCH_H

#include "kernels/photon_march.h"
#include "kernels/scatter.h"

#if PH_DEVICE
#ifndef MS_SIGMA_GRID
#define MS_SIGMA_GRID 0
#endif
#ifndef MS_G_GRID
#define MS_G_GRID 0
#endif
#ifndef MS_HG
#define MS_HG 0
#endif
#define MS_SIGMA_GRID_OF(M) (MS_SIGMA_GRID)
#define MS_G_GRID_OF(M) (MS_G_GRID)
#define MS_HG_OF(M) (MS_HG)
#else
#define MS_SIGMA_GRID_OF(M) ((int)(M)->grid)
#define MS_G_GRID_OF(M) ((int)(M)->g_grid)
#define MS_HG_OF(M) 1
#endif

/* The volume's σs (per metre, the stride of its σ; or the coded σ, the
 * march's own buffer) and g per voxel, as the scattering events read them. */
typedef struct ms_medium {
  BK_GLOBAL const float *sigma_s;
  BK_GLOBAL const float *g;
} ms_medium;

/* σs per channel (per voxel length) and g at the collision of the photon's
 * last leg. */
BK_INLINE float ms_medium_at(const pm_params *P, const ms_params *M, ms_medium med, int nch,
                             bk_long idx, float *ss) {
  for (int ch = 0; ch < nch; ch++)
    ss[ch] = MS_SIGMA_GRID_OF(M) ? pm_sigma_at(P, med.sigma_s, idx, ch, 0) : M->sigma_s[ch];
  if (!MS_HG_OF(M)) return 0.0f;
  return MS_G_GRID_OF(M) ? med.g[idx] : M->g;
}

/* The leg that follows the collision of the last one: weight (with
 * roulette), direction, position. Returns 0 when the chain ends. */
BK_INLINE int ms_scatter(const pm_params *P, const ms_params *M, BK_GLOBAL const float *ng,
                         ms_medium med, pm_photon *ph, float w0, bk_uint index, bk_uint leg) {
  const int nch = PM_NCH(P);
  float ss[3] = {0.0f, 0.0f, 0.0f}, w[3] = {0.0f, 0.0f, 0.0f};
  float g = ms_medium_at(P, M, med, nch, ph->fl.idx, ss);
  if (!ms_next_weight(&ph->fl, ss, nch, w0, ms_uniform(M->seed, index, 4u * leg + 3u), w))
    return 0;
  float cos_t = ms_hg_cos(g, ms_uniform(M->seed, index, 4u * leg + 1u));
  bk_v3 d = ms_rotate(ph->fl.d, cos_t, ms_uniform(M->seed, index, 4u * leg + 2u));
  for (int ch = 0; ch < nch; ch++) ph->power[ch] = w[ch];
  ph->x = ph->fl.x;
  ph->c[0] = ph->fl.c[0];
  ph->c[1] = ph->fl.c[1];
  ph->c[2] = ph->fl.c[2];
  ph->v = d;
  ph->last = -1;
#if PM_FLUX_COMPILED
  ph->scattered = 1;
#endif
#if !PH_DEVICE || HAS_REFRACTION
  if (PM_HAS_REFRACTION(P)) {
    const rc_dims n3 = {P->grid.nx, P->grid.ny, P->grid.nz};
    bk_v3 g0;
    ph->v = v3_scale(d, rc_field(n3, ng, ph->x, &g0));
  }
#endif
  return 1;
}

/* Marches photon `index` and the legs its scattering events start, at most
 * M->max_bounces events; the arguments are pm_march_photon's and the scatter
 * parameters and the volume's σs and g. tally: the photon's energy
 * accounting. */
BK_INLINE void pm_march_scattered(BK_CONSTANT const pm_params *Pc, BK_CONSTANT const ms_params *Mc,
                                  BK_CONSTANT const ph_light *lights, BK_GLOBAL const float *ng,
                                  BK_GLOBAL const bk_uchar *pyr, BK_GLOBAL const float *sigma,
                                  ms_medium med, BK_GLOBAL bk_ulong *acc,
                                  BK_GLOBAL bk_ulong *masks, BK_GLOBAL const float *tables,
                                  bk_uint index, pm_result *res, ms_tally *tally PM_REC_DECL) {
  const pm_params Pv = *Pc;
  const pm_params *P = &Pv;
  const ms_params Mv = *Mc;
  const ms_params *M = &Mv;
  const int nch = PM_NCH(P);
  ng = pm_begin(P, ng, index, res);
  tally->entered = tally->escaped = tally->first = tally->later = 0.0f;
  tally->events = 0;
  pm_photon ph;
  if (!pm_start(P, lights, ng, tables, index, &ph PM_REC_ARG)) return;
#if PM_CAMERA_COMPILED
  ph.gvox = med.g;
#endif
  float w0 = 0.0f;
  for (int ch = 0; ch < nch; ch++) {
    w0 = fmax(w0, ph.power[ch]);
    tally->entered += ph.power[ch];
  }
  /* The step limit holds per leg (it catches light trapped by total
   * internal reflection); the path cap for the chain's physical path: a
   * leg's march past its collision is an expectation, not a path, so the
   * next leg starts from the path at the collision. */
  bk_uint steps = 0, fate, leg = 0;
  for (;;) {
    bk_uint leg_steps = 0;
    if (leg < M->max_bounces) {
      ms_flight_begin(&ph.fl, ms_uniform(M->seed, index, 4u * leg));
    } else {
      ph.fl.state = MS_IDLE;
      ph.fl.deposit = 0.0f;
    }
    fate = pm_march_leg(P, ng, pyr, sigma, acc, masks, &ph, &leg_steps PM_REC_ARG);
    steps += leg_steps;
    if (leg == 0) tally->first += ph.fl.deposit;
    else tally->later += ph.fl.deposit;
    if (fate == PM_FATE_LEFT)
      for (int ch = 0; ch < nch; ch++) tally->escaped += ph.power[ch];
    if (ph.fl.state != MS_HIT) break;
    ph.path = ph.fl.path;
    if (!ms_scatter(P, M, ng, med, &ph, w0, index, leg)) {
      fate = PM_FATE_ABSORBED; /* ended by the roulette */
      break;
    }
    tally->events++;
    leg++;
  }
  res->fate = fate;
  res->steps = steps;
  res->voxels = ph.voxels;
  res->path = ph.path;
}

#endif
