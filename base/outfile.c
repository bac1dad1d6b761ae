/* outfile.c: fsync before rename, and the litter of killed processes
 * (see outfile.h). */
#define _POSIX_C_SOURCE 200809L
#include "base/outfile.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>

/* A temporary file modified this recently is left alone even when its PID
 * looks dead: another host (NFS) or another PID namespace (containers
 * sharing a volume) may be writing it, and a writer touches its file
 * continuously. */
#define BK_STALE_TEMP_AGE_S 60

int bk_fsync_path(const char *temp_path, const char *final_path, bk_error_t *err) {
  int fd = open(temp_path, O_RDONLY);
  if (fd < 0)
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot reopen %s to flush it: %s", final_path,
                   temp_path, strerror(errno));
  int rc = fsync(fd), e = errno;
  /* close can report a deferred write error too (NFS) */
  if (close(fd) != 0 && rc == 0) {
    rc = -1;
    e = errno;
  }
  if (rc != 0)
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write %s to disk: %s", final_path, temp_path,
                   strerror(e));
  return BK_OK;
}

void bk_fsync_dir_of(const char *path) {
  char copy[4096];
  snprintf(copy, sizeof copy, "%s", path);
  int fd = open(dirname(copy), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return;
  (void)fsync(fd);
  close(fd);
}

long bk_temp_name_pid(const char *name) {
  if (name[0] != '.') return 0;
  const char *t = strstr(name + 1, ".tmp");
  const char *next;
  /* the last ".tmp" (NAME may contain one itself) */
  while (t && (next = strstr(t + 1, ".tmp")) != NULL) t = next;
  if (!t || t == name + 1) return 0;
  const char *digits = t + 4;
  if (!*digits || strspn(digits, "0123456789") != strlen(digits) || strlen(digits) > 9) return 0;
  return strtol(digits, NULL, 10);
}

/* A process that no longer exists: kill(pid, 0) fails with ESRCH. EPERM
 * means it exists under another user, which counts as alive. */
static int pid_is_dead(long pid) {
  if (pid <= 0 || pid == (long)getpid()) return 0;
  return kill((pid_t)pid, 0) != 0 && errno == ESRCH;
}

int bk_clean_stale_temps(const char *dir) {
  DIR *d = opendir(dir);
  if (!d) return 0;
  int removed = 0;
  struct dirent *e;
  while ((e = readdir(d)) != NULL) {
    long pid = bk_temp_name_pid(e->d_name);
    if (!pid_is_dead(pid)) continue;
    char path[4096];
    struct stat st;
    if (snprintf(path, sizeof path, "%s/%s", dir, e->d_name) >= (int)sizeof path) continue;
    if (lstat(path, &st) != 0 || !S_ISREG(st.st_mode) || st.st_uid != geteuid()) continue;
    if (difftime(time(NULL), st.st_mtime) < BK_STALE_TEMP_AGE_S) continue;
    if (unlink(path) == 0) {
      removed++;
      bk_log(1, "removed %s, left by process %ld which no longer runs (%lld bytes)", path, pid,
             (long long)st.st_size);
    }
  }
  closedir(d);
  return removed;
}
