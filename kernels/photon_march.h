/* photon_march.h: one photon's march through the grid, shared by host and device.
 *
 * In: the photon's index (its light and origin come from light_sample.h), the
 * refractive field {∇n, n} and the constant-block pyramid of n
 * (kernels/ray_core.h), the volume's σt per metre (or a constant
 * extinction), and a fixed-point accumulator. Out: the accumulator gains
 * Φ·ℓ·S per voxel crossed (ℓ the path length in that voxel, in voxels, S the
 * fixed-point scale); the photon's fate, steps and path length.
 *
 * Everything is in voxel coordinates (u = (x - origin)/h, voxel i spans
 * [i, i+1)); the ray equation d/ds(n dx/ds) = ∇n is unchanged by the uniform
 * scaling. The field, the ray step (Euler or RK4), the segment attenuation,
 * the grid entry and the constant blocks are the ray core's
 * (kernels/ray_core.h), the same the camera rays of the view use.
 * Each step's chord is straight and deposited by an exact 3D DDA
 * (kernels/march_dda.h). In a block
 * the pyramid flags constant (n constant over it and a 2-voxel halo, so n and
 * the interpolated ∇n are exactly constant inside), the photon goes straight to
 * the block's boundary by DDA instead of stepping. With constant n over the
 * whole grid (HAS_REFRACTION 0) the kernel is a pure DDA with no gradient code.
 * In a varying block, a photon in a constant cell of the field (the cube
 * between 8 voxel centres, ∇n exactly 0 in it: the halo around the varying
 * band) goes straight to where the run of such cells ends (pm_cell_walk)
 * instead of stepping: the exact ray there, not the integrator's.
 *
 * Attenuation is exact per voxel: crossing length ℓ in a voxel of extinction
 * σ (per voxel length) deposits Φ0 (1 - e^{-σℓ})/σ, computed in a form stable
 * as σ -> 0 (rc_atten: it tends to Φ0 ℓ), and leaves Φ0 e^{-σℓ}; the energy
 * deposited along a segment is the exact integral of the power.
 *
 * Specialisation (-D flags on the device; fields of pm_params on the host):
 * HAS_REFRACTION, HOMOGENEOUS (σt as parameters, no grid lookups),
 * INTEGRATOR (0 Euler, 1 RK4), PM_CHANNELS (1 when every light has the same
 * colour and the medium is grey: one atomic per voxel instead of three),
 * LIGHT_DIRECTIONAL / LIGHT_SPOT / LIGHT_POINT (light_sample.h), DISPERSION
 * (n differs between channels: ng holds three fields, R, G, B, one after the
 * other; photon i carries channel i mod 3 alone, with 3x that channel's
 * power so every channel's mean is unchanged, and bends with that channel's
 * n: pm_channel_field, pm_disperse), and PM_MODE:
 *
 * Modes: the march's optional inputs from kernels/light_domain.h, which it
 * uses without knowing who made them (the adaptive pipeline does):
 *  PM_MODE_REFERENCE  what is described above.
 *  PM_MODE_ORIGINS    an origin recorder: the deposits go to the coarse cell
 *                     of the voxel (blocks of 2^coarse_shift voxels a side,
 *                     its own accumulator), and each coarse cell a photon
 *                     passes gets the bit of the photon's light-domain cell
 *                     in its origin mask (ld_origin_mark).
 *  PM_MODE_TABLES     sampling tables: the photon's light-domain point is
 *                     warped through its light's table (ld_pdf_warp) and its
 *                     power multiplied by w = 1/pdf. Per voxel the
 *                     accumulator holds one more counter after the radiance
 *                     channels: the photon count and the sum of w, packed
 *                     (count << count_shift) + round(w * weight_scale), added
 *                     with one atomic each time a photon enters the voxel
 *                     (consecutive deposits in the same voxel, the small
 *                     steps of a refractive region, count once). One packed
 *                     atomic per passage and none per extra deposit: the
 *                     slides lost time to atomics for exactly these data.
 *
 * PM_FLUX and PM_CAMERA: the flux's and the camera's counters
 * (kernels/march_deposit.h). */
