/* vox_crop.h: the grid a bake allocates. The scene's grid (grid.bounds,
 * grid.resolution), or, when the medium is a vacuum (scene_crops), only
 * the box around the objects: outside their reach nothing scatters, absorbs
 * or bends light, so nothing there is baked, and memory and time follow the
 * objects instead of the bounds. The crop is a grid of its own (same voxel
 * size, its corner on the scene grid's voxel corners, at a multiple of
 * GRID_CROP_ALIGN voxels): every stage works on it unchanged, and the file's
 * transform puts its voxels where they are in the world. */
#ifndef BAKER_VOX_CROP_H
#define BAKER_VOX_CROP_H

#include "base/grid.h"
#include "mesh_io.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The grid a bake of `resolution` allocates (*out) and, when *cropped, where
 * its first voxel lies in the scene's grid (off) and that grid (*whole;
 * equal to *out otherwise). box_lo/box_hi: the objects' world box
 * (vox_meshes_load's), read only when scene_crops(s). BK_ERR_INPUT for bad
 * grid keys. */
int vox_grid_for(const scene_t *s, int resolution, const float box_lo[3], const float box_hi[3],
                 grid_dims_t *whole, grid_dims_t *out, int off[3], int *cropped,
                 bk_error_t *err);

/* Grows [lo, hi] by the finite vertices of m. */
void vox_mesh_bounds(const mesh_tris_t *m, float lo[3], float hi[3]);

/* Reads object obj's mesh; a read error gets `where`, the object's place in
 * the scene, in front, so the user knows which entry names the file.
 * load_ms (when given) gains the read's time. */
int vox_read_mesh(const scene_object_t *obj, const char *where, mesh_tris_t *mesh,
                  double *load_ms, bk_error_t *err);

/* Object oi's place in the scene ("scene.json:L:C: objects[i].mesh"), or
 * "objects[i].mesh" for a scene made in code. */
#define VOX_WHERE_MAX 64
const char *vox_object_where(const scene_t *s, int oi, char buf[VOX_WHERE_MAX]);

#ifdef __cplusplus
}
#endif
#endif
