/* isolate.cpp: readers of untrusted files run in a child process (fork)
 * with memory and time limits, and hand their result back through a pipe
 * (isolate.h). Used by every VDB read (vdbio_isolate.cpp, which explains
 * why a child) and by the mesh reader (mesh_io.cpp).
 *
 * Limits. Memory: what this process can still hold (MemAvailable, at least
 * ISO_MIN_MEMORY) plus ISO_AS_SLACK for address space that is reserved but
 * not used (the libraries' mappings, thread stacks, malloc arenas); never
 * above the limit the parent already runs under. A job that parses first
 * (a VDB file) starts under a tighter parse limit until it calls
 * iso_lift_parse_limit: the address space at the fork plus ISO_AS_SLACK,
 * ISO_PARSE_MEMORY and the file's size. A corrupt metadata string length
 * (2 GB in an 165 KB file) once made OpenVDB fill 13.5 GB before failing;
 * under the parse limit it fails at once. Not set under AddressSanitizer,
 * whose shadow memory needs terabytes of address space. Time:
 * the job's base (60 s for a VDB file: OpenVDB's initialize and TBB; 10 s
 * for a mesh) plus one second per ISO_BYTES_PER_SECOND of file (zip decodes
 * faster than 10 MB/s of input on any machine we know), at most
 * $BAKER_READER_SECONDS when that is set (a farm that wants a corrupt file
 * to fail sooner; the fuzz targets, under libFuzzer's own timeout). */
#include "isolate.h"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#if defined(__SANITIZE_ADDRESS__)
#define ISO_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ISO_ASAN 1
#endif
#endif

#define ISO_MIN_MEMORY (1ull << 30)    /* a small good file must read on a loaded machine */
#define ISO_AS_SLACK (1ull << 30)      /* reserved, unused address space (see above) */
#define ISO_BYTES_PER_SECOND (10u << 20)
#define ISO_PARSE_MEMORY (256ull << 20) /* metadata, descriptors, transforms */
#define ISO_PIPE_BYTES (1 << 20)        /* Linux's default pipe-max-size */
#define ISO_MAX_CAP 86400u              /* BAKER_READER_SECONDS: a day at most */

/* --- the pipe ------------------------------------------------------------------ */

bool iso_write(int fd, const void *p, size_t n) {
  const char *c = static_cast<const char *>(p);
  while (n) {
    ssize_t w = write(fd, c, n);
    if (w < 0 && errno == EINTR)
      continue;
    if (w <= 0)
      return false;
    c += w;
    n -= (size_t)w;
  }
  return true;
}

bool iso_read(int fd, void *p, size_t n) {
  char *c = static_cast<char *>(p);
  while (n) {
    ssize_t r = read(fd, c, n);
    if (r < 0 && errno == EINTR)
      continue;
    if (r <= 0)
      return false;
    c += r;
    n -= (size_t)r;
  }
  return true;
}

bool iso_write_string(int fd, const char *s) {
  const uint32_t n = (uint32_t)strlen(s);
  return iso_write(fd, &n, sizeof n) && iso_write(fd, s, n);
}

/* A string of at most `max` bytes (the child is trusted with nothing). */
bool iso_read_string(int fd, std::string &s, uint32_t max) {
  uint32_t n;
  if (!iso_read(fd, &n, sizeof n) || n > max)
    return false;
  s.resize(n);
  return n == 0 || iso_read(fd, &s[0], n);
}

/* --- one job: work in the child, send, receive in the parent ------------------ */

/* struct iso_job: vdbio_iso.h */

/* [[maybe_unused]]: under ASan the children get no memory limits */
[[maybe_unused]] static uint64_t iso_mem_available(void) {
  FILE *f = fopen("/proc/meminfo", "r");
  unsigned long long kb = 0;
  char line[256];
  while (f && fgets(line, sizeof line, f))
    if (sscanf(line, "MemAvailable: %llu kB", &kb) == 1)
      break;
  if (f)
    fclose(f);
  return (uint64_t)kb * 1024u;
}

static uint64_t iso_file_size(const char *path) {
  struct stat st;
  return stat(path, &st) == 0 ? (uint64_t)st.st_size : 0;
}

/* This process's address space now (VmSize), which the child starts with. */
[[maybe_unused]] static uint64_t iso_address_space(void) {
  FILE *f = fopen("/proc/self/statm", "r");
  unsigned long long pages = 0;
  if (f) {
    if (fscanf(f, "%llu", &pages) != 1)
      pages = 0;
    fclose(f);
  }
  return (uint64_t)pages * (uint64_t)sysconf(_SC_PAGESIZE);
}

