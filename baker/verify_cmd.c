/* verify_cmd.c: the `baker verify FILE...` command: recomputes the checksum
 * of every grid (formats/vdbio.h gives the rule) and prints one line per
 * grid. Exit 0 when every grid of every file is intact, 1 when any grid is
 * corrupt, 2 when a file cannot be read at all (or on usage errors). */
#include "verify.h"

#include <stdlib.h>
#include <string.h>

#include "base/common.h"
#include "vdbio.h"

void verify_usage(FILE *out) {
  fprintf(out,
          "usage: baker verify FILE.vdb [FILE.vdb ...]\n"
          "\n"
          "Checks each grid's values against the checksum baker recorded in the file's\n"
          "metadata (checksum_<grid>) and prints one line per grid:\n"
          "  FILE: GRID OK | CORRUPT (why) | UNCHECKED (no checksum recorded)\n"
          "\n"
          "Exit status: 0 all grids intact, 1 a grid is corrupt, 2 a file cannot be\n"
          "read (missing, not a VDB file, truncated) or bad usage.\n");
}

/* One file: its lines; returns the exit status it alone would give. */
static int verify_file(const char *path) {
  vdbio_verify_grid_t *grids = NULL;
  int count = 0;
  bk_error_t err;
  int rc = vdbio_verify(path, &grids, &count, &err);
  if (rc) {
    fprintf(stderr, "baker verify: %s\n", err.msg);
    return BK_ERR_INPUT;
  }
  static const char *const words[] = {"OK", "CORRUPT", "UNCHECKED"};
  int status = BK_OK;
  for (int i = 0; i < count; i++) {
    const vdbio_verify_grid_t *g = &grids[i];
    if (g->status == VDBIO_VERIFY_OK)
      printf("%s: %s OK\n", path, g->name);
    else
      printf("%s: %s %s (%s)\n", path, g->name, words[g->status], g->detail);
    if (g->status == VDBIO_VERIFY_CORRUPT) status = BK_ERR_RUNTIME;
  }
  if (count == 0) printf("%s: no grids\n", path);
  free(grids);
  return status;
}

int verify_main(int argc, char **argv) {
  int files = 0, worst = BK_OK;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      verify_usage(stdout);
      return BK_OK;
    }
    if (!strcmp(a, "--version")) {
      printf("baker %s\n", BAKER_VERSION);
      return BK_OK;
    }
    if (a[0] == '-' && a[1] && strcmp(a, "--") != 0) {
      fprintf(stderr, "baker verify: unknown option '%s'\n\n", a);
      verify_usage(stderr);
      return BK_ERR_INPUT;
    }
  }
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--")) continue;
    int rc = verify_file(argv[i]);
    files++;
    /* unreadable (2) outranks corrupt (1), which outranks intact (0) */
    if (rc > worst) worst = rc;
  }
  if (files == 0) {
    verify_usage(stderr);
    return BK_ERR_INPUT;
  }
  fflush(stdout);
  return worst;
}
