/* vdbio.cpp: OpenVDB behind the C interface of vdbio.h.
 *
 * Every entry point catches openvdb and std exceptions and turns them into a
 * bk_error_t: no exception ever crosses into C. Files are read fully (no
 * delayed loading), so a truncated or corrupt file fails inside the call that
 * opened it, never later from a memory-mapped page or a worker thread; the
 * one exception is the dense read of the isolated reader's child
 * (vdbio_read_dense_direct), where a leaf's values are decoded as they are
 * copied and freed a slab at a time.
 * Writing lives in vdbio_write.cpp. */
#include "vdbio_internal.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
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
static std::string vdbio_prefix(const char *path, const char *where) {
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

/* --- dense reading ---------------------------------------------------------- */

/* Reads a float-like or vec3-like grid as Vec3s/float: double grids are
 * converted; anything else is BK_ERR_INPUT naming the type. */
static int vdbio_channels(const vdb::GridBase::Ptr &g, const char *path, const char *name,
                          bk_error_t *err) {
  if (g->isType<vdb::FloatGrid>() || g->isType<vdb::DoubleGrid>())
    return 1;
  if (g->isType<vdb::Vec3SGrid>() || g->isType<vdb::Vec3DGrid>())
    return 3;
  bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" holds %s values, expected float or Vec3f", path, name,
          g->valueType().c_str());
  return 0;
}

/* Samples any supported grid at a world position into `channels` floats. */
template <typename GridT> struct vdbio_sampler {
  typename GridT::ConstAccessor acc;
  vdb::tools::GridSampler<typename GridT::ConstAccessor, vdb::tools::BoxSampler> s;
  explicit vdbio_sampler(const GridT &g) : acc(g.getConstAccessor()), s(acc, g.transform()) {}
};

template <typename GridT> static void vdbio_store(const typename GridT::ValueType &v, float *dst);
template <> void vdbio_store<vdb::FloatGrid>(const float &v, float *dst) { dst[0] = v; }
template <> void vdbio_store<vdb::DoubleGrid>(const double &v, float *dst) { dst[0] = (float)v; }
template <> void vdbio_store<vdb::Vec3SGrid>(const vdb::Vec3s &v, float *dst) {
  dst[0] = v[0];
  dst[1] = v[1];
  dst[2] = v[2];
}
template <> void vdbio_store<vdb::Vec3DGrid>(const vdb::Vec3d &v, float *dst) {
  dst[0] = (float)v[0];
  dst[1] = (float)v[1];
  dst[2] = (float)v[2];
}

/* Fills d->data (allocated, d->nx.. and d->channels set) from grid g, either
 * at the grid's own indices box.min + (a,b,c) (like == NULL) or resampled
 * at the world positions of `like`'s indices. */
template <typename GridT>
static void vdbio_fill(const GridT &g, const vdb::Coord &min, const vdbio_dense_t *like,
                       vdbio_dense_t *d) {
  const int nx = d->nx, ny = d->ny, nz = d->nz, ch = d->channels;
  tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const tbb::blocked_range<int> &r) {
    vdbio_sampler<GridT> smp(g);
    for (int c = r.begin(); c != r.end(); c++)
      for (int b = 0; b < ny; b++)
        for (int a = 0; a < nx; a++) {
          float *dst = d->data + ((size_t)a + (size_t)nx * ((size_t)b + (size_t)ny * c)) * ch;
          if (!like) {
            vdbio_store<GridT>(smp.acc.getValue(min.offsetBy(a, b, c)), dst);
          } else {
            const double(*m)[4] = like->index_to_world;
            vdb::Vec3d w;
            for (int r3 = 0; r3 < 3; r3++)
              w[r3] = m[r3][0] * a + m[r3][1] * b + m[r3][2] * c + m[r3][3];
            vdbio_store<GridT>(smp.s.wsSample(w), dst);
          }
        }
  });
}

static void vdbio_fill_any(const vdb::GridBase::Ptr &g, const vdb::Coord &min,
                           const vdbio_dense_t *like, vdbio_dense_t *d) {
  if (g->isType<vdb::FloatGrid>())
    vdbio_fill(*vdb::gridConstPtrCast<vdb::FloatGrid>(g), min, like, d);
  else if (g->isType<vdb::DoubleGrid>())
    vdbio_fill(*vdb::gridConstPtrCast<vdb::DoubleGrid>(g), min, like, d);
  else if (g->isType<vdb::Vec3SGrid>())
    vdbio_fill(*vdb::gridConstPtrCast<vdb::Vec3SGrid>(g), min, like, d);
  else
    vdbio_fill(*vdb::gridConstPtrCast<vdb::Vec3DGrid>(g), min, like, d);
}