/* $BAKER_READER_SECONDS: a whole number of seconds from 1 to ISO_MAX_CAP;
 * 0 (no cap) when unset, or for another value, which one warning names. */
static unsigned iso_seconds_cap(void) {
  static int warned;
  const char *s = getenv("BAKER_READER_SECONDS");
  if (!s || !*s)
    return 0;
  char *end;
  errno = 0;
  const unsigned long v = strtoul(s, &end, 10);
  if (*end || errno || v < 1 || v > ISO_MAX_CAP || *s == '-' || *s == '+') {
    if (!warned++)
      bk_warn("BAKER_READER_SECONDS=%s is not a whole number of seconds from 1 to %u: ignored", s,
              ISO_MAX_CAP);
    return 0;
  }
  return (unsigned)v;
}

iso_limits iso_limits_for(const iso_job &job, const char *path) {
  iso_limits l;
  const uint64_t size = iso_file_size(path);
  l.seconds = job.base_seconds() + (unsigned)(size / ISO_BYTES_PER_SECOND);
  const unsigned cap = iso_seconds_cap();
  if (cap && cap < l.seconds)
    l.seconds = cap;
  l.memory = l.parse_memory = 0;
#ifndef ISO_ASAN
  uint64_t avail = iso_mem_available();
  if (avail) {
    l.memory = (avail > ISO_MIN_MEMORY ? avail : ISO_MIN_MEMORY) + ISO_AS_SLACK;
    struct rlimit cur;
    if (getrlimit(RLIMIT_AS, &cur) == 0 && cur.rlim_cur != RLIM_INFINITY &&
        (uint64_t)cur.rlim_cur < l.memory)
      l.memory = (uint64_t)cur.rlim_cur;
    l.parse_memory = iso_address_space() + ISO_AS_SLACK + ISO_PARSE_MEMORY + size;
    if (l.parse_memory > l.memory)
      l.parse_memory = l.memory;
  }
#endif
  return l;
}

/* Set in the child only: the limit iso_lift_parse_limit raises RLIMIT_AS to. */
static uint64_t iso_trees_memory = 0;

void iso_lift_parse_limit(void) {
  struct rlimit r;
  if (iso_trees_memory && getrlimit(RLIMIT_AS, &r) == 0) {
    r.rlim_cur = (rlim_t)iso_trees_memory;
    setrlimit(RLIMIT_AS, &r);
    iso_trees_memory = 0;
  }
}

static void iso_apply(const iso_limits &l, bool parse_first) {
  struct rlimit r;
  r.rlim_cur = r.rlim_max = 0;
  setrlimit(RLIMIT_CORE, &r); /* a crash is expected; no core file */
  if (l.memory && getrlimit(RLIMIT_AS, &r) == 0) {
    r.rlim_cur = (rlim_t)(parse_first ? l.parse_memory : l.memory);
    setrlimit(RLIMIT_AS, &r);
    iso_trees_memory = l.memory;
  }
  signal(SIGPIPE, SIG_DFL);
  signal(SIGALRM, SIG_DFL);
  signal(SIGXFSZ, SIG_IGN); /* a file size limit refuses iso_room's memfd: the heap then */
  alarm(l.seconds);
}

[[noreturn]] static void iso_child(iso_job &job, int fd, const iso_limits &l) {
  iso_apply(l, job.parses_first());
  bk_error_t e;
  memset(&e, 0, sizeof e);
  int rc;
  try {
    rc = job.work(&e);
  } catch (...) { /* the readers catch everything; this is a last line */
    rc = bk_fail(&e, BK_ERR_INPUT, "the %s reader failed", job.kind());
  }
  int32_t head = rc;
  bool ok = iso_write(fd, &head, sizeof head) && iso_write_string(fd, rc ? e.msg : "");
  if (ok && !rc)
    ok = job.send(fd);
  fflush(NULL); /* what the job logged (a --log file at a hidden level is buffered) */
  _exit(ok ? 0 : 3); /* no destructors: the parent owns every resource */
}

/* Why the child ended without a result, for the message. */
static std::string iso_why(int status, const iso_limits &l) {
  char buf[160];
  if (WIFSIGNALED(status) && WTERMSIG(status) == SIGALRM)
    snprintf(buf, sizeof buf, "took longer than %u s", l.seconds);
  else if (WIFSIGNALED(status))
    snprintf(buf, sizeof buf, "crashed the reader (%s)", strsignal(WTERMSIG(status)));
  else if (WIFEXITED(status))
    snprintf(buf, sizeof buf, "stopped the reader (exit %d)", WEXITSTATUS(status));
  else
    snprintf(buf, sizeof buf, "stopped the reader");
  return buf;
}

