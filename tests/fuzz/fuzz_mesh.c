/* fuzz_mesh_*: a mesh file -> mesh_io_read_here (the pre-scan, OpenMesh's
 * reader for the extension FUZZ_MESH_EXT, then our triangulation and checks,
 * in this process: not in the child mesh_io_read uses) -> mesh_check
 * (baker/mesh.c's welding and edge counts), as the voxelizer reads a scene's
 * object. One source, one binary per extension and seed corpus. */
#include "fuzz_util.h"
#include "mesh.h"

#ifndef FUZZ_MESH_EXT
#error "FUZZ_MESH_EXT must name the extension, e.g. \".obj\""
#endif

int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc, (void)argv;
  fuzz_enter_workdir();
  return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  fuzz_write_input("in" FUZZ_MESH_EXT, data, size);
  mesh_tris_t m = {0};
  bk_error_t err;
  if (mesh_io_read_here("in" FUZZ_MESH_EXT, &m, &err) != BK_OK) return 0;
  mesh_report_t r;
  if (mesh_check(&m, &r, &err) == BK_OK) {
    char line[512];
    mesh_check_summary(&r, line, sizeof line);
  }
  mesh_io_free(&m);
  return 0;
}