static const int VDBIO_COPY_SLAB = 64; /* z slices: a multiple of the leaves' 8 */

/* grid over `box` into data (x fastest), a slab of VDBIO_COPY_SLAB z slices
 * (leaf-aligned, so each leaf is in one) at a time (tools::copyToDense, leaf
 * by leaf), each slab's leaves inside the box emptied once copied: read with
 * delayed loading, the tree then holds one slab's values beside the copy,
 * not a second copy of the grid (at 512^3 a Vec3f grid's 1.6 GB of fresh
 * pages). Leaves reaching outside the box stay for the checksum's test of
 * what lies there (ck_outside_is_background); nothing else reads the tree. */
template <typename GridT>
static void vdbio_copy_release(GridT &grid, const vdb::CoordBBox &box,
                               typename GridT::ValueType *data) {
  using LeafT = typename GridT::TreeType::LeafNodeType;
  const int z0 = box.min().z(), base = z0 & ~7; /* floor to the leaves' 8 */
  const size_t slabs = (size_t)((box.max().z() - base) / VDBIO_COPY_SLAB) + 1;
  const size_t slice = (size_t)box.dim().x() * (size_t)box.dim().y();
  std::vector<std::vector<LeafT *>> leaves(slabs);
  for (auto it = grid.tree().beginLeaf(); it; ++it)
    if (box.isInside(it->getNodeBoundingBox()))
      leaves[(size_t)((it->origin().z() - base) / VDBIO_COPY_SLAB)].push_back(&*it);
  for (size_t s = 0; s < slabs; s++) {
    const int a = std::max(base + (int)s * VDBIO_COPY_SLAB, z0);
    const int b = std::min(base + ((int)s + 1) * VDBIO_COPY_SLAB - 1, box.max().z());
    vdb::tools::Dense<typename GridT::ValueType, vdb::tools::LayoutXYZ> dense(
        vdb::CoordBBox(vdb::Coord(box.min().x(), box.min().y(), a),
                       vdb::Coord(box.max().x(), box.max().y(), b)),
        data + (size_t)(a - z0) * slice);
    vdb::tools::copyToDense(grid, dense);
    for (LeafT *leaf : leaves[s]) {
      typename LeafT::Buffer empty(vdb::PartialCreate(), grid.background());
      leaf->swap(empty); /* the values go with `empty` */
    }
  }
}

/* d->data over `box` at the grid's own indices: leaf by leaf
 * (vdbio_copy_release) for float and Vec3f grids, through an accessor for
 * the double ones, which need a conversion. */
static void vdbio_copy_any(const vdb::GridBase::Ptr &g, const vdb::CoordBBox &box,
                           vdbio_dense_t *d) {
  if (g->isType<vdb::FloatGrid>())
    vdbio_copy_release(*vdb::gridPtrCast<vdb::FloatGrid>(g), box, d->data);
  else if (g->isType<vdb::Vec3SGrid>())
    vdbio_copy_release(*vdb::gridPtrCast<vdb::Vec3SGrid>(g), box,
                       reinterpret_cast<vdb::Vec3s *>(d->data));
  else
    vdbio_fill_any(g, box.min(), NULL, d);
}

/* The grid's checksum against the file's record: *checked = 1 when there is
 * one and it matches, 0 when the file has none; BK_ERR_INPUT naming the grid
 * when it does not match. */
static int vdbio_read_checked(const vdb::GridBase::Ptr &g, const vdb::MetaMap *meta,
                              const char *path, const char *name, int *checked, bk_error_t *err,
                              const float *dense = nullptr,
                              const vdb::CoordBBox *dense_box = nullptr) {
  std::string detail;
  *checked = 0;
  switch (vdbio_check_grid(*g, meta, name, detail, dense, dense_box)) {
  case VDBIO_VERIFY_UNCHECKED:
    return BK_OK;
  case VDBIO_VERIFY_OK:
    *checked = 1;
    return BK_OK;
  default:
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: grid \"%s\" is corrupt: %s (its checksum does not match; `baker "
                   "verify` checks every grid)", path, name, detail.c_str());
  }
}

