/* clcache.c: size cap and least-recently-used pruning of the kernel binary
 * cache; see clcache.h. */
#define _POSIX_C_SOURCE 200809L
#include "clcache.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "base/common.h"

/* An entry's file name: 16 hex digits and ".clbin" (clhost.c's naming). */
static int is_entry(const char *name) {
  if (strlen(name) != 16 + 6 || strcmp(name + 16, ".clbin") != 0) return 0;
  for (int i = 0; i < 16; i++)
    if (!strchr("0123456789abcdef", name[i])) return 0;
  return 1;
}

/* A temporary file of an interrupted store: ".<entry>.tmp<pid>". */
static int is_stale_temp(const char *name) {
  const char *t = strstr(name, ".clbin.tmp");
  return name[0] == '.' && t != NULL && t - name == 17;
}

uint64_t clc_max_bytes(void) {
  const char *s = getenv("BAKER_CACHE_MAX_MB");
  double mb = CLC_DEFAULT_MAX_MB;
  if (s && s[0]) {
    char *end = NULL;
    double v = strtod(s, &end);
    if (end && *end == 0 && isfinite(v) && v >= 0)
      mb = v;
    else
      bk_warn("kernel cache: BAKER_CACHE_MAX_MB=%s is not a size in MiB; using %d", s,
              CLC_DEFAULT_MAX_MB);
  }
  return (uint64_t)(mb * 1024.0 * 1024.0);
}

void clc_touch(const char *path) {
  (void)utimensat(AT_FDCWD, path, NULL, 0); /* NULL: both times become now */
}

typedef struct {
  char name[24];
  uint64_t bytes;
  struct timespec used;
} clc_entry_t;

/* The entries of dir in a growing array; NULL with *n = 0 when there are
 * none, and -1 from *n when dir cannot be read. */
static clc_entry_t *list_entries(const char *dir, int *n) {
  DIR *d = opendir(dir);
  *n = d ? 0 : -1;
  if (!d) return NULL;
  clc_entry_t *v = NULL;
  int cap = 0;
  struct dirent *de;
  char path[4200];
  while ((de = readdir(d)) != NULL) {
    struct stat st;
    if (!is_entry(de->d_name)) continue;
    snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) continue;
    if (*n == cap) {
      cap = cap ? 2 * cap : 64;
      clc_entry_t *g = realloc(v, (size_t)cap * sizeof *v);
      if (!g) break;
      v = g;
    }
    memcpy(v[*n].name, de->d_name, 16 + 6 + 1); /* is_entry: 22 characters and the NUL */
    v[*n].bytes = (uint64_t)st.st_size;
    v[*n].used = st.st_mtim;
    (*n)++;
  }
  closedir(d);
  return v;
}

int clc_usage(const char *dir, clc_usage_t *out) {
  int n;
  clc_entry_t *v = list_entries(dir, &n);
  out->entries = 0;
  out->bytes = 0;
  if (n < 0) return -1;
  for (int i = 0; i < n; i++) out->bytes += v[i].bytes;
  out->entries = (unsigned)n;
  free(v);
  return 0;
}

/* Oldest use first; ties by name, so pruning is deterministic. */
static int by_use(const void *a, const void *b) {
  const clc_entry_t *x = a, *y = b;
  if (x->used.tv_sec != y->used.tv_sec) return x->used.tv_sec < y->used.tv_sec ? -1 : 1;
  if (x->used.tv_nsec != y->used.tv_nsec) return x->used.tv_nsec < y->used.tv_nsec ? -1 : 1;
  return strcmp(x->name, y->name);
}

unsigned clc_prune(const char *dir, uint64_t max_bytes, const char *keep) {
  int n;
  clc_entry_t *v = list_entries(dir, &n);
  uint64_t total = 0;
  unsigned removed = 0;
  for (int i = 0; i < n; i++) total += v[i].bytes;
  if (total > max_bytes) qsort(v, (size_t)n, sizeof *v, by_use);
  const char *keep_name = keep ? strrchr(keep, '/') : NULL;
  keep_name = keep_name ? keep_name + 1 : keep;
  char path[4200];
  for (int i = 0; i < n && total > max_bytes; i++) {
    if (keep_name && strcmp(v[i].name, keep_name) == 0) continue;
    snprintf(path, sizeof path, "%s/%s", dir, v[i].name);
    if (remove(path) != 0) continue;
    total -= v[i].bytes;
    removed++;
    bk_log(2, "kernel cache: removed %s (least recently used; cap %.1f MiB)", path,
           max_bytes / (1024.0 * 1024.0));
  }
  free(v);
  return removed;
}

int clc_clear(const char *dir) {
  DIR *d = opendir(dir);
  if (!d) return errno == ENOENT ? 0 : -1;
  int removed = 0;
  struct dirent *de;
  char path[4200];
  while ((de = readdir(d)) != NULL) {
    int entry = is_entry(de->d_name);
    if (!entry && !is_stale_temp(de->d_name)) continue;
    snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
    if (remove(path) == 0 && entry) removed++;
  }
  closedir(d);
  return removed;
}
