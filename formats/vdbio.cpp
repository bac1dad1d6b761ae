/* vdbio.cpp: OpenVDB behind the C interface of vdbio.h.
 *
 * Every entry point catches openvdb and std exceptions and turns them into a
 * bk_error_t: no exception ever crosses into C. Files are read fully (no
 * delayed loading), so a truncated or corrupt file fails inside the call that
 * opened it, never later from a memory-mapped page or a worker thread; the
 * one exception is the dense read of the isolated reader's child
 * (vdbio_read_dense_direct, in vdbio_dense.cpp), where a leaf's values are
 * decoded as they are copied and freed a slab at a time.
 * Writing lives in vdbio_write.cpp. */
#include "vdbio_internal.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <mutex>
#include <new>
#include <string>

namespace vdb = openvdb;

void vdbio_init(void) {
  static std::once_flag once;
  std::call_once(once, [] { vdb::initialize(); });
}

/* "where: path" or just "path", the prefix of every read error. */
std::string vdbio_prefix(const char *path, const char *where) {
  std::string s;
  if (where && where[0])
    s = std::string(where) + ": ";
  return s + (path ? path : "(null)");
}

/* --- reading --------------------------------------------------------------- */

/* io::File reads past the end of a truncated file without noticing (the
 * stream's failure is never checked) and returns grids of zeros. This walks
 * the file's layout the way io::File::open does, on a stream that throws on a
 * short read, and checks that every grid's recorded end lies inside the file.
 * Throws (IoError, ios_base::failure, LookupError) when it does not. */
class vdbio_layout_check : public vdb::io::Archive {
public:
  void check(const char *path) {
    std::ifstream is(path, std::ios::in | std::ios::binary);
    is.exceptions(std::ios::failbit | std::ios::badbit);
    is.seekg(0, std::ios::end);
    const int64_t size = (int64_t)is.tellg();
    is.seekg(0, std::ios::beg);
    vdb::io::StreamMetadata::Ptr sm(new vdb::io::StreamMetadata);
    sm->setSeekable(true);
    vdb::io::setStreamMetadataPtr(is, sm, /*transfer=*/false);
    readHeader(is);
    setFormatVersion(is);
    setLibraryVersion(is);
    setDataCompression(is);
    vdb::MetaMap meta;
    meta.readMeta(is);
    if (!inputHasGridOffsets())
      return; /* pre-2.0 files: read whole by io::File */
    const int32_t count = readGridCount(is);
    if (count < 0)
      OPENVDB_THROW(vdb::IoError, "negative grid count " << count);
    for (int32_t g = 0; g < count; g++) {
      vdb::io::GridDescriptor gd;
      gd.read(is);
      const int64_t here = (int64_t)is.tellg();
      if (gd.getGridPos() < here || gd.getBlockPos() < gd.getGridPos() ||
          gd.getEndPos() < gd.getBlockPos() || gd.getEndPos() > size)
        OPENVDB_THROW(vdb::IoError, "grid \"" << gd.gridName() << "\" should span bytes "
                                              << gd.getGridPos() << " to " << gd.getEndPos()
                                              << " but the file has " << size << " bytes");
      gd.seekToEnd(is);
    }
  }
};

/* vdbio_internal.h. Exceptions are the caller's to catch. */
int vdbio_open(vdb::io::File &file, const char *path, const char *where, bk_error_t *err,
               bool delayed) {
  /* io::File says only "could not open"; errno says why */
  FILE *probe = fopen(path, "rb");
  if (!probe)
    return bk_fail(err, BK_ERR_INPUT, "%s: cannot open VDB file: %s",
                   vdbio_prefix(path, where).c_str(), strerror(errno));
  fclose(probe);
  try {
    vdbio_layout_check().check(path);
  } catch (const std::bad_alloc &) {
    throw;
  } catch (const std::exception &e) {
    /* the header check gives the better message for foreign files */
    std::string what = e.what();
    if (what.find("not a VDB file") != std::string::npos)
      return bk_fail(err, BK_ERR_INPUT, "%s: not a VDB file", vdbio_prefix(path, where).c_str());
    return bk_fail(err, BK_ERR_INPUT, "%s: the VDB file is truncated or corrupt (%s)",
                   vdbio_prefix(path, where).c_str(),
                   dynamic_cast<const std::ios_base::failure *>(&e) ? "it ends too early"
                                                                    : e.what());
  }
  try {
    if (delayed)
      file.setCopyMaxBytes(0); /* map the file itself, never a private copy of it */
    file.open(delayed);
  } catch (const std::bad_alloc &) {
    throw;
  } catch (const std::exception &e) {
    return bk_fail(err, BK_ERR_INPUT, "%s: not a readable VDB file (%s)",
                   vdbio_prefix(path, where).c_str(), e.what());
  }
  return BK_OK;
}

