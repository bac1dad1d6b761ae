/* isolate.h: a reader of untrusted files run in a child process with
 * memory and time limits (isolate.cpp). The VDB readers
 * (vdbio_isolate*.cpp) and the mesh reader (mesh_io.cpp) use it. C++. */
#ifndef BAKER_ISOLATE_H
#define BAKER_ISOLATE_H

#include <cstddef>
#include <cstdint>
#include <string>

#include <sys/types.h>

#include "base/common.h"

/* One job: work in the child, send, receive in the parent. */
struct iso_job {
  virtual ~iso_job() {}
  /* the file's kind in messages: "the VDB file is corrupt" */
  virtual const char *kind() const { return "VDB"; }
  /* under the tighter parse limit until iso_lift_parse_limit */
  virtual bool parses_first() const { return true; }
  /* seconds allowed besides one per 10 MB of file (isolate.cpp) */
  virtual unsigned base_seconds() const { return 60u; } /* OpenVDB's initialize, TBB */
  virtual void prepare() {}                     /* parent, before the fork */
  virtual int work(bk_error_t *err) = 0;        /* child: read the file */
  virtual bool send(int fd) = 0;                /* child: the result */
  virtual int recv(int fd, bk_error_t *err) = 0; /* parent: the result, checked; -1 short */
};

/* The pipe: whole writes and reads (false: the other end went away). */
bool iso_write(int fd, const void *p, size_t n);
bool iso_read(int fd, void *p, size_t n);
bool iso_write_string(int fd, const char *s);
/* A string of at most `max` bytes (the child is trusted with nothing). */
bool iso_read_string(int fd, std::string &s, uint32_t max);

/* A child's limits, computed in the parent (no allocation after fork). */
struct iso_limits {
  uint64_t memory;       /* 0: none */
  uint64_t parse_memory; /* until iso_lift_parse_limit; 0: none */
  unsigned seconds;
};
iso_limits iso_limits_for(const iso_job &job, const char *path);
/* In the child: from the parse limit to the full one. */
void iso_lift_parse_limit(void);

/* A child at work: its pid, the read end of its pipe and its limits. */
struct iso_started {
  pid_t pid = -1;
  int fd = -1;
  iso_limits limits = {};
};
/* Starts job's child (a path that is not a regular file is refused). */
int iso_start(iso_job &job, const char *path, const iso_limits &l, iso_started *s,
              bk_error_t *err);
/* The child's answer, then its end; *died when it ended without one. */
int iso_parent(iso_job &job, int fd, pid_t pid, const char *path, const iso_limits &l,
               bk_error_t *err, bool *died = nullptr);
/* Ends a child whose result is no longer wanted. */
void iso_abandon(iso_started *s);
/* Runs job in a child under the limits for path, and waits for it. */
int iso_run(iso_job &job, const char *path, bk_error_t *err);

#endif
