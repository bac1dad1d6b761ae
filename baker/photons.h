/* photons.h: the scene's lights made ready for in-kernel photon generation
 * (pipeline stage 4).
 *
 * In: the scene's lights, the grid, the photon count and seed. Out: one
 * ph_light per light that gets photons (kernels/light_sample.h), in voxel
 * coordinates, with its range of photon indices and its power per photon.
 * The photons themselves are generated inside the march from their index.
 *
 * Sharing: light l emits P_l (W, RGB), its kind's power (lights.h:
 * directional E·A, spot I·Ω, point I·4π). Photons are shared out in
 * proportion to the sum of RGB of P_l (largest remainders, so the counts add
 * up to N exactly); each of light l's N_l photons carries P_l / N_l. A light
 * of zero power gets none. Each light's Hammersley set gets its own
 * Cranley–Patterson rotation, hashed from the seed and the light's index. */
#ifndef BAKER_PHOTONS_H
#define BAKER_PHOTONS_H

#include "base/grid.h"
#include "kernels/light_sample.h"
#include "lights.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A photon index is 32-bit on the device. */
#define PH_MAX_PHOTONS 4294967295ull

typedef struct ph_setup {
  ph_light lights[SCENE_MAX_LIGHTS]; /* those with photons, in photon-index order */
  int count;
  int scene_index[SCENE_MAX_LIGHTS]; /* which scene light each one is */
  uint64_t photons;                  /* total, = sum of the lights' counts */
  double power[3];                   /* W carried by all photons together, RGB */
  /* Every light has the same colour (RGB proportional): the march may carry
   * one channel, the sum of RGB, and colour the result by chroma at the end. */
  int one_colour;
  double chroma[3];                  /* that colour, normalised to sum 1 */
  int has_type[LIGHT_KIND_COUNT];       /* light types present, by light_type_t */
} ph_setup_t;

/* Power the light emits towards the grid, W per channel; returns the sum of
 * RGB. For a directional light also the rectangle (voxel coordinates) that
 * its photons start from. */
double ph_light_power(const scene_light_t *l, const grid_dims_t *d, double rgb[3]);

/* The kernel's light flags, "-DLIGHT_DIRECTIONAL=1 -DLIGHT_SPOT=0 ...", one
 * per row of light_kinds[] (lights.h): a specialised march keeps only the
 * generators of the kinds present. BK_ERR_RUNTIME when n is too small. */
int ph_kernel_defines(const ph_setup_t *s, char *buf, size_t n);

/* Splits `total` photons over n weights >= 0 in proportion, by largest
 * remainders (ties to the lower index); counts sum to total unless every
 * weight is 0. */
void ph_share(const double *weights, int n, uint64_t total, uint64_t *counts);

/* Prepares every light of the scene for `photons` photons (over
 * PH_MAX_PHOTONS is BK_ERR_INPUT naming photons.count). Power per photon is
 * RGB in power[0..2]. */
int ph_prepare(const scene_t *scene, const grid_dims_t *d, uint64_t photons, unsigned seed,
               ph_setup_t *out, bk_error_t *err);
/* Batch `batch` of a bake in batches (baker/batches.h): the same as
 * ph_prepare for `photons` photons (the batch's own count, its lights'
 * power per photon that of a whole bake of that count) but with rotations
 * of their own, hashed from the seed, the light and the batch; batch 0 is
 * ph_prepare's set. Independent batches are what the noise estimate needs. */
int ph_prepare_batch(const scene_t *scene, const grid_dims_t *d, uint64_t photons, unsigned seed,
                     int batch, ph_setup_t *out, bk_error_t *err);
/* Photons of batch `batch` when `photons` are split over `batches`: equal
 * shares, the first photons % batches batches one more. */
uint64_t ph_batch_photons(uint64_t photons, int batches, int batch);
/* Rewrites every light's power as the sum of its RGB in power[0] (for a
 * one-channel march; needs one_colour). */
void ph_make_grey(ph_setup_t *s);

#ifdef __cplusplus
}
#endif
#endif
