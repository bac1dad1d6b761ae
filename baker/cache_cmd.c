/* cache_cmd.c: `baker cache [--clear]`: where the kernel binary cache is, how
 * many entries and bytes it holds against its cap, and emptying it. */
#include <stdio.h>
#include <string.h>

#include "base/common.h"
#include "cache_cmd.h"
#include "clcache.h"
#include "clhost.h"

static void cache_usage(FILE *out) {
  fprintf(out,
          "usage: baker cache [--clear]\n"
          "\n"
          "Prints the kernel binary cache's directory, entry count, size and cap.\n"
          "  --clear   remove every cached kernel binary (nothing else in the directory)\n"
          "\n"
          "The directory is $BAKER_CACHE_DIR, else $XDG_CACHE_HOME/baker, else\n"
          "~/.cache/baker; BAKER_NO_CACHE=1 turns the cache off. The cap is\n"
          "$BAKER_CACHE_MAX_MB MiB (default %d); least recently used binaries go first.\n",
          CLC_DEFAULT_MAX_MB);
}

static int cache_print(const char *dir) {
  clc_usage_t u;
  double cap = clc_max_bytes() / (1024.0 * 1024.0);
  if (clc_usage(dir, &u) != 0) { /* not created yet: an empty cache */
    u.entries = 0;
    u.bytes = 0;
  }
  printf("kernel cache: %s\n", dir);
  printf("entries: %u\n", u.entries);
  printf("size: %.2f MiB (%llu bytes) of %.0f MiB cap\n", u.bytes / (1024.0 * 1024.0),
         (unsigned long long)u.bytes, cap);
  return BK_OK;
}

int cache_main(int argc, char **argv) {
  int clear = 0;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--clear")) {
      clear = 1;
    } else if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      cache_usage(stdout);
      return BK_OK;
    } else if (!strcmp(argv[i], "--version")) {
      printf("baker %s\n", BAKER_VERSION);
      return BK_OK;
    } else {
      fprintf(stderr, "baker cache: unknown option '%s'\n\n", argv[i]);
      cache_usage(stderr);
      return BK_ERR_INPUT;
    }
  }
  char dir[4096];
  if (!clh_cache_dir(dir, sizeof dir)) {
    printf("kernel cache: off (BAKER_NO_CACHE is set, or no cache directory)\n");
    return BK_OK;
  }
  if (!clear) return cache_print(dir);
  int n = clc_clear(dir);
  if (n < 0) {
    fprintf(stderr, "baker cache: cannot read %s\n", dir);
    return BK_ERR_RUNTIME;
  }
  printf("kernel cache: %s: removed %d entr%s\n", dir, n, n == 1 ? "y" : "ies");
  return BK_OK;
}
