/* fuzz_vdb: a VDB file -> vdbio_list_grids -> vdbio_read_dense of each
 * float or Vec3f grid (at most 4), the path of `baker view`. */
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "vdbio.h"

enum { FUZZ_VDB_MAX_GRIDS = 4 }; /* bounds the time per input */

/* Each read runs in a child (formats/isolate.cpp) whose alarm defaults to
 * 60 s: an input that keeps OpenVDB busy would pass libFuzzer's -timeout
 * in the waiting parent. One second each keeps the list and the four reads
 * of an input under it; a good seed reads in a fraction of that. */
#define FUZZ_VDB_READER_SECONDS "1"

int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc, (void)argv;
  fuzz_enter_workdir();
  fuzz_children_die_plainly();
  setenv("BAKER_READER_SECONDS", FUZZ_VDB_READER_SECONDS, 1);
  return 0;
}

static void read_grid(const char *name) {
  vdbio_dense_t d;
  bk_error_t err;
  memset(&d, 0, sizeof d);
  if (vdbio_read_dense("in.vdb", name, 1, &d, &err) == BK_OK) vdbio_dense_free(&d);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  fuzz_write_input("in.vdb", data, size);
  char **names = NULL, **types = NULL;
  int count = 0;
  bk_error_t err;
  if (vdbio_list_grids("in.vdb", &names, &types, &count, &err) != BK_OK) return 0;
  for (int i = 0, read = 0; i < count && read < FUZZ_VDB_MAX_GRIDS; i++) {
    if (strcmp(types[i], "float") != 0 && strcmp(types[i], "vec3s") != 0) continue;
    read_grid(names[i]);
    read++;
  }
  vdbio_free_names(names, types, count);
  return 0;
}