/* "density (float), vel (vec3s)" for messages. */
static std::string vdbio_grid_list(vdb::io::File &file) {
  std::string s;
  try {
    vdb::GridPtrVecPtr grids = file.readAllGridMetadata();
    for (const vdb::GridBase::Ptr &g : *grids) {
      if (!s.empty())
        s += ", ";
      s += "\"" + g->getName() + "\" (" + g->valueType() + ")";
    }
  } catch (const std::exception &) {
    for (vdb::io::File::NameIterator it = file.beginName(); it != file.endName(); ++it) {
      if (!s.empty())
        s += ", ";
      s += "\"" + *it + "\"";
    }
  }
  return s.empty() ? std::string("none") : s;
}

/* Reads one grid; *found = 0 (with BK_OK) when absent and found != NULL,
 * BK_ERR_INPUT listing the file's grids when absent and found == NULL. */
static int vdbio_read_grid(vdb::io::File &file, const char *path, const char *where,
                           const char *grid_name, vdb::GridBase::Ptr &grid, int *found,
                           bk_error_t *err) {
  if (!grid_name || !grid_name[0])
    return bk_fail(err, BK_ERR_INPUT, "%s: no grid name given", vdbio_prefix(path, where).c_str());
  if (!file.hasGrid(grid_name)) {
    if (found) {
      *found = 0;
      return BK_OK;
    }
    return bk_fail(err, BK_ERR_INPUT, "%s: no grid named \"%s\"; the file has %s",
                   vdbio_prefix(path, where).c_str(), grid_name, vdbio_grid_list(file).c_str());
  }
  try {
    file.readGridMetadata(grid_name); /* under the parse limit: vdbio_trees_next */
    vdbio_trees_next();
    grid = file.readGrid(grid_name);
  } catch (const std::bad_alloc &) {
    throw;
  } catch (const std::exception &e) {
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: grid \"%s\" cannot be read, the file is truncated or "
                   "corrupt (%s)",
                   vdbio_prefix(path, where).c_str(), grid_name, e.what());
  }
  if (!grid)
    return bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" cannot be read",
                   vdbio_prefix(path, where).c_str(), grid_name);
  if (found)
    *found = 1;
  return BK_OK;
}

/* vdbio_open, then vdbio_read_grid, then closes the file: the start of every
 * reader of one grid (vdbio_internal.h). */
int vdbio_load_grid(const char *path, const char *where, const char *grid_name,
                    vdb::GridBase::Ptr &grid, int *found, bk_error_t *err,
                    vdb::MetaMap::Ptr *meta, bool delayed) {
  if (vdbio_is_nano_file(path))
    return nvdbio_load_grid(path, where, grid_name, grid, found, err);
  vdb::io::File file(path);
  int rc = vdbio_open(file, path, where, err, delayed);
  if (rc)
    return rc;
  rc = vdbio_read_grid(file, path, where, grid_name, grid, found, err);
  if (!rc && meta)
    *meta = file.getMetadata();
  file.close();
  return rc;
}

/* Samples g at the voxel centres of d, one z slice per task, each task with
 * its own accessor (accessors cache nodes and are not thread-safe). */
template <typename GridT>
static void vdbio_resample(const GridT &g, const grid_dims_t &d, float *out) {
  tbb::parallel_for(tbb::blocked_range<int>(0, d.nz), [&](const tbb::blocked_range<int> &r) {
    typename GridT::ConstAccessor acc = g.getConstAccessor();
    vdb::tools::GridSampler<typename GridT::ConstAccessor, vdb::tools::BoxSampler> s(acc,
                                                                                     g.transform());
    for (int k = r.begin(); k != r.end(); k++)
      for (int j = 0; j < d.ny; j++)
        for (int i = 0; i < d.nx; i++) {
          float c[3];
          grid_voxel_center(&d, i, j, k, c);
          out[grid_index(&d, i, j, k)] = (float)s.wsSample(vdb::Vec3d(c[0], c[1], c[2]));
        }
  });
}

