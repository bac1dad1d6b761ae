/* vdbio_internal.h: what vdbio.cpp and vdbio_dense.cpp (reading) and
 * vdbio_write.cpp share.
 * C++ only; the C interface is vdbio.h. */
#ifndef BAKER_VDBIO_INTERNAL_H
#define BAKER_VDBIO_INTERNAL_H

#include "vdbio.h"

#include <openvdb/openvdb.h>

#include <functional>
#include <string>
#include <vector>

class ck_hasher; /* vdbio_hash.h */

/* openvdb::initialize, once per process, before any grid is made or read. */
void vdbio_init(void);

/* NanoVDB (nvdbio.cpp; vdbio_is_nano_path in vdbio.h): a file that is
 * one (by its magic number); writing the grids vdbio_write makes (throws what
 * NanoVDB throws); listing and loading one grid as OpenVDB, with the same
 * conventions as vdbio.cpp's readers (found == NULL: absent is an error).
 * nvdbio_write asks make(i) for grid i, named names[i], only when it writes
 * it, and drops it and its NanoVDB copy before the next; done(i) then. */
bool vdbio_is_nano_file(const char *path);
void nvdbio_write(const std::string &file, const std::vector<std::string> &names,
                  const std::function<openvdb::GridBase::Ptr(int)> &make,
                  const std::function<void(int)> &done);
int nvdbio_list(const char *path, std::vector<std::string> &names,
                std::vector<std::string> &types, bk_error_t *err);
int nvdbio_load_grid(const char *path, const char *where, const char *grid_name,
                     openvdb::GridBase::Ptr &grid, int *found, bk_error_t *err);

/* Called by every reader between the metadata it parses and the trees it
 * reads. In an isolated reader's child (vdbio_isolate.cpp) it raises the
 * memory limit from the parse limit to the read limit; elsewhere it does
 * nothing. Metadata is small in every good file, so a corrupt length field
 * there fails at once instead of filling all the memory there is. */
void vdbio_trees_next(void);

/* Where vdbio.cpp's dense readers put a grid's values: NULL for bk_calloc,
 * or a function giving zeroed room for `bytes` (NULL when there is none:
 * then bk_calloc too).
 * The isolated reader's child sets it so that the values land in memory its
 * parent then maps (vdbio_isolate.cpp). */
extern float *(*vdbio_dense_room)(size_t bytes);
/* Shortens the room vdbio_dense_room gave to its first `bytes` (a Vec3f
 * grid that came out grey: one channel of the three it was given). */
extern void (*vdbio_dense_room_trim)(size_t bytes);

/* "where: path" or just "path", the prefix of every read error. */
std::string vdbio_prefix(const char *path, const char *where);

/* The catch block every reader ends with. */
#define VDBIO_CATCH_READ(path, where)                                                              \
  catch (const std::bad_alloc &) {                                                                 \
    rc = bk_fail(err, BK_ERR_INPUT, "%s: out of memory while reading the VDB file (corrupt "       \
                 "sizes, or more than this machine can hold)", vdbio_prefix(path, where).c_str());  \
  }                                                                                                \
  catch (const std::exception &e) {                                                                \
    rc = bk_fail(err, BK_ERR_INPUT, "%s: cannot read VDB file: %s",                                \
                 vdbio_prefix(path, where).c_str(), e.what());                                     \
  }                                                                                                \
  catch (...) {                                                                                    \
    rc = bk_fail(err, BK_ERR_INPUT, "%s: cannot read VDB file: unknown error",                     \
                 vdbio_prefix(path, where).c_str());                                               \
  }

/* Opens `path` after checking its layout; BK_ERR_INPUT when it is missing,
 * not a VDB file or truncated. Fully (no delayed loading) unless `delayed`:
 * then leaf values are read from the mapped file when first used, which
 * only an isolated reader may do (a page of a file cut short meanwhile is
 * a SIGBUS, which the child's status reports). */
int vdbio_open(openvdb::io::File &file, const char *path, const char *where, bk_error_t *err,
               bool delayed = false);

/* Opens `path` (VDB or NanoVDB), reads grid `grid_name` and closes the
 * file; found NULL: a missing grid is BK_ERR_INPUT naming the grids there
 * are, else *found = 0. meta (may be NULL) gets the file metadata.
 * Exceptions are the caller's to catch. */
