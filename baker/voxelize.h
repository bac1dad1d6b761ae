/* voxelize.h: scene -> refractive-index and medium-coefficient grids.
 *
 * In: a validated scene (its meshes, medium, optional ior_vdb/density_vdb).
 * Out: per voxel n, sigma_s and sigma_a. Inside an object n = object IOR and
 * sigma = object coefficients; outside, the medium's. The boundary is smoothed
 * over `ior_smoothing` voxels from a signed distance d (in voxels, negative
 * inside): the blend weight is a smoothstep of d over [-w/2, +w/2]... (see
 * voxelize.c for the exact profile), so grad n exists and the n = mid-value
 * surface is the mesh surface. The inside test is a ray-parity vote along the
 * three axes, so open meshes (the Stanford bunny) still fill. */
#ifndef BAKER_VOXELIZE_H
#define BAKER_VOXELIZE_H

#include "grid.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct volume {
  grid_dims_t dims;
  float *ior;      /* n per voxel, >= 1 */
  float *sigma_s;  /* 3 per voxel (RGB, interleaved), 1/m */
  float *sigma_a;  /* 3 per voxel */
  /* What the scene contains, for kernel specialisation (DESIGN §3). */
  int has_refraction;  /* n varies somewhere */
  int homogeneous;     /* sigma_s and sigma_a the same in every voxel */
  int grey;            /* R = G = B for both coefficients everywhere */
  float n_min, n_max;
} volume_t;

/* Bytes per voxel the volume needs (for grid_check_memory). */
#define VOX_BYTES_PER_VOXEL (7 * sizeof(float))

int vox_build(const scene_t *scene, volume_t *out, bk_timings_t *timings, bk_error_t *err);
void vox_free(volume_t *v);

#ifdef __cplusplus
}
#endif
#endif
