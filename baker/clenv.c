/* clenv.c: cache directories for baker and for PoCL (see clenv.h). */
#define _POSIX_C_SOURCE 200809L
#include "clenv.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/common.h"

int clh_mkdir_p(const char *path) {
  char tmp[4096];
  size_t n = strlen(path);
  if (n == 0 || n >= sizeof tmp) return -1;
  memcpy(tmp, path, n + 1);
  for (char *p = tmp + 1; *p; p++) {
    if (*p != '/') continue;
    *p = 0;
    if (mkdir(tmp, 0755) != 0 && errno != EEXIST) return -1;
    *p = '/';
  }
  if (mkdir(tmp, 0755) != 0 && errno != EEXIST) return -1;
  struct stat st;
  return (stat(tmp, &st) == 0 && S_ISDIR(st.st_mode)) ? 0 : -1;
}

int clh_cache_dir(char *out, size_t len) {
  const char *off = getenv("BAKER_NO_CACHE");
  if (off && off[0] && strcmp(off, "0") != 0) return 0;
  const char *d = getenv("BAKER_CACHE_DIR");
  const char *x = getenv("XDG_CACHE_HOME");
  const char *h = getenv("HOME");
  int w;
  if (d && d[0]) w = snprintf(out, len, "%s", d);
  else if (x && x[0]) w = snprintf(out, len, "%s/baker", x);
  else if (h && h[0]) w = snprintf(out, len, "%s/.cache/baker", h);
  else return 0;
  return w > 0 && (size_t)w < len;
}

/* `dir` exists, is a real directory of ours that nobody else can write to
 * (a shared /tmp name could be planted by another user), and we can write. */
static int private_dir_ok(const char *dir) {
  struct stat st;
  return lstat(dir, &st) == 0 && S_ISDIR(st.st_mode) && st.st_uid == geteuid() &&
         (st.st_mode & 022) == 0 && access(dir, W_OK | X_OK) == 0;
}

/* $TMPDIR/baker-pocl-UID, created 0700; else a fresh mkdtemp one. */
static int private_temp_dir(char *out, size_t len) {
  const char *t = getenv("TMPDIR");
  if (!t || !t[0]) t = "/tmp";
  if (snprintf(out, len, "%s/baker-pocl-%ld", t, (long)geteuid()) >= (int)len) return 0;
  if ((mkdir(out, 0700) == 0 || errno == EEXIST) && private_dir_ok(out)) return 1;
  if (snprintf(out, len, "%s/baker-pocl-XXXXXX", t) >= (int)len) return 0;
  return mkdtemp(out) != NULL;
}

void clh_prepare_env(void) {
  const char *set = getenv("POCL_CACHE_DIR");
  if (set && set[0]) return;
  char dir[4096], pocl[4200];
  int ok = 0;
  if (clh_cache_dir(dir, sizeof dir) && snprintf(pocl, sizeof pocl, "%s/pocl", dir) <
                                            (int)sizeof pocl)
    ok = clh_mkdir_p(pocl) == 0 && access(pocl, W_OK | X_OK) == 0;
  if (!ok) ok = private_temp_dir(pocl, sizeof pocl);
  if (!ok) {
    bk_log(2, "OpenCL: no writable directory for PoCL's cache; leaving POCL_CACHE_DIR unset");
    return;
  }
  setenv("POCL_CACHE_DIR", pocl, 0);
  bk_log(2, "OpenCL: POCL_CACHE_DIR=%s", pocl);
}