#ifndef BAKER_MARCH_KERNEL_H
#define BAKER_MARCH_KERNEL_H

#include "kernels/light_domain.h"
#include "kernels/light_sample.h"
#include "kernels/medium_code.h"
#include "kernels/ray_core.h"

/* Multiple scattering (kernels/scatter.h, scatter_march.h): on the host
 * always compiled (off unless asked for), on the device only with
 * -DMULTIPLE_SCATTERING=1 (kernels/march_ms.cl); without it the march below
 * is single scattering. */
#if !PH_DEVICE || (defined(MULTIPLE_SCATTERING) && MULTIPLE_SCATTERING)
#define PM_MS_COMPILED 1
#include "kernels/scatter.h"
#else
#define PM_MS_COMPILED 0
#endif

#define PM_MAX_STEPS 65536 /* photons trapped by total internal reflection */
/* A photon that has travelled this many grid diagonals inside the grid is
 * trapped too: the bound on every photon's path that makes the fixed-point
 * sums overflow-free (baker/march.h). */
#define PM_MAX_PATH_DIAGONALS 16.0f
/* A photon whose brightest channel falls below this fraction of its initial
 * power is absorbed: what it would still deposit is at most this fraction. */
#define PM_ABSORB_FRACTION 1e-6f
/* What happened to a photon (pm_result.fate). */
#define PM_FATE_MISSED 0     /* never hit the grid */
#define PM_FATE_LEFT 1       /* left the grid */
#define PM_FATE_ABSORBED 2   /* power below PM_ABSORB_FRACTION */
#define PM_FATE_STEP_LIMIT 3 /* PM_MAX_STEPS or PM_MAX_PATH_DIAGONALS */


#define PM_MODE_REFERENCE 0
#define PM_MODE_ORIGINS 1
#define PM_MODE_TABLES 2

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
#ifndef DISPERSION
#define DISPERSION 0
#endif
#define PM_DISPERSION(P) (DISPERSION)
#ifndef PM_SIGMA_STRIDE
#define PM_SIGMA_STRIDE 3
#endif
#define PM_SIGMA_STRIDE_OF(P) (PM_SIGMA_STRIDE)
#ifndef PM_SIGMA_CODED
#define PM_SIGMA_CODED 0
#endif
#define PM_SIGMA_CODED_OF(P) (PM_SIGMA_CODED)
#ifndef PM_FLUX
#define PM_FLUX 0
#endif
#define PM_FLUX_COMPILED (PM_FLUX && PM_MODE != PM_MODE_ORIGINS)
#define PM_FLUX_OF(P) (PM_FLUX_COMPILED)
#ifndef PM_CAMERA
#define PM_CAMERA 0
#endif
#define PM_CAMERA_COMPILED (PM_FLUX_COMPILED && PM_CAMERA)
#define PM_CAMERA_OF(P) (PM_CAMERA_COMPILED)
/* the twins' even lattice (pm_params.lattice): a per-voxel test and index
 * that cost the main march 5% when compiled in and switched off */