/* Allocates d->data for d->nx*ny*nz*channels floats, refusing arrays that
 * would not fit in memory with the size they would need. */
static int vdbio_alloc_dense(vdbio_dense_t *d, const char *path, const char *name,
                             bk_error_t *err) {
  grid_dims_t gd;
  memset(&gd, 0, sizeof gd);
  gd.nx = d->nx;
  gd.ny = d->ny;
  gd.nz = d->nz;
  std::string where = std::string(path) + ": grid \"" + name + "\"";
  int rc = grid_check_memory(&gd, sizeof(float) * (size_t)d->channels, where.c_str(), err);
  if (rc)
    return rc;
  const size_t count = grid_count(&gd) * (size_t)d->channels;
  d->data = vdbio_dense_room ? vdbio_dense_room(count * sizeof(float)) : NULL;
  if (!d->data) /* no room given, or refused (e.g. a file size limit): the heap */
    d->data = (float *)bk_calloc(count, sizeof(float), where.c_str(), err);
  return d->data ? BK_OK : BK_ERR_RUNTIME;
}

/* out's index <-> world maps for the dense box `box` of a grid with the
 * linear transform xf, whether its scale is uniform, and its voxel size. */
static void vdbio_set_geometry(const vdb::math::Transform &xf, const vdb::CoordBBox &box,
                               vdbio_dense_t *out) {
  /* OpenVDB matrices act on row vectors: world = [i j k 1] * M */
  const vdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
  const vdb::Mat4d inv = m.inverse();
  const vdb::Vec3d w0 = xf.indexToWorld(box.min());
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) {
      out->index_to_world[r][c] = m(c, r);
      out->world_to_index[r][c] = inv(c, r);
    }
    out->index_to_world[r][3] = w0[r];
    out->world_to_index[r][3] = inv(3, r) - (double)box.min()[r];
  }
  const double sx = m(0, 0), tol = 1e-9 * std::fabs(sx);
  bool uniform = sx > 0.0;
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++)
      if (std::fabs(m(r, c) - (r == c ? sx : 0.0)) > tol)
        uniform = false;
  out->uniform_scale = uniform;
  const vdb::Vec3d vs = xf.voxelSize();
  /* not uniform: the shortest step, the safe one for marching */
  out->voxel_size = uniform ? sx : std::min(vs[0], std::min(vs[1], vs[2]));
}

