#define _POSIX_C_SOURCE 200809L
#include "fuzz_util.h"

#include <pthread.h>
#include <signal.h>
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

/* weak: the replay programs are built without a sanitizer runtime */
extern void __sanitizer_set_death_callback(void (*callback)(void)) __attribute__((weak));

/* A reader's child (formats/isolate.cpp) inherits libFuzzer's crash
 * handlers through fork, and they wrote each child's expected failure (an
 * OpenVDB assert, a sanitizer report inside OpenVDB) to the artifact
 * directory as if it were a finding. The parent reports those failures
 * itself; the child now just dies, the sanitizer's report still printed. */

static void child_without_fuzzer_handlers(void) {
  static const int faults[] = {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL};
  if (__sanitizer_set_death_callback) __sanitizer_set_death_callback(NULL);
  for (size_t i = 0; i < sizeof faults / sizeof faults[0]; i++) signal(faults[i], SIG_DFL);
}

void fuzz_children_die_plainly(void) {
  if (pthread_atfork(NULL, NULL, child_without_fuzzer_handlers) != 0) {
    perror("fuzz: pthread_atfork");
    abort();
  }
}
