/* vox_crop.c: the scene's grid, or its crop around the objects in a vacuum
 * (vox_crop.h). */
#include "vox_crop.h"

#include <math.h>

#include "mesh_io.h"
#include "voxelize.h"

const char *vox_object_where(const scene_t *s, int oi, char buf[VOX_WHERE_MAX]) {
  if (s->objects[oi].where[0]) return s->objects[oi].where;
  snprintf(buf, VOX_WHERE_MAX, "objects[%d].mesh", oi);
  return buf;
}

int vox_read_mesh(const scene_object_t *obj, const char *where, mesh_tris_t *mesh,
                  double *load_ms, bk_error_t *err) {
  double t0 = bk_now_ms();
  int rc = mesh_io_read(obj->mesh, mesh, err);
  if (rc) {
    char inner[sizeof err->msg];
    snprintf(inner, sizeof inner, "%s", err->msg);
    return bk_fail(err, rc, "%s: %s", where, inner);
  }
  if (load_ms) *load_ms += bk_now_ms() - t0;
  return BK_OK;
}

void vox_mesh_bounds(const mesh_tris_t *m, float lo[3], float hi[3]) {
  for (size_t i = 0; i < 3 * (size_t)m->vertex_count; i++) {
    const float p = m->positions[i];
    const int a = (int)(i % 3);
    if (!isfinite(p)) continue; /* vox_build names the vertex */
    lo[a] = fminf(lo[a], p);
    hi[a] = fmaxf(hi[a], p);
  }
}

int vox_grid_for(const scene_t *s, int resolution, const float box_lo[3], const float box_hi[3],
                 grid_dims_t *whole, grid_dims_t *out, int off[3], int *cropped,
                 bk_error_t *err) {
  const char *where = s->where_resolution[0] ? s->where_resolution : s->path;
  int rc = grid_dims_from_bounds(s->bounds_min, s->bounds_max, resolution, where, whole, err);
  *out = *whole;
  off[0] = off[1] = off[2] = 0;
  *cropped = 0;
  if (rc || !scene_crops(s)) return rc;
  /* the voxels each object may change (voxelize.c's region): its box in
   * index space, voxel centres at integers, grown by the blend's band */
  const float band = 0.5f * s->ior_smoothing + VOX_BAND_MARGIN;
  float lo[3], hi[3];
  for (int a = 0; a < 3; a++) {
    const double vs = whole->voxel_size;
    lo[a] = (float)(((double)box_lo[a] - whole->origin[a]) / vs - 0.5 - band);
    hi[a] = (float)(((double)box_hi[a] - whole->origin[a]) / vs - 0.5 + band);
  }
  *cropped = grid_crop(whole, lo, hi, out, off);
  return BK_OK;
}