#ifndef PM_LATTICE
#define PM_LATTICE 0
#endif
#define PM_LATTICE_OF(P) (PM_LATTICE && PM_MODE == PM_MODE_REFERENCE)
#define PM_HAS_REFRACTION(P) (HAS_REFRACTION)
#define PM_HOMOGENEOUS(P) (HOMOGENEOUS)
#define PM_INTEGRATOR(P) (INTEGRATOR)
#define PM_NCH(P) (PM_CHANNELS)
#define PM_MODE_OF(P) (PM_MODE)
#define PM_ATOMIC_ADD(p, q) atom_add((p), (q))
#define PM_REC_DECL
#define PM_REC_ARG
#define PM_RECORD(x)
#else
#define PM_HAS_REFRACTION(P) ((P)->has_refraction)
#define PM_HOMOGENEOUS(P) ((P)->homogeneous)
#define PM_INTEGRATOR(P) ((P)->integrator)
#define PM_NCH(P) ((int)(P)->channels)
#define PM_MODE_OF(P) ((int)(P)->mode)
#define PM_DISPERSION(P) ((P)->dispersion)
#define PM_SIGMA_STRIDE_OF(P) ((int)((P)->sigma_stride & ~PM_SIGMA_CODED_FLAG))
#define PM_SIGMA_CODED_OF(P) (((P)->sigma_stride & PM_SIGMA_CODED_FLAG) != 0u)
#define PM_FLUX_COMPILED 1
#define PM_FLUX_OF(P) ((P)->flux && (P)->mode != PM_MODE_ORIGINS)
#define PM_CAMERA_COMPILED 1
#define PM_CAMERA_OF(P) ((P)->camera && PM_FLUX_OF(P))
#define PM_LATTICE_OF(P) ((P)->lattice != 0)
/* The host path marches one photon at a time on one thread. */
#define PM_ATOMIC_ADD(p, q) (*(p) += (q))
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
#define PM_REC_ARG , rec
#define PM_RECORD(x) pm_record(rec, (x))
#endif

/* Whether the march has the pyramid: always on the device; on the host a
 * null one is no octree at all, a curved step everywhere (the plain loop
 * of scripts/bench_march_run, issue 15's yardstick). */
#if PH_DEVICE
#define PM_HAS_PYRAMID(pyr) 1
#else
#define PM_HAS_PYRAMID(pyr) ((pyr) != 0)
#endif

/* pm_params.sigma_stride: the volume's σ is coded (kernels/medium_code.h) */
#define PM_SIGMA_CODED_FLAG 0x100u

/* Parameters of one march, shared by every photon. Pinned at 160 bytes. */
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
  bk_uint dispersion;     /* host path only: the device uses -D DISPERSION */
  bk_uint flux;           /* host path only: the device uses -D PM_FLUX */
  bk_uint sigma_stride;   /* channels of the volume's σ (1 grey, 3), | PM_SIGMA_CODED_FLAG when coded: host path only (-D PM_SIGMA_STRIDE, PM_SIGMA_CODED) */
  bk_uint mode;               /* PM_MODE_*: host path only (the device uses -D PM_MODE) */
  int coarse_shift;           /* pilot: deposits and marks at voxel >> coarse_shift */
  int cnx, cny, cnz;          /* pilot: the coarse grid */
  float weight_scale;         /* weighted: quanta of the packed weight sum per unit w */
  bk_uint count_shift;        /* weighted: the count's lowest bit in the packed counter */
  float h;                    /* the voxel size: σ per metre -> per voxel length */
  float cam[3];               /* PM_CAMERA: the camera's position, voxel coordinates */
  float cam_g;                /* PM_CAMERA: the media's one g (not cam_g_grid) */
  float cam_scale;            /* PM_CAMERA: 1 / P_max, of the largest |g| */
  bk_uint camera;             /* host path only: the device uses -D PM_CAMERA */
  bk_uint cam_g_grid;         /* PM_CAMERA: g per voxel, from pm_photon.gvox */
  bk_uint lattice;            /* reference: deposits only at voxels of even (i, j, k), packed
                                 at c >> 1 in the cnx x cny x cnz lattice (error-estimate twins) */
} pm_params;
BK_STATIC_ASSERT(sizeof(pm_params) == 160, "pm_params layout is shared with kernels");