static int iso_wait(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

/* "3072 MiB of memory, 10 s"; the parse limit too where the job has one;
 * no memory where none was set (under AddressSanitizer). */
static std::string iso_limits_text(const iso_limits &l, bool parses_first) {
  char buf[160];
  const double mib = 1048576.0;
  if (!l.memory)
    snprintf(buf, sizeof buf, "%u s, no memory limit", l.seconds);
  else if (!parses_first)
    snprintf(buf, sizeof buf, "%.0f MiB of memory, %u s", (double)l.memory / mib, l.seconds);
  else
    snprintf(buf, sizeof buf, "%.0f MiB of memory while parsing its metadata, %.0f MiB for its "
             "grids, %u s", (double)l.parse_memory / mib, (double)l.memory / mib, l.seconds);
  return buf;
}

/* Reads the child's answer: its status and message, then the result. */
int iso_parent(iso_job &job, int fd, pid_t pid, const char *path, const iso_limits &l,
                      bk_error_t *err, bool *died) {
  int32_t head;
  std::string msg;
  int rc = -1;
  if (iso_read(fd, &head, sizeof head) && iso_read_string(fd, msg, sizeof err->msg)) {
    if (head != BK_OK)
      rc = bk_fail(err, head == BK_ERR_RUNTIME ? BK_ERR_RUNTIME : BK_ERR_INPUT, "%s",
                   msg.c_str());
    else
      rc = job.recv(fd, err);
  }
  if (rc > 0) /* a refusal is final; the child may still be writing */
    kill(pid, SIGKILL);
  const int status = iso_wait(pid);
  if (rc >= 0 && (rc != BK_OK || (WIFEXITED(status) && WEXITSTATUS(status) == 0)))
    return rc;
  if (died)
    *died = true;
  return bk_fail(err, BK_ERR_INPUT, "%s: the %s file is corrupt: reading it %s (limits: %s)",
                 path, job.kind(), iso_why(status, l).c_str(),
                 iso_limits_text(l, job.parses_first()).c_str());
}

/* Starts the child of `job`. A path that is not a regular file (a FIFO, a
 * device) is refused: the child would wait on it until its alarm. The child
 * dies with this process (PR_SET_PDEATHSIG): a bake killed by its scheduler
 * leaves no reader behind, holding memory until the alarm. (The signal
 * follows the forking thread, which always waits for its children here.) */
int iso_start(iso_job &job, const char *path, const iso_limits &l, iso_started *s,
                     bk_error_t *err) {
  const bk_file_kind_t kind = bk_file_kind(path);
  if (kind == BK_FILE_PIPE || kind == BK_FILE_OTHER)
    return bk_fail(err, BK_ERR_INPUT, "%s: not a regular file", path);
  const pid_t parent = getpid();
  int fds[2];
  if (pipe(fds) != 0)
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot create a pipe: %s", path, strerror(errno));
#ifdef F_SETPIPE_SZ
  /* a bigger pipe: a 25 MB grid in 25 hand-overs instead of 400, each a
   * wait for the other process to be scheduled on a busy machine; the
   * default stays when the system refuses */
  fcntl(fds[1], F_SETPIPE_SZ, ISO_PIPE_BYTES);
#endif
  job.prepare();
  fflush(NULL); /* the child must not write the parent's buffered output again */
  const pid_t pid = fork();
  if (pid < 0) {
    close(fds[0]);
    close(fds[1]);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot start the %s reader: %s", path, job.kind(),
                   strerror(errno));
  }
  if (pid == 0) {
    close(fds[0]);
    if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || getppid() != parent)
      _exit(127); /* the parent is gone already */
    iso_child(job, fds[1], l);
  }
  close(fds[1]); /* so that a later child does not hold this pipe open */
  s->pid = pid;
  s->fd = fds[0];
  return BK_OK;
}

/* Ends a child whose result is no longer wanted. */
void iso_abandon(iso_started *s) {
  if (s->pid > 0) {
    kill(s->pid, SIGKILL);
    iso_wait(s->pid);
  }
  if (s->fd >= 0)
    close(s->fd);
  s->pid = -1;
  s->fd = -1;
}

int iso_run(iso_job &job, const char *path, bk_error_t *err) {
  const iso_limits l = iso_limits_for(job, path);
  iso_started s;
  int rc = iso_start(job, path, l, &s, err);
  if (rc)
    return rc;
  rc = iso_parent(job, s.fd, s.pid, path, l, err);
  close(s.fd);
  return rc;
}