int vdbio_resample_float_direct(const char *path, const char *grid_name, const grid_dims_t *dims,
                         float *out, const char *where, bk_error_t *err) {
  if (!path || !dims || !out || dims->nx < 1 || dims->ny < 1 || dims->nz < 1)
    return bk_fail(err, BK_ERR_RUNTIME, "%s: vdbio_resample_float: invalid arguments",
                   vdbio_prefix(path, where).c_str());
  vdbio_init();
  int rc = BK_OK;
  try {
    vdb::GridBase::Ptr base;
    if ((rc = vdbio_load_grid(path, where, grid_name, base, NULL, err)))
      return rc;
    /* double grids (some simulators write them) are narrowed as sampled */
    if (base->isType<vdb::FloatGrid>())
      vdbio_resample(*vdb::gridConstPtrCast<vdb::FloatGrid>(base), *dims, out);
    else if (base->isType<vdb::DoubleGrid>())
      vdbio_resample(*vdb::gridConstPtrCast<vdb::DoubleGrid>(base), *dims, out);
    else
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: grid \"%s\" holds %s values, expected a float (or double) grid",
                     vdbio_prefix(path, where).c_str(), grid_name, base->valueType().c_str());
  }
  VDBIO_CATCH_READ(path, where)
  return rc;
}

/* --- listing and metadata ---------------------------------------------------- */

int vdbio_list_grids_direct(const char *path, char ***names, char ***types, int *count, bk_error_t *err) {
  if (!path || !names || !count)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_list_grids: invalid arguments");
  *names = NULL;
  if (types)
    *types = NULL;
  *count = 0;
  vdbio_init();
  int rc = BK_OK;
  char **n = NULL, **t = NULL;
  int got = 0;
  try {
    std::vector<std::string> gn, gt;
    if (vdbio_is_nano_file(path)) {
      if ((rc = nvdbio_list(path, gn, gt, err)))
        return rc;
    } else {
      vdb::io::File file(path);
      if ((rc = vdbio_open(file, path, NULL, err)))
        return rc;
      vdb::GridPtrVecPtr grids = file.readAllGridMetadata(); /* owns what the loop reads */
      for (const vdb::GridBase::Ptr &g : *grids) {
        gn.push_back(g->getName());
        gt.push_back(g->valueType());
      }
      file.close();
    }
    const size_t total = gn.size();
    n = (char **)bk_calloc(total, sizeof(char *), path, err);
    t = (char **)bk_calloc(total, sizeof(char *), path, err);
    if (!n || !t) {
      rc = BK_ERR_RUNTIME;
    } else {
      for (size_t i = 0; i < total; i++) {
        n[got] = strdup(gn[i].c_str());
        t[got] = strdup(gt[i].c_str());
        got++;
        if (!n[got - 1] || !t[got - 1]) {
          rc = bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory listing grids", path);
          break;
        }
      }
    }
  }
  VDBIO_CATCH_READ(path, (const char *)NULL)
  if (rc) {
    vdbio_free_names(n, t, got);
    return rc;
  }
  *names = n;
  *count = got;
  if (types)
    *types = t;
  else
    vdbio_free_names(NULL, t, got);
  return BK_OK;
}

void vdbio_free_names(char **names, char **types, int count) {
  for (int i = 0; i < count; i++) {
    if (names)
      free(names[i]);
    if (types)
      free(types[i]);
  }
  free(names);
  free(types);
}

int vdbio_read_meta_direct(const char *path, const char *key, char *out, size_t len, bk_error_t *err) {
  if (!path || !key || !out || len == 0)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_meta: invalid arguments");
  out[0] = 0;
  vdbio_init();
  int rc = BK_OK;
  if (vdbio_is_nano_file(path))
    return BK_OK; /* NanoVDB files carry no file metadata */
  try {
    vdb::io::File file(path);
    if ((rc = vdbio_open(file, path, NULL, err)))
      return rc;
    vdb::MetaMap::Ptr meta = file.getMetadata();
    file.close();
    if (meta) {
      vdb::Metadata::Ptr m = (*meta)[key];
      if (m)
        snprintf(out, len, "%s", m->str().c_str());
    }
  }
  VDBIO_CATCH_READ(path, (const char *)NULL)
  return rc;
}