/* One photon's outcome. */
typedef struct pm_result {
  bk_uint fate;   /* PM_FATE_* */
  bk_uint steps;  /* march iterations: integrator steps, straight blocks and runs of cells */
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
#if PM_MS_COMPILED
  ms_flight fl;     /* multiple scattering: this leg's free flight */
#endif
#if PM_FLUX_COMPILED
  bk_v3 fdir;       /* PM_FLUX: the unit direction of the chord being deposited */
  bk_uint scattered; /* PM_FLUX: 0 on the light's own leg, 1 after a scattering event */
#endif
#if PM_CAMERA_COMPILED
  BK_GLOBAL const float *gvox; /* PM_CAMERA with cam_g_grid: g per voxel (the scatter's) */
#endif
} pm_photon;

#include "kernels/march_deposit.h"

BK_INLINE bk_long pm_index(const bk_grid g, int i, int j, int k) {
  return (bk_long)i + (bk_long)g.nx * ((bk_long)j + (bk_long)g.ny * (bk_long)k);
}

/* Counters per voxel in the accumulator of a mode (the pilot's are per
 * coarse cell). */
BK_INLINE int pm_acc_stride(int mode, int channels) {
  return mode == PM_MODE_TABLES ? channels + 1 : channels;
}

/* σs (t = 0) or σt (t = 1) per voxel length, channel ch, at voxel idx, from
 * the volume's σ per metre (one channel for a grey medium, three
 * otherwise): plain, the array of that coefficient (the caller passes σt's
 * or σs's); coded (kernels/medium_code.h), the one buffer of both. The float
 * product is the host's (float)(σ · (double)h) bit for bit: two floats
 * multiply exactly in double, so both round once. */
BK_INLINE float pm_sigma_at(const pm_params *P, BK_GLOBAL const float *sigma, bk_long idx,
                            int ch, int t) {
  if (PM_SIGMA_CODED_OF(P)) {
    const bk_long voxels = (bk_long)P->grid.nx * P->grid.ny * P->grid.nz;
    return mc_sigma(sigma, voxels, PM_SIGMA_STRIDE_OF(P), idx, ch, t) * P->h;
  }
  return sigma[PM_SIGMA_STRIDE_OF(P) == 1 ? idx : 3 * idx + ch] * P->h;
}

/* σt per voxel length of the nch channels at voxel idx (pm_sigma_at's
 * values; a homogeneous medium's from the parameters), read once per
 * voxel crossed. */
BK_INLINE void pm_sigma_t_all(const pm_params *P, BK_GLOBAL const float *sigma, bk_long idx,
                              int nch, float *st) {
  if (PM_HOMOGENEOUS(P)) {
    for (int ch = 0; ch < nch; ch++) st[ch] = P->sigma_t[ch];
  } else if (PM_SIGMA_CODED_OF(P)) {
    const bk_long voxels = (bk_long)P->grid.nx * P->grid.ny * P->grid.nz;
    const int C = PM_SIGMA_STRIDE_OF(P);
    float v[3];
    mc_sigma_all(sigma, voxels, C, idx, 1, v);
    for (int ch = 0; ch < nch; ch++) st[ch] = v[C == 1 ? 0 : ch] * P->h;
  } else {
    for (int ch = 0; ch < nch; ch++) st[ch] = pm_sigma_at(P, sigma, idx, ch, 1);
  }
}

/* The photon crosses length seg (voxels) of voxel idx (at c): deposits the
 * exact integral of its attenuated power and attenuates it. Returns 1 when
 * it is absorbed (every channel below its threshold). Always inlined: with
 * multiple scattering PoCL made it a call per voxel, which cost that march
 * 8% (the DDA's registers saved and restored around it). */
