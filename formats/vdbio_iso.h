/* vdbio_iso.h: the isolated reader's parts shared by its two files:
 * vdbio_isolate.cpp (the child, its limits, the grid readers) and
 * vdbio_isolate_meta.cpp (names, metadata, boxes, checksums). */
#ifndef BAKER_VDBIO_ISO_H
#define BAKER_VDBIO_ISO_H

#include <cstddef>
#include <cstdint>
#include <string>

#include "vdbio_internal.h"

/* One job: work in the child, send, receive in the parent. */
struct iso_job {
  virtual ~iso_job() {}
  virtual void prepare() {}                     /* parent, before the fork */
  virtual int work(bk_error_t *err) = 0;        /* child: read the file */
  virtual bool send(int fd) = 0;                /* child: the result */
  virtual int recv(int fd, bk_error_t *err) = 0; /* parent: the result, checked; -1 short */
};

/* The pipe: whole writes and reads (false: the other end went away). */
bool iso_write(int fd, const void *p, size_t n);
bool iso_read(int fd, void *p, size_t n);

/* A job whose result is a caller's array of known size: the child fills
 * its copy of `out`, the parent receives exactly bytes() into its own. */
struct iso_fill_job : iso_job {
  float *out = nullptr;
  virtual size_t bytes() const = 0;
  bool send(int fd) override { return iso_write(fd, out, bytes()); }
  int recv(int fd, bk_error_t *) override { return iso_read(fd, out, bytes()) ? BK_OK : -1; }
};
bool iso_write_string(int fd, const char *s);
/* A string of at most `max` bytes (the child is trusted with nothing). */
bool iso_read_string(int fd, std::string &s, uint32_t max);
/* Runs job in a child under the limits for path (vdbio_isolate.cpp). */
int iso_run(iso_job &job, const char *path, bk_error_t *err);

#endif
