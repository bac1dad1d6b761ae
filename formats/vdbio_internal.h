/* vdbio_internal.h: what vdbio.cpp (reading) and vdbio_write.cpp share.
 * C++ only; the C interface is vdbio.h. */
#ifndef BAKER_VDBIO_INTERNAL_H
#define BAKER_VDBIO_INTERNAL_H

#include "vdbio.h"

#include <openvdb/openvdb.h>

/* openvdb::initialize, once per process, before any grid is made or read. */
void vdbio_init(void);

/* Opens `path` fully (no delayed loading) after checking its layout;
 * BK_ERR_INPUT when it is missing, not a VDB file or truncated. */
int vdbio_open(openvdb::io::File &file, const char *path, const char *where, bk_error_t *err);

/* Adds checksum_<grid> for every grid, and checksum_box, to the file
 * metadata (vdbio_checksum.cpp; the rule is in vdbio.h). `half`: the values
 * are stored as 16-bit floats, so the checksum covers the rounded values. */
void vdbio_add_checksums(const grid_dims_t *dims, const vdbio_grid_t *grids, int grid_count,
                         bool half, openvdb::MetaMap &file_meta);

#endif
