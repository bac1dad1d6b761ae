/* vdbio_box.cpp: exact reading of what vdbio_write wrote (see vdbio.h):
 * a grid copied value for value over our index box, and the file metadata
 * whole. Photon shards (baker/shard.h) carry their raw sums and medium
 * grids this way to `baker merge`, which must get back the very bits. The
 * isolated wrappers are in vdbio_isolate.cpp. */
#include "vdbio_internal.h"

#include <openvdb/tools/Dense.h>

#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <vector>

namespace vdb = openvdb;

/* The catch every reader here ends with. */
#define BOX_CATCH(path)                                                                      \
  catch (const std::bad_alloc &) {                                                           \
    rc = bk_fail(err, BK_ERR_INPUT, "%s: out of memory while reading the VDB file", path);   \
  }                                                                                          \
  catch (const std::exception &e) {                                                          \
    rc = bk_fail(err, BK_ERR_INPUT, "%s: cannot read VDB file: %s", path, e.what());         \
  }                                                                                          \
  catch (...) {                                                                              \
    rc = bk_fail(err, BK_ERR_INPUT, "%s: cannot read VDB file: unknown error", path);        \
  }

template <typename GridT>
static void box_copy(const vdb::GridBase &base, const grid_dims_t *d, float *out) {
  using ValueT = typename GridT::ValueType;
  const GridT &g = static_cast<const GridT &>(base);
  const vdb::CoordBBox box(vdb::Coord(0, 0, 0), vdb::Coord(d->nx - 1, d->ny - 1, d->nz - 1));
  vdb::tools::Dense<ValueT, vdb::tools::LayoutXYZ> dense(box, reinterpret_cast<ValueT *>(out));
  vdb::tools::copyToDense(g, dense);
}

int vdbio_read_box_direct(const char *path, const char *grid_name, const grid_dims_t *dims,
                          int channels, float *out, bk_error_t *err) {
  if (!path || !grid_name || !dims || !out || (channels != 1 && channels != 3) || dims->nx < 1 ||
      dims->ny < 1 || dims->nz < 1)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_box: invalid arguments");
  vdbio_init();
  int rc = BK_OK;
  try {
    vdb::GridBase::Ptr g;
    if ((rc = vdbio_load_grid(path, NULL, grid_name, g, NULL, err)))
      return rc;
    const bool ok = channels == 1 ? g->isType<vdb::FloatGrid>() : g->isType<vdb::Vec3SGrid>();
    if (!ok)
      return bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" holds %s values, expected %s", path,
                     grid_name, g->valueType().c_str(), channels == 1 ? "float" : "vec3s");
    if (channels == 1)
      box_copy<vdb::FloatGrid>(*g, dims, out);
    else
      box_copy<vdb::Vec3SGrid>(*g, dims, out);
  }
  BOX_CATCH(path)
  return rc;
}

/* One entry's kind and exact text; false for kinds we do not carry. */
static bool box_meta_text(const vdb::Metadata &m, vdbio_meta_entry_t *e) {
  const std::string t = m.typeName();
  if (t == vdb::StringMetadata::staticTypeName()) {
    e->kind = VDBIO_META_STRING;
    std::snprintf(e->value, sizeof e->value, "%s", m.str().c_str());
  } else if (t == vdb::Int64Metadata::staticTypeName()) {
    e->kind = VDBIO_META_INT;
    std::snprintf(e->value, sizeof e->value, "%" PRId64,
                  static_cast<const vdb::Int64Metadata &>(m).value());
  } else if (t == vdb::Int32Metadata::staticTypeName()) {
    e->kind = VDBIO_META_INT;
    std::snprintf(e->value, sizeof e->value, "%d",
                  (int)static_cast<const vdb::Int32Metadata &>(m).value());
  } else if (t == vdb::DoubleMetadata::staticTypeName()) {
    e->kind = VDBIO_META_FLOAT;
    std::snprintf(e->value, sizeof e->value, "%.17g",
                  static_cast<const vdb::DoubleMetadata &>(m).value());
  } else if (t == vdb::FloatMetadata::staticTypeName()) {
    e->kind = VDBIO_META_FLOAT;
    std::snprintf(e->value, sizeof e->value, "%.9g",
                  (double)static_cast<const vdb::FloatMetadata &>(m).value());
  } else {
    return false;
  }
  return true;
}

int vdbio_read_meta_all_direct(const char *path, vdbio_meta_entry_t **entries, int *count,
                               bk_error_t *err) {
  *entries = NULL;
  *count = 0;
  vdbio_init();
  if (vdbio_is_nano_file(path))
    return bk_fail(err, BK_ERR_INPUT, "%s: a NanoVDB file carries no file metadata", path);
  int rc = BK_OK;
  try {
    vdb::io::File file(path);
    if ((rc = vdbio_open(file, path, NULL, err)))
      return rc;
    vdb::MetaMap::Ptr meta = file.getMetadata();
    file.close();
    std::vector<vdbio_meta_entry_t> got;
    if (!meta)
      meta.reset(new vdb::MetaMap);
    for (auto it = meta->beginMeta(); it != meta->endMeta(); ++it) {
      vdbio_meta_entry_t e;
      std::memset(&e, 0, sizeof e);
      std::snprintf(e.key, sizeof e.key, "%s", it->first.c_str());
      if (it->second && box_meta_text(*it->second, &e))
        got.push_back(e);
    }
    *entries = static_cast<vdbio_meta_entry_t *>(
        bk_calloc(got.size() ? got.size() : 1, sizeof(vdbio_meta_entry_t), path, err));
    if (!*entries)
      return BK_ERR_RUNTIME;
    if (!got.empty())
      std::memcpy(*entries, got.data(), got.size() * sizeof(vdbio_meta_entry_t));
    *count = (int)got.size();
  }
  BOX_CATCH(path)
  return rc;
}