BK_ALWAYS_INLINE int pm_cross_voxel(const pm_params *P, BK_GLOBAL const float *sigma,
                                    BK_GLOBAL bk_ulong *acc, BK_GLOBAL bk_ulong *masks,
                                    pm_photon *ph, bk_long idx, const int *c, float seg) {
  const int nch = PM_NCH(P);
  const int stride = pm_acc_stride(PM_MODE_OF(P), nch);
  bk_long didx = idx; /* where the deposit goes */
#if !PH_DEVICE || PM_MODE == PM_MODE_ORIGINS
  if (PM_MODE_OF(P) == PM_MODE_ORIGINS) {
    const int s = P->coarse_shift;
    didx = (bk_long)(c[0] >> s) +
           (bk_long)P->cnx * ((bk_long)(c[1] >> s) + (bk_long)P->cny * (bk_long)(c[2] >> s));
    if (didx != ph->last) {
      ph->last = didx;
      ld_origin_mark(masks, ld_origin_index(didx, ph->light, (bk_long)P->cnx * P->cny * P->cnz),
                     ph->cell);
    }
  }
#endif
  int keep = 1; /* the deposit is stored */
  if (PM_LATTICE_OF(P)) { /* the twins read the even lattice alone: 1/8 of the sums */
    keep = ((c[0] | c[1] | c[2]) & 1) == 0;
    didx = (bk_long)(c[0] >> 1) +
           (bk_long)P->cnx * ((bk_long)(c[1] >> 1) + (bk_long)P->cny * (bk_long)(c[2] >> 1));
  }
#if !PH_DEVICE || PM_MODE == PM_MODE_TABLES
  if (PM_MODE_OF(P) == PM_MODE_TABLES && idx != ph->last) {
    ph->last = idx;
    PM_ATOMIC_ADD(acc + stride * idx + nch, ph->packed);
  }
#endif
  float st[3];
  pm_sigma_t_all(P, sigma, idx, nch, st);
#if PM_MS_COMPILED
  if (ph->fl.state == MS_FLYING) {
    float sbar = 0.0f;
    for (int ch = 0; ch < nch; ch++) sbar += st[ch];
    ms_flight_cross(&ph->fl, ph->power, ph->path, st, nch, sbar / (float)nch, seg, idx, c);
  }
#endif
  float pmax = 0.0f;
#if PM_FLUX_COMPILED
  float lum = 0.0f; /* the luminance deposited, for the flux */
#endif
  for (int ch = 0; ch < nch; ch++) {
#if !PH_DEVICE || DISPERSION
    if (PM_DISPERSION(P) && ph->power[ch] == 0.0f) continue; /* not this photon's channel */
#endif
    float trans;
    float r = rc_atten(st[ch] * seg, &trans);
    if (keep) pm_deposit(acc + stride * didx + ch, ph->power[ch] * seg * r * P->fixed_scale);
#if PM_FLUX_COMPILED
    lum += pm_flux_weight(nch, ch) * ph->power[ch] * seg * r;
#endif
#if PM_MS_COMPILED
    ph->fl.deposit += ph->power[ch] * seg * r;
#endif
    ph->power[ch] *= trans;
    pmax = ph->power[ch] > pmax ? ph->power[ch] : pmax;
  }
#if PM_FLUX_COMPILED
  if (PM_FLUX_OF(P)) {
    const bk_grid g = P->grid;
    const bk_long base = (bk_long)g.nx * (bk_long)g.ny * (bk_long)g.nz * (bk_long)stride;
    BK_GLOBAL bk_ulong *f = acc + base + PM_FLUX_SLOTS_WITH(PM_CAMERA_OF(P)) * idx;
    pm_deposit_flux(f, lum * P->fixed_scale, ph->fdir, ph->scattered);
#if PM_CAMERA_COMPILED
    if (PM_CAMERA_OF(P)) {
      const float g = P->cam_g_grid ? ph->gvox[idx] : P->cam_g;
      pm_deposit(f + PM_CAMERA_SLOT, lum * P->fixed_scale * pm_camera_phase(P, c, ph->fdir, g));
    }
#endif
  }
#endif
  ph->path += seg;
  ph->voxels++;
  return pmax < ph->threshold;
}

#include "kernels/march_dda.h"

#if !PH_DEVICE || DISPERSION
/* Dispersion: the field of photon `index`'s channel (index mod 3), the
 * fields of R, G and B following one another in ng. */
