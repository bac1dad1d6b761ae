#define _POSIX_C_SOURCE 200809L
#include "fuzz_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char workdir[256];

static void remove_workdir(void) {
  /* only the files the targets write; the directory then goes if empty */
  static const char *const names[] = {"scene.json", "in.obj", "in.ply", "in.stl", "in.off",
                                      "in.vdb", NULL};
  if (!workdir[0] || chdir(workdir) != 0) return;
  for (int i = 0; names[i]; i++) unlink(names[i]);
  if (chdir("/") == 0) rmdir(workdir);
}

void fuzz_enter_workdir(void) {
  if (workdir[0]) return;
  const char *tmp = getenv("TMPDIR");
  snprintf(workdir, sizeof workdir, "%s/baker-fuzz-XXXXXX", tmp && *tmp ? tmp : "/tmp");
  if (!mkdtemp(workdir) || chdir(workdir) != 0) {
    perror("fuzz: cannot make a working directory");
    abort();
  }
  atexit(remove_workdir);
}

void fuzz_write_input(const char *name, const uint8_t *data, size_t size) {
  FILE *f = fopen(name, "wb");
  if (!f || (size && fwrite(data, 1, size, f) != size) || fclose(f) != 0) {
    perror("fuzz: cannot write the input");
    abort();
  }
}
