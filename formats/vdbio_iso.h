/* vdbio_iso.h: the isolated VDB reader's parts shared by its two files:
 * vdbio_isolate.cpp (the grid readers) and vdbio_isolate_meta.cpp (names,
 * metadata, boxes, checksums); the child itself: isolate.h. */
#ifndef BAKER_VDBIO_ISO_H
#define BAKER_VDBIO_ISO_H

#include <cstddef>
#include <cstdint>
#include <string>

#include "isolate.h"
#include "vdbio_internal.h"

/* A job whose result is a caller's array of known size: the child fills
 * its copy of `out`, the parent receives exactly bytes() into its own. */
struct iso_fill_job : iso_job {
  float *out = nullptr;
  virtual size_t bytes() const = 0;
  bool send(int fd) override { return iso_write(fd, out, bytes()); }
  int recv(int fd, bk_error_t *) override { return iso_read(fd, out, bytes()) ? BK_OK : -1; }
};

#endif
