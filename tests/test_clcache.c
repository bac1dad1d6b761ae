/* test_clcache.c: the kernel cache's size cap (baker/clcache.c): least
 * recently used entries go first, the entry just stored stays, files that are
 * not entries are never touched, a hit renews an entry, --clear empties it.
 * Usage: test_clcache DIR (created and emptied by the test). */
#define _POSIX_C_SOURCE 200809L
#include <fcntl.h>
#include <stdint.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "clcache.h"
#include "test_util.h"

static char dir[2048];

/* An entry of `kib` KiB last used `age` seconds ago. */
static void put(const char *name, int kib, int age) {
  char path[4200];
  snprintf(path, sizeof path, "%s/%s", dir, name);
  FILE *f = fopen(path, "wb");
  REQUIRE(f != NULL, ": cannot write %s", path);
  for (int i = 0; i < kib * 1024; i++) fputc(i & 0xff, f);
  fclose(f);
  struct timespec t[2];
  clock_gettime(CLOCK_REALTIME, &t[0]);
  t[0].tv_sec -= age;
  t[1] = t[0];
  REQUIRE(utimensat(AT_FDCWD, path, t, 0) == 0);
}

static int exists(const char *name) {
  char path[4200];
  snprintf(path, sizeof path, "%s/%s", dir, name);
  return access(path, F_OK) == 0;
}

#define E(c) c "000000000000000.clbin" /* an entry name from one hex digit */

static void test_prune(void) {
  put(E("a"), 100, 400); /* oldest */
  put(E("b"), 100, 300);
  put(E("c"), 100, 200);
  put(E("d"), 100, 100);
  put("notes.txt", 500, 1000); /* not an entry: neither counted nor removed */
  clc_usage_t u;
  REQUIRE(clc_usage(dir, &u) == 0);
  EXPECT(u.entries == 4 && u.bytes == 400 * 1024, ": %u entries, %llu bytes", u.entries,
         (unsigned long long)u.bytes);
  /* a hit renews b: now a and c are the two least recently used */
  char path[4200];
  snprintf(path, sizeof path, "%s/%s", dir, E("b"));
  clc_touch(path);
  unsigned n = clc_prune(dir, 250 * 1024, NULL);
  EXPECT(n == 2, ": removed %u, expected 2", n);
  EXPECT(!exists(E("a")) && !exists(E("c")), ": the least recently used must go");
  EXPECT(exists(E("b")) && exists(E("d")) && exists("notes.txt"));
  /* under the cap: nothing goes */
  EXPECT(clc_prune(dir, 250 * 1024, NULL) == 0);
}

static void test_keep(void) {
  put(E("e"), 300, 5000); /* the oldest, but just stored: kept past the cap */
  char keep[4200];
  snprintf(keep, sizeof keep, "%s/%s", dir, E("e"));
  clc_prune(dir, 100 * 1024, keep);
  EXPECT(exists(E("e")) && !exists(E("b")) && !exists(E("d")));
  clc_usage_t u;
  clc_usage(dir, &u);
  EXPECT(u.entries == 1);
}

static void test_clear_and_env(void) {
  put(E("f"), 1, 0);
  put("." E("f") ".tmp123", 1, 0); /* an interrupted store */
  int n = clc_clear(dir);
  EXPECT(n == 2, ": cleared %d, expected 2", n);
  EXPECT(!exists("." E("f") ".tmp123") && exists("notes.txt"));
  setenv("BAKER_CACHE_MAX_MB", "0.5", 1);
  EXPECT(clc_max_bytes() == 512 * 1024);
  setenv("BAKER_CACHE_MAX_MB", "lots", 1);
  EXPECT(clc_max_bytes() == (uint64_t)CLC_DEFAULT_MAX_MB << 20);
  unsetenv("BAKER_CACHE_MAX_MB");
  EXPECT(clc_max_bytes() == (uint64_t)CLC_DEFAULT_MAX_MB << 20);
}

int main(int argc, char **argv) {
  REQUIRE(argc == 2, ": usage: test_clcache DIR");
  snprintf(dir, sizeof dir, "%s", argv[1]);
  mkdir(dir, 0755);
  clc_clear(dir);
  test_prune();
  test_keep();
  test_clear_and_env();
  return tu_failures ? 1 : 0;
}
