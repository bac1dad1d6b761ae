/* enospc_shim.c: an LD_PRELOAD library that makes the disk "full" for the
 * reliability tests (tests/reliability.sh).
 *
 *   BK_SHIM_MATCH=".tmp"          only files whose path contains this
 *   BK_SHIM_ENOSPC_AFTER=N        write/writev/pwrite/fwrite to them fail
 *                                 with ENOSPC once N bytes have gone to them
 *   BK_SHIM_FSYNC_ERRNO=28        fsync/fdatasync of them fail with that errno
 *                                 (a full disk seen only at write-back)
 *   BK_SHIM_NO_MEMFD=1            memfd_create fails with ENOSYS (a kernel or
 *                                 sandbox without it), BK_SHIM_MATCH aside
 *
 * OpenVDB and OpenEXR write through std::ofstream / our fd streams, which
 * reach write(2) through the PLT, so interposing write catches them; glibc's
 * stdio calls its internal write, so fwrite (libpng) is interposed too. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

static long long written;

static int matches(int fd) {
  const char *want = getenv("BK_SHIM_MATCH");
  if (!want || !*want) return 0;
  char link[64], path[4096];
  snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  ssize_t n = readlink(link, path, sizeof path - 1);
  if (n <= 0) return 0;
  path[n] = 0;
  return strstr(path, want) != NULL;
}

/* How many of `want` bytes may still go to fd (all when it does not match). */
static size_t allowance(int fd, size_t want) {
  const char *lim = getenv("BK_SHIM_ENOSPC_AFTER");
  if (!lim || !matches(fd)) return want;
  long long left = atoll(lim) - __atomic_load_n(&written, __ATOMIC_RELAXED);
  if (left <= 0) return 0;
  return (size_t)left < want ? (size_t)left : want;
}

/* Only the matching files' bytes count: the process may write others (the
 * view writes its EXR and PNG side by side) in any order. */
static void count_written(int fd, ssize_t w) {
  if (w > 0 && matches(fd)) __atomic_add_fetch(&written, (long long)w, __ATOMIC_RELAXED);
}

#define REAL(name) ((__typeof__(&name))dlsym(RTLD_NEXT, #name))

ssize_t write(int fd, const void *buf, size_t n) {
  size_t ok = allowance(fd, n);
  if (n > 0 && ok == 0) {
    errno = ENOSPC;
    return -1;
  }
  ssize_t w = REAL(write)(fd, buf, ok);
  count_written(fd, w);
  return w;
}

ssize_t pwrite(int fd, const void *buf, size_t n, off_t off) {
  size_t ok = allowance(fd, n);
  if (n > 0 && ok == 0) {
    errno = ENOSPC;
    return -1;
  }
  ssize_t w = REAL(pwrite)(fd, buf, ok, off);
  count_written(fd, w);
  return w;
}

ssize_t writev(int fd, const struct iovec *iov, int cnt) {
  size_t total = 0;
  for (int i = 0; i < cnt; i++) total += iov[i].iov_len;
  /* a short writev would be legal; failing it whole keeps the shim simple */
  if (total > 0 && allowance(fd, total) < total) {
    errno = ENOSPC;
    return -1;
  }
  ssize_t w = REAL(writev)(fd, iov, cnt);
  count_written(fd, w);
  return w;
}

size_t fwrite(const void *buf, size_t size, size_t count, FILE *f) {
  size_t n = size * count;
  if (n > 0 && allowance(fileno(f), n) < n) {
    errno = ENOSPC;
    return 0;
  }
  size_t w = REAL(fwrite)(buf, size, count, f);
  count_written(fileno(f), (ssize_t)(w * size));
  return w;
}

static int fsync_errno(int fd) {
  const char *e = getenv("BK_SHIM_FSYNC_ERRNO");
  return e && matches(fd) ? atoi(e) : 0;
}

int fsync(int fd) {
  int e = fsync_errno(fd);
  if (e) {
    errno = e;
    return -1;
  }
  return REAL(fsync)(fd);
}

int fdatasync(int fd) {
  int e = fsync_errno(fd);
  if (e) {
    errno = e;
    return -1;
  }
  return REAL(fdatasync)(fd);
}

int memfd_create(const char *name, unsigned int flags) {
  if (getenv("BK_SHIM_NO_MEMFD")) {
    errno = ENOSYS;
    return -1;
  }
  return REAL(memfd_create)(name, flags);
}
