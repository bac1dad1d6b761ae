/* out_grids.c: the derived grids of out_grids.h, voxel run by voxel run. */
#include "out_grids.h"

#include <string.h>

#include "vox_code.h"
#include "voxelize.h"

/* Channels of the volume's σ per voxel: 1 (grey) or 3. */
static inline int sigma_channels(const volume_t *v) { return v->sigma_channels == 1 ? 1 : 3; }

/* σs (t = 0) or σt (t = 1) of voxels [lo, hi), sigma_channels per voxel. */
static void sigma_run(const volume_t *v, int t, size_t lo, size_t hi, float *out) {
  if (v->sigma_code) {
    vox_code_run(v, t, lo, hi, out);
    return;
  }
  const size_t C = (size_t)sigma_channels(v);
  const float *a = (t ? v->sigma_t : v->sigma_s) + vox_sigma_index(v, lo, 0);
  if (!v->homogeneous) { /* the run as stored: a copy, not a lookup per value */
    memcpy(out, a, (hi - lo) * C * sizeof(float));
    return;
  }
  for (size_t i = lo; i < hi; i++, out += C) memcpy(out, a, C * sizeof(float));
}

/* Voxels per piece of a fill that needs σ beside other values. */
#define OG_PIECE 512

void og_extinction(const void *src, size_t lo, size_t hi, float *out) {
  sigma_run(((const og_source_t *)src)->vol, 1, lo, hi, out);
}

void og_scattering(const void *src, size_t lo, size_t hi, float *out) {
  sigma_run(((const og_source_t *)src)->vol, 0, lo, hi, out);
}

/* The grey density: the mean of the channels' σt, summed in order. */
void og_density(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  const volume_t *v = s->vol;
  const int C = sigma_channels(v);
  float st[3 * OG_PIECE];
  for (size_t a = lo; a < hi; a += OG_PIECE) {
    const size_t b = hi - a < OG_PIECE ? hi : a + OG_PIECE;
    if (s->sigma_t) memcpy(st, s->sigma_t + (size_t)C * a, (b - a) * (size_t)C * sizeof(float));
    else sigma_run(v, 1, a, b, st);
    for (size_t k = 0; k < b - a; k++) {
      float sum = 0.0f;
      for (int c = 0; c < 3; c++) sum += st[(size_t)C * k + (C == 1 ? 0 : c)];
      *out++ = sum / 3.0f;
    }
  }
}

/* The source term of L = ∫ T σs L̄ dt per channel, σs ⊙ L̄ (W·m⁻³·sr⁻¹): a
 * renderer that takes the volume as emissive and absorbing (Blender, Houdini)
 * reads it as emission with `extinction` as absorption and no scattering. */
void og_emission(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  if (s->vol) {
    const int C = sigma_channels(s->vol), R = s->radiance_channels == 1 ? 1 : 3;
    float ss[3 * OG_PIECE];
    for (size_t a = lo; a < hi; a += OG_PIECE) {
      const size_t b = hi - a < OG_PIECE ? hi : a + OG_PIECE;
      sigma_run(s->vol, 0, a, b, ss);
      for (size_t i = a; i < b; i++, out += 3) {
        const float *sk = ss + (size_t)C * (i - a), *r = s->radiance + (size_t)R * i;
        for (int c = 0; c < 3; c++) out[c] = sk[C == 1 ? 0 : c] * r[R == 1 ? 0 : c];
      }
    }
    return;
  }
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < 3; c++)
      *out++ = s->scattering[vox_channel_at(s->sca_channels, i, c)] *
               s->radiance[vox_channel_at(s->radiance_channels, i, c)];
}

/* Grey light in a grey medium: og_emission's one product per voxel, once. */
void og_emission_grey(const void *src, size_t lo, size_t hi, float *out) {
  const og_source_t *s = src;
  float ss[OG_PIECE];
  for (size_t a = lo; a < hi; a += OG_PIECE) {
    const size_t b = hi - a < OG_PIECE ? hi : a + OG_PIECE;
    sigma_run(s->vol, 0, a, b, ss);
    for (size_t i = a; i < b; i++) *out++ = ss[i - a] * s->radiance[i];
  }
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
  const int C = sigma_channels(s->vol);
  float ss[3 * OG_PIECE];
  for (size_t a = lo; a < hi; a += OG_PIECE) {
    const size_t b = hi - a < OG_PIECE ? hi : a + OG_PIECE;
    sigma_run(s->vol, 0, a, b, ss);
    for (size_t i = a; i < b; i++) {
      const float *sk = ss + (size_t)C * (i - a);
      const int scatters = sk[0] > 0.0f || sk[C == 1 ? 0 : 1] > 0.0f || sk[C == 1 ? 0 : 2] > 0.0f;
      *out++ = scatters ? (s->g ? s->g[i] : s->medium_g) : 0.0f;
    }
  }
}