int vdbio_read_dense_direct(const char *path, const char *grid_name, int pad, vdbio_dense_t *out,
                            int *checked, bk_error_t *err) {
  if (!path || !out)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_dense: invalid arguments");
  memset(out, 0, sizeof *out);
  if (pad < 0)
    return bk_fail(err, BK_ERR_RUNTIME, "%s: vdbio_read_dense: negative pad %d", path, pad);
  vdbio_init();
  int rc = BK_OK;
  try {
    vdb::GridBase::Ptr g;
    vdb::MetaMap::Ptr meta;
    /* delayed: leaf values are decoded as vdbio_copy_any copies them */
    if ((rc = vdbio_load_grid(path, NULL, grid_name, g, NULL, err, &meta, true)))
      return rc;
    const int ch = vdbio_channels(g, path, grid_name, err);
    if (!ch)
      return BK_ERR_INPUT;
    /* float and Vec3f grids read over their own box are checked on the
     * dense copy (one pass less); a grid refused before that copy is still
     * checked first, so that a corrupt file reads as corrupt */
    bool late_check = checked && pad == 0 &&
                      (g->isType<vdb::FloatGrid>() || g->isType<vdb::Vec3SGrid>());
    if (checked && !late_check &&
        (rc = vdbio_read_checked(g, meta.get(), path, grid_name, checked, err)))
      return rc;
    auto refuse = [&](int code) {
      std::string why = err->msg;
      if (late_check && (rc = vdbio_read_checked(g, meta.get(), path, grid_name, checked, err)))
        return rc;
      late_check = false;
      std::snprintf(err->msg, sizeof err->msg, "%s", why.c_str());
      err->code = code;
      return code;
    };
    const vdb::math::Transform &xf = g->transform();
    if (!xf.isLinear())
      return refuse(bk_fail(err, BK_ERR_INPUT,
                            "%s: grid \"%s\" has a non-linear (%s) transform, which is unsupported",
                            path, grid_name, xf.mapType().c_str()));

    vdb::CoordBBox box = g->evalActiveVoxelBoundingBox();
    if (box.empty()) {
      box = vdb::CoordBBox(vdb::Coord(0), vdb::Coord(0));
    } else {
      /* in 64 bits: a padded box near the int limits must not wrap */
      int64_t lo[3], hi[3];
      for (int a = 0; a < 3; a++) {
        lo[a] = (int64_t)box.min()[a] - pad;
        hi[a] = (int64_t)box.max()[a] + pad;
        if (lo[a] < INT32_MIN || hi[a] > INT32_MAX || hi[a] - lo[a] + 1 > GRID_MAX_AXIS)
          return refuse(bk_fail(err, BK_ERR_INPUT,
                         "%s: grid \"%s\": its active box spans %lld voxels along axis %d (with "
                         "pad %d), more than the %d a dense read allows",
                         path, grid_name, (long long)(hi[a] - lo[a] + 1), a, pad, GRID_MAX_AXIS));
      }
      box = vdb::CoordBBox(vdb::Coord((int)lo[0], (int)lo[1], (int)lo[2]),
                           vdb::Coord((int)hi[0], (int)hi[1], (int)hi[2]));
    }
    /* a box other than the checksum's (a damaged file's may be huge) is
     * checked before anything that size is allocated */
    if (late_check && !vdbio_is_checksum_box(meta.get(), box)) {
      late_check = false;
      if ((rc = vdbio_read_checked(g, meta.get(), path, grid_name, checked, err)))
        return rc;
    }
    const vdb::Coord dim = box.dim();
    out->nx = dim[0];
    out->ny = dim[1];
    out->nz = dim[2];
    out->channels = ch;

    vdbio_set_geometry(xf, box, out);

    if ((rc = vdbio_alloc_dense(out, path, grid_name, err)))
      return refuse(rc);
    vdbio_copy_any(g, box, out);
    /* the checksum after the copy, which it then reads instead of the tree */
    if (late_check && (rc = vdbio_read_checked(g, meta.get(), path, grid_name, checked, err,
                                               out->data, &box)))
      return rc;
  }
  VDBIO_CATCH_READ(path, (const char *)NULL)
  if (rc)
    vdbio_dense_free(out);
  return rc;
}

int vdbio_read_dense_like_direct(const char *path, const char *grid_name, const vdbio_dense_t *like,
                          vdbio_dense_t *out, int *found, bk_error_t *err) {
  if (!path || !like || !out || !found || like->nx < 1 || like->ny < 1 || like->nz < 1)
    return bk_fail(err, BK_ERR_RUNTIME, "%s: vdbio_read_dense_like: invalid arguments",
                   path ? path : "(null)");
  memset(out, 0, sizeof *out);
  *found = 0;
  vdbio_init();
  int rc = BK_OK;
  try {
    vdb::GridBase::Ptr g;
    rc = vdbio_load_grid(path, NULL, grid_name, g, found, err);
    if (rc || !*found)
      return rc;
    const int ch = vdbio_channels(g, path, grid_name, err);
    if (!ch) {
      *found = 0;
      return BK_ERR_INPUT;
    }
    out->nx = like->nx;
    out->ny = like->ny;
    out->nz = like->nz;
    out->channels = ch;
    memcpy(out->index_to_world, like->index_to_world, sizeof out->index_to_world);
    memcpy(out->world_to_index, like->world_to_index, sizeof out->world_to_index);
    out->uniform_scale = like->uniform_scale;
    out->voxel_size = like->voxel_size;
    if ((rc = vdbio_alloc_dense(out, path, grid_name, err)))
      return rc;
    vdbio_fill_any(g, vdb::Coord(0), like, out);
  }
  VDBIO_CATCH_READ(path, (const char *)NULL)
  if (rc) {
    vdbio_dense_free(out);
    *found = 0;
  }
  return rc;
}

void vdbio_dense_free(vdbio_dense_t *d) {
  if (!d)
    return;
  vdbio_array_free(d->data);
  d->data = NULL;
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
