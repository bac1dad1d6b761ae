/* vdbio_internal.h: what vdbio.cpp (reading) and vdbio_write.cpp share.
 * C++ only; the C interface is vdbio.h. */
#ifndef BAKER_VDBIO_INTERNAL_H
#define BAKER_VDBIO_INTERNAL_H

#include "vdbio.h"

#include <openvdb/openvdb.h>

#include <string>
#include <vector>

/* openvdb::initialize, once per process, before any grid is made or read. */
void vdbio_init(void);

/* NanoVDB (nvdbio.cpp): a path that asks for it (".nvdb"), a file that is
 * one (by its magic number); writing the grids vdbio_write made (throws what
 * NanoVDB throws); listing and loading one grid as OpenVDB, with the same
 * conventions as vdbio.cpp's readers (found == NULL: absent is an error). */
bool vdbio_is_nano_path(const char *path);
bool vdbio_is_nano_file(const char *path);
void nvdbio_write(const std::string &file, const openvdb::GridPtrVec &grids);
int nvdbio_list(const char *path, std::vector<std::string> &names,
                std::vector<std::string> &types, bk_error_t *err);
int nvdbio_load_grid(const char *path, const char *where, const char *grid_name,
                     openvdb::GridBase::Ptr &grid, int *found, bk_error_t *err);

#endif
