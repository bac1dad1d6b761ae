/* mesh.h: placing a loaded triangle soup in the scene, and checking its topology.
 *
 * mesh_transform: p' = T + Rz(z) Ry(y) Rx(x) (S p), i.e. scale first, then the
 * rotations about X, then Y, then Z (degrees, right-handed: +90 about Z takes
 * +X to +Y), then the translation; the scene's `transform` object.
 *
 * mesh_check: counts what makes a mesh not a closed 2-manifold, on the soup
 * itself after welding vertices with identical positions (OpenMesh
 * duplicates the vertices of faces it cannot add to its half-edge structure,
 * which would otherwise turn non-manifold edges into boundary edges):
 * degenerate faces (a repeated vertex or zero area), boundary edges (used by
 * one face), boundary loops (connected components of boundary edges) and
 * non-manifold edges (used by three faces or more). Nothing here is an error:
 * the voxelizer's inside test copes with open and non-manifold meshes, and
 * mesh_check_log says so in one line per mesh. */
#ifndef BAKER_MESH_H
#define BAKER_MESH_H

#include "mesh_io.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mesh_report {
  int triangles;
  int vertices;          /* as loaded */
  int welded_vertices;   /* distinct positions */
  int degenerate_faces;  /* repeated (welded) vertex or zero area */
  int boundary_edges;    /* used by exactly one face */
  int boundary_loops;    /* connected components of the boundary edges */
  int nonmanifold_edges; /* used by more than two faces */
} mesh_report_t;

/* In place; the result may overflow to Inf for absurd scales (callers check). */
void mesh_transform(mesh_tris_t *m, const scene_object_t *obj);

/* Fills the report; fails only when scratch memory cannot be had. */
int mesh_check(const mesh_tris_t *m, mesh_report_t *out, bk_error_t *err);
int mesh_check_is_clean(const mesh_report_t *r);
/* "69451 triangles, open: 223 boundary edges in 5 loops" (no file name). */
void mesh_check_summary(const mesh_report_t *r, char *buf, size_t len);
/* The summary prefixed by `name`: bk_log at verbosity 1 for a closed manifold,
 * a warning (ending "filled by a 3-axis ray-parity vote") otherwise. */
void mesh_check_log(const char *name, const mesh_report_t *r);

#ifdef __cplusplus
}
#endif
#endif
