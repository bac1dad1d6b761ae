// mesh_prescan.h: the text pre-scan of mesh files, before OpenMesh reads
// them (internal to formats/mesh_io.cpp; C++).
#ifndef BAKER_MESH_PRESCAN_H
#define BAKER_MESH_PRESCAN_H

#include <string>

#include "base/common.h"

enum mesh_format { FMT_OBJ, FMT_PLY, FMT_OFF, FMT_STL, FMT_UNKNOWN };

// Reads path and checks its text for what OpenMesh mishandles (non-finite
// coordinates, headers it loops on, counts and indices it allocates by),
// BK_ERR_INPUT naming the line. Missing or unreadable files are named here,
// before OpenMesh tries; an OBJ's "v" lines are counted into
// obj_vertex_lines so that vertices OpenMesh drops can be noticed.
int mesh_prescan_file(const char *path, mesh_format fmt, int *obj_vertex_lines, bk_error_t *err);

// "(nan, 0, 1)": coordinates as they will be stored (as floats), for messages.
std::string mesh_coords_text(const double v[3]);

#endif
