/* view_fields.c: the camera rays' fields and pyramids (see view_fields.h). */
#include "view_fields.h"

#include <stdlib.h>

#include "field.h"
#include "octree.h"

/* n, its constant blocks and the field's constant cells, exactly as the
 * photon march sees them. */
static int build_refraction(view_volume_t *v, bk_error_t *err) {
  const size_t count = (size_t)v->nx * v->ny * v->nz;
  const oct_source_t n[3] = {{v->ior, 1, 1, 0}, {v->ior_rb, 1, 1, 0},
                             {v->ior_rb ? v->ior_rb + count : NULL, 1, 1, 0}};
  v->ng = v->ior_rb ? fld_build_rgb(v->nx, v->ny, v->nz, v->voxel_size, v->ior, v->ior_rb, err)
                    : fld_build(v->nx, v->ny, v->nz, v->voxel_size, v->ior, err);
  if (!v->ng) return BK_ERR_RUNTIME;
  const int nsrc = v->ior_rb ? 3 : 1;
  int rc = oct_build_fields(v->nx, v->ny, v->nz, n, nsrc, OCT_HALO, &v->npyr, err);
  return rc ? rc : oct_add_cells(v->nx, v->ny, v->nz, n, nsrc, &v->npyr, err);
}

int view_fields_build(view_volume_t *v, bk_error_t *err) {
  int rc;
  if (v->refraction && (rc = build_refraction(v, err))) return rc;
  /* S and σt constant over a block and the voxel around it that trilinear
   * sampling reads: S, σt and the phase lobes packed padded already
   * (view_volume.c) */
  const int mf = v->medium_floats;
  oct_source_t medium[4] = {{v->medium, mf, mf, 1}, {v->sigma_t4, 4, 3, 1}, {v->aniso, 4, 4, 1},
                            {v->aniso_s, 4, v->camera_phase ? 4 : 3, 1}};
  int nsrc = 1;
  if (v->sigma_t4) medium[nsrc++] = medium[1];
  if (v->aniso) { /* the phase lobes: part of the source */
    medium[nsrc++] = medium[2];
    medium[nsrc++] = medium[3];
  }
  return oct_build_fields(v->nx, v->ny, v->nz, medium, nsrc, 1, &v->mpyr, err);
}
