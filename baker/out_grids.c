/* out_grids.c: the derived grids of out_grids.h, voxel run by voxel run. */
#include "out_grids.h"

#include "voxelize.h"

/* Channels of the volume's σ per voxel: 1 (grey) or 3. */
static inline int sigma_channels(const volume_t *v) { return v->sigma_channels == 1 ? 1 : 3; }

void og_extinction(const void *src, size_t lo, size_t hi, float *out) {
  const volume_t *v = ((const og_source_t *)src)->vol;
  const int C = sigma_channels(v);
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < C; c++) *out++ = vol_sigma_t(v, i, c);
}

void og_scattering(const void *src, size_t lo, size_t hi, float *out) {
  const volume_t *v = ((const og_source_t *)src)->vol;
  const int C = sigma_channels(v);
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < C; c++) *out++ = vol_sigma_s(v, i, c);
}

/* The grey density: the mean of the channels' σt, summed in order. */
void og_density(const void *src, size_t lo, size_t hi, float *out) {
  const volume_t *v = ((const og_source_t *)src)->vol;
  for (size_t i = lo; i < hi; i++) {
    float sum = 0.0f;
    for (int c = 0; c < 3; c++) sum += vol_sigma_t(v, i, c);
    *out++ = sum / 3.0f;
  }
}

/* The source term of L = ∫ T σs L̄ dt per channel, σs ⊙ L̄ (W·m⁻³·sr⁻¹): a
 * renderer that takes the volume as emissive and absorbing (Blender, Houdini)
 * reads it as emission with `extinction` as absorption and no scattering. */
void og_emission(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  if (s->vol && s->vol->sigma_channels == 1 && s->radiance_channels == 1) {
    for (size_t i = lo; i < hi; i++, out += 3) /* grey: one product per voxel */
      out[0] = out[1] = out[2] = vol_sigma_s(s->vol, i, 0) * s->radiance[i];
    return;
  }
  if (s->vol) {
    for (size_t i = lo; i < hi; i++)
      for (int c = 0; c < 3; c++)
        *out++ = vol_sigma_s(s->vol, i, c) * s->radiance[vox_channel_at(s->radiance_channels, i, c)];
    return;
  }
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < 3; c++)
      *out++ = s->scattering[vox_channel_at(s->sca_channels, i, c)] *
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
    const volume_t *v = s->vol;
    const int scatters =
        vol_sigma_s(v, i, 0) > 0.0f || vol_sigma_s(v, i, 1) > 0.0f || vol_sigma_s(v, i, 2) > 0.0f;
    *out++ = scatters ? (s->g ? s->g[i] : s->medium_g) : 0.0f;
  }
}
