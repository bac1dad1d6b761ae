// mesh_prescan.h: the pre-scan of mesh files, text and binary, before
// OpenMesh reads them (internal to formats/mesh_io.cpp; C++).
#ifndef BAKER_MESH_PRESCAN_H
#define BAKER_MESH_PRESCAN_H

#include <string>
#include <vector>

#include "base/common.h"

enum mesh_format { FMT_OBJ, FMT_PLY, FMT_OFF, FMT_STL, FMT_UNKNOWN };

// Reads path and checks its text for what OpenMesh mishandles (non-finite
// coordinates, headers it loops on, counts and indices it allocates by),
// BK_ERR_INPUT naming the line. Missing or unreadable files are named here,
// before OpenMesh tries; an OBJ's "v" lines are counted into
// obj_vertex_lines so that vertices OpenMesh drops can be noticed.
int mesh_prescan_file(const char *path, mesh_format fmt, int *obj_vertex_lines, bk_error_t *err);

// A PLY header's element as the pre-scans read it. For each property: its
// name, whether it is a list, and its layout in a binary body: a list's
// count (bytes, signed), then each value (bytes, signed, integer or not).
struct ply_prop {
  std::string name;
  bool list;
  int count_bytes;
  bool count_signed;
  int bytes;
  bool is_signed, integer;
};
struct ply_element {
  std::string name;
  long count;
  std::vector<ply_prop> props;
};

// The binary bodies (mesh_prescan_binary.cpp), walked as OpenMesh 9 reads
// them: false with *msg ("byte N: ...", to follow "path:") on a count that
// does not fit in the bytes after it, a face index that names no vertex,
// a body that ends early, or (PLY) a layout OpenMesh would misread. A PLY
// body starts at file offset `at`; an OFF's text is the whole file, its
// header's letters saying what each vertex holds.
bool prescan_ply_binary(const char *body, size_t left, size_t at,
                        const std::vector<ply_element> &elems, bool big_endian, std::string *msg);
bool prescan_off_binary(const char *text, size_t len, bool normals, bool colours, bool texcoords,
                        std::string *msg);

// "(nan, 0, 1)": coordinates as they will be stored (as floats), for messages.
std::string mesh_coords_text(const double v[3]);

#endif