BK_INLINE BK_GLOBAL const float *pm_channel_field(const pm_params *P, BK_GLOBAL const float *ng,
                                                  bk_uint index) {
  const rc_dims n3 = {P->grid.nx, P->grid.ny, P->grid.nz};
  return rc_field_channel(n3, ng, (int)(index % 3u));
}
#endif

/* What both walks (pm_march_photon, pm_march_scattered) do first: an empty
 * result, and the field the photon bends in (its channel's, with dispersion). */
BK_INLINE BK_GLOBAL const float *pm_begin(const pm_params *P, BK_GLOBAL const float *ng,
                                          bk_uint index, pm_result *res) {
  res->fate = PM_FATE_MISSED;
  res->steps = 0;
  res->voxels = 0;
  res->path = 0.0f;
#if !PH_DEVICE || DISPERSION
  if (PM_DISPERSION(P)) return pm_channel_field(P, ng, index);
#endif
  return ng;
}

#if !PH_DEVICE || DISPERSION
/* Dispersion: the photon carries channel ch alone, with three times its
 * power there (each channel gets a third of the photons). */
BK_INLINE void pm_disperse(pm_photon *ph, int ch) {
  for (int c = 0; c < 3; c++) ph->power[c] = c == ch ? 3.0f * ph->power[c] : 0.0f;
}
#endif

/* Starts photon `index`: its light, its point of the light domain (warped
 * through the light's sampling table in PM_MODE_TABLES, which sets its
 * weight), origin, direction and grid entry. Returns 0 when it misses the
 * grid. */
BK_INLINE int pm_start(const pm_params *P, BK_CONSTANT const ph_light *lights,
                       BK_GLOBAL const float *ng, BK_GLOBAL const float *tables, bk_uint index,
                       pm_photon *ph PM_REC_DECL) {
  const bk_grid g = P->grid;
  const bk_uint l = ph_light_of(lights, P->light_count, index);
  BK_CONSTANT const ph_light *L = lights + l;
  bk_v3 o, d;
  float t0, t1, a, b, w = 1.0f;
  ph_point(L, index - L->first, &a, &b);
#if !PH_DEVICE || PM_MODE == PM_MODE_TABLES
  if (PM_MODE_OF(P) == PM_MODE_TABLES) {
    ld_sample s = ld_pdf_warp(tables + l * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y), LD_CELLS_X,
                              LD_CELLS_Y, a, b);
    a = s.x;
    b = s.y;
    w = 1.0f / s.pdf;
  }
#endif
  ph_map(L, a, b, &o, &d);
  PM_RECORD(o);
  if (!rc_slab(o, d, v3(0.0f, 0.0f, 0.0f), v3((float)g.nx, (float)g.ny, (float)g.nz), &t0, &t1))
    return 0;
  ph->light = (int)l;
  ph->cell = ld_cell_of(a, b);
  ph->last = -1;
  ph->packed = ((bk_ulong)1 << P->count_shift) + (bk_ulong)(w * P->weight_scale + 0.5f);
  ph->x = v3_madd(o, d, t0);
  ph->c[0] = bk_clampi(rc_floori(ph->x.x), 0, g.nx - 1);
  ph->c[1] = bk_clampi(rc_floori(ph->x.y), 0, g.ny - 1);
  ph->c[2] = bk_clampi(rc_floori(ph->x.z), 0, g.nz - 1);
  ph->v = d;
  ph->power[0] = L->power[0] * w;
  ph->power[1] = L->power[1] * w;
  ph->power[2] = L->power[2] * w;
#if !PH_DEVICE || DISPERSION
  if (PM_DISPERSION(P)) pm_disperse(ph, (int)(index % 3u));
#endif
  float pmax = ph->power[0];
  for (int ch = 1; ch < PM_NCH(P); ch++) pmax = ph->power[ch] > pmax ? ph->power[ch] : pmax;
  ph->threshold = P->absorb_fraction * pmax;
  ph->path = 0.0f;
  ph->voxels = 0;
