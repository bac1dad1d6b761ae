/* clcache.h: keeps the on-disk kernel binary cache (clhost.c writes it) within
 * a size cap, least recently used first.
 *
 * An entry is a file named <16 hex digits>.clbin in the cache directory; its
 * mtime is the time of its last use (clhost.c touches it on every hit), so the
 * oldest mtime goes first. The cap is $BAKER_CACHE_MAX_MB MiB (a decimal
 * number; default CLC_DEFAULT_MAX_MB). Nothing else in the directory is
 * counted or removed: BAKER_CACHE_DIR may point at a shared folder. */
#ifndef BAKER_CLCACHE_H
#define BAKER_CLCACHE_H

#include <stdint.h>

/* Large enough for every kernel variant of several scenes on several devices
 * (a PoCL binary is about 100 KiB, a GPU one about as much), small enough to
 * go unnoticed in ~/.cache. */
#define CLC_DEFAULT_MAX_MB 256

typedef struct {
  unsigned entries; /* .clbin files */
  uint64_t bytes;   /* their total size */
} clc_usage_t;

/* The cap in bytes from $BAKER_CACHE_MAX_MB, else the default. A value that
 * is not a non-negative number is warned about and the default is used. */
uint64_t clc_max_bytes(void);

/* Marks the entry at `path` as used now (its mtime). Failures are ignored:
 * a stale mtime only makes the entry go sooner. */
void clc_touch(const char *path);

/* Counts the entries in `dir`; 0 on success, -1 when dir cannot be read. */
int clc_usage(const char *dir, clc_usage_t *out);

/* Removes the least recently used entries until the total is at most
 * max_bytes. The entry named `keep` (a path, or NULL) is never removed: the
 * program just stored stays even when it alone passes the cap. Returns the
 * number removed. */
unsigned clc_prune(const char *dir, uint64_t max_bytes, const char *keep);

/* Removes every entry (and stale temporary files of interrupted stores).
 * Returns the number removed, or -1 when dir cannot be read. */
int clc_clear(const char *dir);

#endif