int vdbio_load_grid(const char *path, const char *where, const char *grid_name,
                    openvdb::GridBase::Ptr &grid, int *found, bk_error_t *err,
                    openvdb::MetaMap::Ptr *meta = nullptr, bool delayed = false);

/* Voxels of z slices [z0, z0 + nz) of a grid to write (x fastest, type
 * floats each, one for a grey Vec3 grid): the dense array's own, or made by
 * its fill into buf (in parallel). */
const float *vdbio_slices(const grid_dims_t *dims, const vdbio_grid_t &grid, int z0, int nz,
                          std::vector<float> &buf);

/* The file's checksums (the rule is in vdbio.h): checksum_box and
 * checksum_<grid> for every grid, each grid's holding
 * vdbio_checksum_placeholder(key, g), 16 characters like the hex that
 * replaces it once the grid is written (the writer hashes each grid as it
 * builds its tree, vdbio_hash.h); key (vdbio_checksum_key) is drawn per
 * file, so that no other metadata holds the same text. */
void vdbio_add_checksum_placeholders(const grid_dims_t *dims, const vdbio_grid_t *grids,
                                     int grid_count, uint64_t key, openvdb::MetaMap &file_meta);
std::string vdbio_checksum_placeholder(uint64_t key, int g);
uint64_t vdbio_checksum_key(void);

/* Whether `box` is the box the file's checksums were taken over. */
bool vdbio_is_checksum_box(const openvdb::MetaMap *meta, const openvdb::CoordBBox &box);

/* Whether the file records a checksum for grid `name` (*lanes: under the
 * eight-lane rule, else the serial one), so that a reader copying exactly
 * the checksum box can feed a ck_hasher (vdbio_hash.h) of that rule. */
bool vdbio_checksum_recorded(const openvdb::MetaMap *meta, const std::string &name, bool *lanes);

/* One grid against the checksum the file metadata records for it (the rule
 * is in vdbio.h); `detail` says why CORRUPT or UNCHECKED (meta NULL: no
 * file metadata, UNCHECKED). `fed`: a hasher of the recorded rule already
 * fed the grid's values over the checksum box, in box order (a reader's
 * copy); NULL: the values are copied from the grid again. */
vdbio_verify_status_t vdbio_check_grid(const openvdb::GridBase &grid, const openvdb::MetaMap *meta,
                                       const std::string &name, std::string &detail,
                                       const ck_hasher *fed = nullptr);

/* The readers themselves (vdbio.cpp, vdbio_dense.cpp), in this process.
 * The functions of vdbio.h run them in an isolated child
 * (vdbio_isolate.cpp). checked == NULL: no checksum check; grey: as in
 * vdbio_read_dense_verified_all. */
int vdbio_resample_float_direct(const char *path, const char *grid_name, const grid_dims_t *dims,
                                float *out, const char *where, bk_error_t *err);
int vdbio_read_dense_direct(const char *path, const char *grid_name, int pad, vdbio_dense_t *out,
                            int *checked, int grey, bk_error_t *err);
int vdbio_read_dense_like_direct(const char *path, const char *grid_name,
                                 const vdbio_dense_t *like, vdbio_dense_t *out, int *found,
                                 bk_error_t *err);
int vdbio_list_grids_direct(const char *path, char ***names, char ***types, int *count,
                            bk_error_t *err);
int vdbio_read_meta_direct(const char *path, const char *key, char *out, size_t len,
                           bk_error_t *err);
/* vdbio_checksum.cpp: one grid of vdbio_verify, in this process. */
int vdbio_verify_grid_direct(const char *path, const char *name, vdbio_verify_grid_t *out,
                             bk_error_t *err);
/* vdbio_box.cpp: the exact readers of vdbio.h (vdbio_read_box,
 * vdbio_read_meta_all), in this process. */
int vdbio_read_box_direct(const char *path, const char *grid_name, const grid_dims_t *dims,
                          int channels, float *out, bk_error_t *err);
int vdbio_read_meta_all_direct(const char *path, vdbio_meta_entry_t **entries, int *count,
                               bk_error_t *err);

#endif
