/* mesh_io.h: triangle meshes read with OpenMesh (OBJ, PLY, OFF, STL).
 *
 * In: a mesh file. Out: a triangle soup with shared vertex indices (polygons
 * fan-triangulated). Refused with BK_ERR_INPUT and a message naming the file:
 * unreadable or unknown format, no triangles, NaN or Inf coordinates. Topology
 * problems (open boundaries, non-manifold edges, degenerate faces) are not
 * refused here: mesh_check() in baker/mesh.h counts them on the soup itself,
 * because OpenMesh's read_mesh succeeds on non-manifold input. */
#ifndef BAKER_MESH_IO_H
#define BAKER_MESH_IO_H

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mesh_tris {
  float *positions;   /* 3 floats per vertex */
  int vertex_count;
  int *indices;       /* 3 per triangle */
  int triangle_count;
} mesh_tris_t;

/* Reads path in a child process under memory and time limits (isolate.h):
 * what OpenMesh does on a file the pre-scan let through (an assert, a loop,
 * memory without end) ends with the child, and the file is refused. */
int mesh_io_read(const char *path, mesh_tris_t *out, bk_error_t *err);
/* The same read in this process: for the fuzz targets, which must see what
 * the reader does. BAKER_MESH_NO_PRESCAN=1 in the environment skips the
 * pre-scan (the tests use it to show that the child bounds OpenMesh). */
int mesh_io_read_here(const char *path, mesh_tris_t *out, bk_error_t *err);
/* Writes an OBJ (tests use it to make icospheres and broken meshes). */
int mesh_io_write_obj(const char *path, const mesh_tris_t *m, bk_error_t *err);
void mesh_io_free(mesh_tris_t *m);

#ifdef __cplusplus
}
#endif
#endif
