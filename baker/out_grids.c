/* out_grids.c: the derived grids of out_grids.h, voxel run by voxel run. */
#include "out_grids.h"

#include "voxelize.h"

/* The voxel whose σ stands for voxel i: voxel 0 of a uniform source. */
static inline size_t sigma_voxel(const og_source_t *s, size_t i) { return s->uniform ? 0 : i; }

/* Where channel c of voxel i lies in sigma_s and sigma_t. */
static inline size_t at(const og_source_t *s, size_t i, int c) {
  return vox_channel_at(s->sigma_channels, sigma_voxel(s, i), c);
}

/* a's values (sigma_channels per voxel; voxel 0's for all when uniform)
 * for voxels [lo, hi). */
static void og_repeat(const og_source_t *s, const float *a, size_t lo, size_t hi, float *out) {
  const int C = s->sigma_channels == 1 ? 1 : 3;
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < C; c++) *out++ = a[at(s, i, c)];
}

void og_extinction(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  og_repeat(s, s->sigma_t, lo, hi, out);
}

void og_scattering(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  og_repeat(s, s->sigma_s, lo, hi, out);
}

/* The grey density: the mean of the channels' sigma_t, summed in order. */
void og_density(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  for (size_t i = lo; i < hi; i++) {
    float sum = 0.0f;
    for (int c = 0; c < 3; c++) sum += s->sigma_t[at(s, i, c)];
    *out++ = sum / 3.0f;
  }
}

/* The source term of L = ∫ T σs L̄ dt per channel, σs ⊙ L̄ (W·m⁻³·sr⁻¹): a
 * renderer that takes the volume as emissive and absorbing (Blender, Houdini)
 * reads it as emission with `extinction` as absorption and no scattering. */
void og_emission(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  if (s->sca_channels == 1 && s->radiance_channels == 1) { /* grey: one product per voxel */
    for (size_t i = lo; i < hi; i++, out += 3)
      out[0] = out[1] = out[2] = s->scattering[sigma_voxel(s, i)] * s->radiance[i];
    return;
  }
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < 3; c++)
      *out++ = s->scattering[vox_channel_at(s->sca_channels, sigma_voxel(s, i), c)] *
               s->radiance[vox_channel_at(s->radiance_channels, i, c)];
}

/* Grey light's one value per voxel as the RGB grid `radiance`. */
void og_radiance(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < 3; c++) *out++ = s->radiance[vox_channel_at(s->radiance_channels, i, c)];
}

/* Dispersion: n per channel interleaved (R, G, B). */
void og_ior_rgb(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  for (size_t i = lo; i < hi; i++) {
    *out++ = s->ior_rb[i];
    *out++ = s->ior[i];
    *out++ = s->ior_rb[s->voxels + i];
  }
}

/* The Henyey–Greenstein g the view needs with radiance_flux: the object's
 * or the medium's, where anything scatters (0, the background, elsewhere). */
void og_phase_g(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  for (size_t i = lo; i < hi; i++) {
    const float *a = s->sigma_s;
    const int scatters = a[at(s, i, 0)] > 0.0f || a[at(s, i, 1)] > 0.0f || a[at(s, i, 2)] > 0.0f;
    *out++ = scatters ? (s->g ? s->g[i] : s->medium_g) : 0.0f;
  }
}
