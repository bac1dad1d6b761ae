/* view_aniso.h: the phase lobes of an anisotropic medium, per voxel, for
 * the camera rays (kernels/view_march.h), from the grids a bake with g != 0
 * writes beside `radiance` (README, "Multiple scattering and anisotropic
 * phase"). */
#ifndef BAKER_VIEW_ANISO_H
#define BAKER_VIEW_ANISO_H

#include "base/common.h"
#include "view_volume.h"

/* The grids of one file on the view's dense box (unpadded, x fastest; NULL:
 * absent) and that box's map. */
typedef struct view_aniso_grids {
  const char *path;             /* for messages and the camera's metadata */
  const float *flux, *phase_g;  /* radiance_flux (3), phase_g (1): both, or no lobes */
  const float *radiance;        /* 3 per voxel */
  const float *uncollided;      /* radiance_uncollided (1), radiance_flux_uncollided (3) */
  const float *flux_uncollided;
  const float *camera;          /* radiance_camera (1) */
  double scale;                 /* world length of a voxel */
  double world_to_index[3][4];
} view_aniso_grids_t;

/* v->aniso and v->aniso_s in the padded layout (field.h), and
 * v->anisotropic, v->camera_phase, v->camera_world; neither array when no
 * lobe differs from isotropic. VIEW_PACK_SLAB z slices at a time, giving
 * back each slab of the grids they are made from (radiance apart, which
 * the medium still reads): the lobes' 32 B per voxel take the pages of the
 * 32-40 B of those grids. A phase_g outside (-1, 1) is BK_ERR_INPUT naming
 * it. */
int view_aniso_build(const view_aniso_grids_t *in, view_volume_t *v, bk_error_t *err);

#endif
