/* out_grids.h: the grids a bake writes that follow from others (density,
 * emission, ior_rgb, phase_g), made a run of voxels
 * at a time while the writer builds each OpenVDB tree (vdbio_fill_fn) instead
 * of as whole arrays: at the write, the peak of a bake, they cost a few z
 * slices instead of 4-12 bytes per voxel each. Each value is computed exactly
 * as the dense arrays they replace were, so the files are the same. */
#ifndef BAKER_OUT_GRIDS_H
#define BAKER_OUT_GRIDS_H

#include <stddef.h>

#include "vdbio.h"

/* What the fills read; each uses only its own fields. */
struct volume;
typedef struct og_source {
  /* extinction, scattering, density, phase_g and emission's σs: the
   * volume's σ however stored (voxelize.h vol_sigma_s, vol_sigma_t) */
  const struct volume *vol;
  const float *sigma_t;           /* density: σt decoded, sigma_channels per voxel; NULL: vol's */
  const float *scattering;        /* emission without vol: sca_channels per voxel */
  int sca_channels;
  const float *radiance;          /* emission: radiance_channels per voxel */
  int radiance_channels;          /* 3, or 1: grey light (march.h pm_radiance_channels) */
  const float *ior, *ior_rb;      /* ior_rgb: n; n of R then B (2 * voxels) */
  size_t voxels;
  const float *g;                 /* phase_g: g per voxel, or NULL: medium_g */
  float medium_g;
} og_source_t;

/* A grid's values: a dense array, or a fill over an og_source_t; `grey`:
 * a Vec3 grid given as one float per voxel (vdbio_grid_t.grey). */
typedef struct og_values {
  const float *data;
  vdbio_fill_fn fill;
  const void *ctx;
  int grey;
} og_values_t;

static inline og_values_t og_dense(const float *data) {
  og_values_t v = {data, NULL, NULL, 0};
  return v;
}
static inline og_values_t og_made(vdbio_fill_fn fill, const og_source_t *src) {
  og_values_t v = {NULL, fill, src, 0};
  return v;
}
static inline og_values_t og_grey(og_values_t v) {
  v.grey = 1;
  return v;
}
static inline int og_present(og_values_t v) { return v.data || v.fill; }

void og_density(const void *src, size_t lo, size_t hi, float *out);  /* mean of σt */
/* σt and σs as the extinction and scattering grids, the volume's
 * sigma_channels floats per voxel (decoded, or repeated for a homogeneous
 * volume that holds one voxel) */
void og_extinction(const void *src, size_t lo, size_t hi, float *out);
void og_scattering(const void *src, size_t lo, size_t hi, float *out);
void og_emission(const void *src, size_t lo, size_t hi, float *out); /* scattering ⊙ radiance */
/* grey light in a grey medium: σs·L̄ once per voxel, the grey Vec3 grid
 * `emission` (og_grey) */
void og_emission_grey(const void *src, size_t lo, size_t hi, float *out);
void og_ior_rgb(const void *src, size_t lo, size_t hi, float *out);  /* n per channel */
void og_phase_g(const void *src, size_t lo, size_t hi, float *out);  /* g where σs > 0 */

#endif
