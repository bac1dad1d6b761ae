/* march_deposit.h: what a photon leaves in a voxel it crosses, as 64-bit
 * fixed-point sums (order-independent integer atomics); part of
 * kernels/photon_march.h, which includes it after pm_params and
 * PM_ATOMIC_ADD.
 *
 * Radiance: one counter per channel, Σ Φ·ℓ·r (pm_deposit).
 *
 * PM_FLUX (g != 0 somewhere, baker/bounces.c ms_decide): the accumulator
 * also holds, after the voxels' counters, PM_FLUX_SLOTS counters per voxel:
 * 3 signed ones (two's complement in the ulong atomics, order-independent
 * like the others), the luminance-weighted deposit times the chord's unit
 * direction, Σ Y·ℓ·ω with Y = Σ_c lum_c Φ_c (Rec. 709; the one channel
 * itself when PM_CHANNELS is 1), of the photons that have scattered; then
 * Σ Y·ℓ and Σ Y·ℓ·ω (3 signed) of the photons not scattered yet (a
 * multiple-scattering chain's first leg; every deposit with bounces 0).
 * baker/march.h pm_to_flux: the first moment of radiance (the two Σ Y·ℓ·ω
 * added), next to radiance's zeroth, and the uncollided light with its own
 * flux: the view gives the beam and the scattered light each its own
 * direction (they differ by tens of degrees in thick fog, where one mean
 * direction for both misplaced the forward lobes by 5-15% of the image).
 * Not in PM_MODE_ORIGINS.
 * Without the flag nothing of it is compiled.
 *
 * PM_CAMERA (with PM_FLUX and a scene camera, baker/march.c; a g that
 * varies only with multiple scattering, whose march reads g per voxel):
 * one more counter per voxel after the flux's,
 * Σ Y·ℓ·P(ω·ω_c)/P_max, the deposit weighted by the Henyey–Greenstein
 * phase 4π p(g, ω·ω_c) from the photon's direction ω into ω_c, the
 * direction from the voxel's centre to the camera; P_max = (1+|g|)/(1−|g|)²
 * keeps the sums within the luminance's own bound. Its mean over the
 * voxel is the light the voxel scatters towards that camera point, of
 * every order and every light, which no lobe of the first moment holds
 * when g is large (baker view, `radiance_camera`). */
#ifndef BAKER_MARCH_DEPOSIT_H
#define BAKER_MARCH_DEPOSIT_H

#define PM_FLUX_SLOTS 7 /* PM_FLUX: counters per voxel after the voxels' */
#define PM_CAMERA_SLOT 7 /* PM_CAMERA: its counter, after the flux's */
/* Counters per voxel after the voxels' with the flux (and the camera's). */
#define PM_FLUX_SLOTS_WITH(camera) (PM_FLUX_SLOTS + ((camera) ? 1 : 0))

/* Adds value (already multiplied by the fixed-point scale) to one counter,
 * rounded to the nearest quantum. */
BK_INLINE void pm_deposit(BK_GLOBAL bk_ulong *acc, float value) {
  bk_ulong q = (bk_ulong)(value + 0.5f);
  if (q) PM_ATOMIC_ADD(acc, q);
}

#if PM_FLUX_COMPILED
/* PM_FLUX: a channel's weight in the flux's luminance (Rec. 709; one
 * channel carries the sum of RGB, coloured by the host). */
BK_INLINE float pm_flux_weight(int nch, int ch) {
  return nch == 1 ? 1.0f : ch == 0 ? 0.2126f : ch == 1 ? 0.7152f : 0.0722f;
}

/* Adds y·d to three signed counters (quanta rounded to the nearest, in the
 * ulongs' two's complement). */
BK_INLINE void pm_deposit_vector(BK_GLOBAL bk_ulong *f, float y, bk_v3 d) {
  const float v[3] = {y * d.x, y * d.y, y * d.z};
  for (int a = 0; a < 3; a++) {
    bk_long q = (bk_long)(v[a] >= 0.0f ? v[a] + 0.5f : v[a] - 0.5f);
    if (q) PM_ATOMIC_ADD(f + a, (bk_ulong)q);
  }
}

/* Adds y·d to the scattered light's flux counters of a voxel, or, while
 * the photon has not scattered, y and y·d to the uncollided ones: four
 * atomics per deposit at most, as many as one flux sum for all and Y0 took
 * (the total F is the sum of the two, baker/march.c). */
BK_INLINE void pm_deposit_flux(BK_GLOBAL bk_ulong *f, float y, bk_v3 d, bk_uint scattered) {
  if (scattered) {
    pm_deposit_vector(f, y, d);
    return;
  }
  pm_deposit(f + 3, y);
  pm_deposit_vector(f + 4, y, d);
}
#endif

#if PM_CAMERA_COMPILED
/* PM_CAMERA: 4π p_HG(g, d·ω_c) / P_max, at most 1, for light moving along
 * unit d through voxel c of asymmetry g; ω_c points from the voxel's centre
 * to the camera. */
BK_INLINE float pm_camera_phase(const pm_params *P, const int *c, bk_v3 d, float g) {
  const bk_v3 w = v3(P->cam[0] - ((float)c[0] + 0.5f), P->cam[1] - ((float)c[1] + 0.5f),
                     P->cam[2] - ((float)c[2] + 0.5f));
  const float len = rc_length(w);
  const float cosv = len > 0.0f ? v3_dot(d, w) / len : 1.0f;
  const float den = 1.0f + g * g - 2.0f * g * cosv;
  const float p = (1.0f - g * g) / (den * RC_SQRT(den)) * P->cam_scale;
  return p < 1.0f ? p : 1.0f;
}
#endif

#endif