#if PM_MS_COMPILED
  ph->fl.state = MS_IDLE;
#endif
#if PM_FLUX_COMPILED
  ph->scattered = 0;
#endif
  PM_RECORD(ph->x);
#if !PH_DEVICE || HAS_REFRACTION
  if (PM_HAS_REFRACTION(P)) {
    const rc_dims n3 = {g.nx, g.ny, g.nz};
    bk_v3 g0;
    ph->v = v3_scale(d, rc_field(n3, ng, ph->x, &g0));
  }
#endif
  return 1;
}

#if !PH_DEVICE || HAS_REFRACTION
/* One step where n varies: the ray core's step, its chord deposited.
 * Returns a PM_DDA_* status. */
BK_INLINE int pm_curved_step(const pm_params *P, BK_GLOBAL const float *ng,
                             BK_GLOBAL const float *sigma, BK_GLOBAL bk_ulong *acc,
                             BK_GLOBAL bk_ulong *masks, pm_photon *ph) {
  const bk_grid g = P->grid;
  const rc_dims n3 = {g.nx, g.ny, g.nz};
  int gl[3] = {0, 0, 0}, gh[3] = {g.nx, g.ny, g.nz};
  bk_v3 x1, v1;
  rc_step(n3, ng, (int)PM_INTEGRATOR(P), P->step, ph->x, ph->v, &x1, &v1);
  bk_v3 seg = v3_sub(x1, ph->x);
  float len = rc_length(seg);
  int r = PM_DDA_REACHED;
  if (rc_floori(x1.x) == ph->c[0] && rc_floori(x1.y) == ph->c[1] && rc_floori(x1.z) == ph->c[2]) {
    /* most steps of half a voxel stay in their voxel: no DDA set-up */
#if PM_FLUX_COMPILED
    if (len > 0.0f) ph->fdir = v3_scale(seg, 1.0f / len);
#endif
    if (len > 0.0f &&
        pm_cross_voxel(P, sigma, acc, masks, ph, pm_index(g, ph->c[0], ph->c[1], ph->c[2]), ph->c, len))
      r = PM_DDA_ABSORBED;
#if PM_MS_COMPILED
    if (len > 0.0f) ms_flight_place(&ph->fl, ph->x, v3_scale(seg, 1.0f / len));
#endif
  } else if (len > 0.0f) {
    r = pm_dda(P, 0, sigma, acc, masks, ph, v3_scale(seg, 1.0f / len), len, gl, gh, 0);
  }
  if (r == PM_DDA_REACHED) ph->x = x1;
  ph->v = v1;
  return r;
}
#endif

#if !PH_DEVICE || HAS_REFRACTION
/* Straight across the run of constant cells of the field that x starts
 * (rc_cell_constant: n one value and ∇n exactly 0 in each), to the face
 * where the next cell varies or the grid ends (rc_cell_run), deposited by
 * the DDA as a curved step's chord is. Returns a PM_DDA_* status, or -1
 * when x is already on the exit face (the caller takes a curved step,
 * which always moves on). v stays: ∇n is 0 on the way. */
BK_INLINE int pm_cell_walk(const pm_params *P, BK_GLOBAL const bk_uchar *pyr,
                           BK_GLOBAL const float *sigma, BK_GLOBAL bk_ulong *acc,
                           BK_GLOBAL bk_ulong *masks, pm_photon *ph) {
  const rc_dims n3 = {P->grid.nx, P->grid.ny, P->grid.nz};
  const bk_v3 d = rc_normalize(ph->v);
  const float len = rc_cell_run(pyr, n3, ph->x, d);
  if (!(len > RC_CELL_PAST)) return -1;
  int gl[3] = {0, 0, 0}, gh[3] = {n3.nx, n3.ny, n3.nz};
  return pm_dda(P, 0, sigma, acc, masks, ph, d, len + RC_CELL_PAST, gl, gh, 0);
}
#endif

