/* bounces.h: multiple scattering's host side: photons.bounces "auto"
 * decided from the volume, and the parameters and scatter grid that the
 * scattering march (kernels/scatter_march.h) reads.
 *
 * The "auto" rule. r, the ratio of the energy deposited by one scattering
 * order to the one before it, is estimated as
 *     r = a · (1 − e^(−τ)),
 * a = Σσs / Σσt over the voxels (the albedo: a scattered photon survives),
 * τ = σ̄t · L̄ with σ̄t the mean extinction over the voxels that scatter and
 * L̄ = 4V/S the mean chord of the grid box (Cauchy's formula: the mean
 * length a photon crossing the box travels in it); 1 − e^(−τ) is then the
 * chance that a photon scatters before it leaves. Single scattering misses
 * r + r² + … = r/(1 − r) of the first order, a share r of the total. So:
 *   r < MS_AUTO_THIN (2%)  → bounces 0: single scattering, the kernels of a
 *                            scene without multiple scattering, no cost;
 *   else                   → the fewest N events whose truncation misses a
 *                            share r^(N+1) < MS_AUTO_REMAINDER (1%) of the
 *                            total, at most MS_AUTO_MAX.
 * On a 2 m box: thin haze (σs 0.01) r = 0.013, single scattering; the
 * bundled fog (σs 0.5, σa 0.02) r = 0.48, N = 6; thick fog (σs 1.5, σa 0.05)
 * r = 0.85, N = 27 (tests/test_scatter.c auto). Photons end sooner by
 * leaving the grid or by Russian roulette: N bounds the cost, it does not
 * set it. */
#ifndef BAKER_BOUNCES_H
#define BAKER_BOUNCES_H

#include "kernels/scatter.h"
#include "scene.h"
#include "voxelize.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MS_AUTO_THIN 0.02
#define MS_AUTO_REMAINDER 0.01
#define MS_AUTO_MAX 1000

typedef struct ms_setup {
  ms_params params;  /* max_bounces 0: single scattering, nothing else set */
  int auto_chosen;   /* bounces came from the "auto" rule */
  double ratio;      /* the rule's r (computed for every scene) */
  int sigma_grid;    /* σs varies: the march reads the volume's */
  int g_grid;        /* g varies: the march reads the volume's */
  int hg;            /* g != 0 somewhere */
} ms_setup_t;

/* The rule's r for a volume (see above). */
double ms_order_ratio(const volume_t *vol);
/* The events the rule allows for r. */
int ms_auto_bounces(double r);

/* Decides the events (scene->bounces or the rule), and whether σs and g
 * vary. Sets *grey_scatter: σs has R = G = B everywhere (a one-channel march
 * then still holds, as for σt). */
void ms_decide(const scene_t *scene, const volume_t *vol, ms_setup_t *ms, int *grey_scatter);
/* When events are allowed: the parameters (the uniform σs per voxel
 * length and g, when they do not vary; otherwise the march reads the
 * volume's). */
void ms_build(const scene_t *scene, const volume_t *vol, ms_setup_t *ms);

/* -D flags of the scattering kernel (empty when max_bounces is 0). */
void ms_kernel_defines(const ms_setup_t *ms, char *buf, size_t len);

#ifdef __cplusplus
}
#endif
#endif
