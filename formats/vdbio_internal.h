/* vdbio_internal.h: what vdbio.cpp (reading) and vdbio_write.cpp share.
 * C++ only; the C interface is vdbio.h. */
#ifndef BAKER_VDBIO_INTERNAL_H
#define BAKER_VDBIO_INTERNAL_H

#include "vdbio.h"

/* openvdb::initialize, once per process, before any grid is made or read. */
void vdbio_init(void);

#endif