/* Marches a started photon until it leaves the grid, is absorbed or reaches
 * the step or path limit (*steps counts on across calls); returns its
 * PM_FATE_*. Each iteration either crosses a constant block of the pyramid
 * straight to its boundary or takes one curved step. */
BK_INLINE bk_uint pm_march_leg(const pm_params *P, BK_GLOBAL const float *ng,
                               BK_GLOBAL const bk_uchar *pyr, BK_GLOBAL const float *sigma,
                               BK_GLOBAL bk_ulong *acc, BK_GLOBAL bk_ulong *masks, pm_photon *ph,
                               bk_uint *steps PM_REC_DECL) {
  const rc_dims n3 = {P->grid.nx, P->grid.ny, P->grid.nz};
  int gl[3] = {0, 0, 0}, gh[3] = {n3.nx, n3.ny, n3.nz};
  for (;;) {
    if (pm_out_of_steps(P, ph, *steps)) return PM_FATE_STEP_LIMIT;
    (*steps)++;
    int r;
#if !PH_DEVICE || HAS_REFRACTION
    if (PM_HAS_REFRACTION(P)) {
      const int level = PM_HAS_PYRAMID(pyr) ? rc_block_level(pyr, n3, ph->c) : 0;
      if (level > 0) { /* constant block: straight to its boundary */
        int lo[3], hi[3];
        rc_block_bounds(n3, level, ph->c, lo, hi);
        r = pm_dda(P, pyr, sigma, acc, masks, ph, rc_normalize(ph->v), RC_FAR, lo, hi, steps);
      } else {
        r = PM_HAS_PYRAMID(pyr) && rc_cell_constant(pyr, n3, ph->x)
                ? pm_cell_walk(P, pyr, sigma, acc, masks, ph)
                : -1;
        if (r < 0) r = pm_curved_step(P, ng, sigma, acc, masks, ph);
      }
    } else
#endif
    {
      r = pm_dda(P, 0, sigma, acc, masks, ph, ph->v, RC_FAR, gl, gh, 0);
    }
    PM_RECORD(ph->x);
    if (r == PM_DDA_LEFT_GRID) return PM_FATE_LEFT;
    if (r == PM_DDA_ABSORBED) return PM_FATE_ABSORBED;
  }
}

/* Marches photon `index` (0 <= index < photon_total) to its end. masks: the
 * origin recorder's masks (PM_MODE_ORIGINS); tables: one sampling table of
 * LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y) floats per light (PM_MODE_TABLES);
 * unused otherwise. */
BK_INLINE void pm_march_photon(BK_CONSTANT const pm_params *Pc, BK_CONSTANT const ph_light *lights,
                               BK_GLOBAL const float *ng, BK_GLOBAL const bk_uchar *pyr,
                               BK_GLOBAL const float *sigma, BK_GLOBAL bk_ulong *acc,
                               BK_GLOBAL bk_ulong *masks, BK_GLOBAL const float *tables,
                               bk_uint index, pm_result *res PM_REC_DECL) {
  /* a private copy: the compiler cannot know the deposits leave P alone and
   * would reload it after every atomic */
  const pm_params Pv = *Pc;
  const pm_params *P = &Pv;
  ng = pm_begin(P, ng, index, res);
  pm_photon ph;
  if (!pm_start(P, lights, ng, tables, index, &ph PM_REC_ARG)) return;
#if PM_CAMERA_COMPILED
  ph.gvox = 0; /* single scattering keeps the camera only for one g */
#endif
  bk_uint steps = 0;
  res->fate = pm_march_leg(P, ng, pyr, sigma, acc, masks, &ph, &steps PM_REC_ARG);
  res->steps = steps;
  res->voxels = ph.voxels;
  res->path = ph.path;
}

#endif
