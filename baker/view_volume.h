/* view_volume.h: every grid of a VDB file on one dense box, as the view
 * kernel reads them.
 *
 * In: a VDB with a `radiance` Vec3f grid and optionally `ior`, `extinction`
 * (else `density`), `scattering` (view.h says how absent grids default),
 * `radiance_flux` with `phase_g` and `radiance_uncollided` (the anisotropic
 * phase's lobes) and `radiance_camera` (the phase towards one camera), any
 * similarity transform. Out: the union of the grids' active boxes in the
 * radiance grid's index space, with the index <-> world transforms, and the
 * packed fields: S = σs L̄ with σt, RGB σt, n, {∇n, n}, the flat distances
 * and the brick flags (view_fields.h), σ per voxel length. */
#ifndef BAKER_VIEW_VOLUME_H
#define BAKER_VIEW_VOLUME_H

#include <stddef.h>
#include <stdint.h>

#include "base/common.h"
#include "octree.h"
#include "view_arrays.h"

#define VIEW_N_EPS 1e-6f         /* n differences below this bend nothing */

typedef struct view_volume {
  int nx, ny, nz;
  double i2w[3][4], w2i[3][4]; /* index (cell centre) <-> world */
  double voxel_size;           /* world length of one index step */
  int empty;                   /* no grid has active voxels: the image is the background */
  float *medium;               /* 4 per voxel: S = σs L̄ (RGB), σt when grey; per voxel length;
                                  padded (field.h), packed so by the read */
  int medium_floats;           /* 4, or 2 under grey light with grey σ: {S, σt} */
  float *sigma_t4;             /* 4 per voxel: σt (RGB) when RGB and not homogeneous; padded */
  float *aniso, *aniso_s;      /* 4 per voxel: the phase lobes (view_march.h), index space;
                                  aniso_s's 4th: the camera's factor (camera_phase); padded */
  int anisotropic;             /* some lobe is not isotropic (radiance_flux and phase_g) */
  int camera_phase;            /* `radiance_camera`: its factor C / Y(L̄) per voxel in aniso_s */
  double camera_world[3];      /* ... for a camera at this point (its metadata) */
  int sigma_ch;                /* 1: grey coefficients, 3: RGB */
  int homogeneous;             /* RGB σt constant: st_const */
  float st_const[3];
  float *ior;                  /* NULL: n = 1 */
  float *ior_rb;               /* dispersion (an `ior_rgb` grid whose channels differ): n of R,
                                * then of B, a plane each (ior is G's); ng then holds 3 fields */
  float *ng;                   /* refraction only: the padded {∇n, n} field (baker/field.h) */
  int refraction;
  float n_min, n_max;
  oct_pyramid_t npyr;          /* refraction only: constant blocks of n */
  oct_pyramid_t mpyr;          /* constant blocks of the medium (view_fields.h) */
  char desc[512];              /* what was read, for -v */
} view_volume_t;

/* What the load asks of the command that renders: meanwhile(ctx) (NULL:
 * nothing) runs while the grids are decoded in their reader processes
 * (vdbio_read_dense_verified_all): the view starts OpenCL there.
 * max_buffer(ctx, &device) opens the device at once and gives the largest
 * buffer it allows (0: no limit, the host, or no device: the render says
 * why); asked before the read when a file's least buffer is over
 * BUDGET_DEVICE_CHECK_BYTES. */
typedef struct view_load_hooks {
  void (*meanwhile)(void *ctx);
  uint64_t (*max_buffer)(void *ctx, const char **device);
  void *ctx;
} view_load_hooks_t;

/* Reads path into v (zeroed first); on failure v is freed. A file whose
 * estimated peak (view_budget.h) exceeds the memory available, or
 * max_bytes when > 0, is refused (BK_ERR_INPUT): before any grid is read
 * when the file records its box, else after; so is a large one whose least
 * buffer the device cannot hold (before the read only). */
int view_volume_load(const char *path, view_volume_t *v, uint64_t max_bytes,
                     const view_load_hooks_t *hooks, bk_error_t *err);
void view_volume_free(view_volume_t *v);
/* World bounding box of the volume's cells. */
void view_volume_world_box(const view_volume_t *v, double bmin[3], double bmax[3]);

#endif
