/* vdbio_dense.cpp: grids read into dense arrays (vdbio.h's dense readers,
 * in this process: vdbio_isolate.cpp runs them in a child). Over a grid's
 * own box the values are copied leaf by leaf from a file opened with
 * delayed loading, a slab at a time, the checksum fed as they go; elsewhere
 * (another box, double grids) they are sampled through an accessor. */
#include "vdbio_internal.h"
#include "vdbio_hash.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <openvdb/tools/Interpolation.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace vdb = openvdb;

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
static const int VDBIO_GREY_SLAB = 8;  /* the grey copy's slab, through a buffer */

/* The n voxels of Vec3 values rgb as one float each into out, while their
 * three channels hold the same bits; false at the first that does not. */
static bool vdbio_squeeze_grey(const float *rgb, size_t n, float *out) {
  const uint32_t *u = reinterpret_cast<const uint32_t *>(rgb);
  for (size_t i = 0; i < n; i++) {
    if (u[3 * i + 1] != u[3 * i] || u[3 * i + 2] != u[3 * i])
      return false;
    out[i] = rgb[3 * i];
  }
  return true;
}

/* The first n voxels of data, one float each, spread in place to three. */
static void vdbio_spread_grey(float *data, size_t n) {
  for (size_t i = n; i-- > 0;) /* backwards: voxel i's three go at or after it */
    data[3 * i] = data[3 * i + 1] = data[3 * i + 2] = data[i];
}

/* grid over `box` into data (x fastest), a slab of z slices (leaf-aligned,
 * so each leaf is in one) at a time (tools::copyToDense, leaf by leaf),
 * each slab's leaves inside the box emptied once copied: read with delayed
 * loading, the tree then holds one slab's values beside the copy, not a
 * second copy of the grid (at 512^3 a Vec3f grid's 1.6 GB of fresh pages).
 * Leaves reaching outside the box stay for the checksum's test of what lies
 * there (ck_outside_is_background); nothing else reads the tree. `hash`
 * (may be NULL) is fed the values in box order. With `grey` a Vec3f grid
 * goes through a small buffer and is stored one float per voxel while its
 * channels agree (grey light: a third of the pages); at the first voxel
 * where they do not, what was stored is spread back to three. data has room
 * for all channels either way. Returns the channels stored: 1 or 3. */
template <typename GridT>
static int vdbio_copy_release(GridT &grid, const vdb::CoordBBox &box, float *data, ck_hasher *hash,
                              bool grey) {
  using ValueT = typename GridT::ValueType;
  using LeafT = typename GridT::TreeType::LeafNodeType;
  const int C = (int)(sizeof(ValueT) / sizeof(float));
  grey = grey && C == 3;
  const int slab = grey ? VDBIO_GREY_SLAB : VDBIO_COPY_SLAB;
  const int z0 = box.min().z(), base = z0 & ~7; /* floor to the leaves' 8 */
  const size_t slabs = (size_t)((box.max().z() - base) / slab) + 1;
  const size_t slice = (size_t)box.dim().x() * (size_t)box.dim().y();
  std::vector<std::vector<LeafT *>> leaves(slabs);
  for (auto it = grid.tree().beginLeaf(); it; ++it)
    if (box.isInside(it->getNodeBoundingBox()))
      leaves[(size_t)((it->origin().z() - base) / slab)].push_back(&*it);
  std::vector<float> buffer(grey ? (size_t)slab * slice * 3 : 0);
  size_t done = 0; /* voxels stored */
  for (size_t s = 0; s < slabs; s++) {
    const int a = std::max(base + (int)s * slab, z0);
    const int b = std::min(base + ((int)s + 1) * slab - 1, box.max().z());
    const size_t n = (size_t)(b - a + 1) * slice;
    float *dst = grey ? buffer.data() : data + done * (size_t)C;
    vdb::tools::Dense<ValueT, vdb::tools::LayoutXYZ> dense(
        vdb::CoordBBox(vdb::Coord(box.min().x(), box.min().y(), a),
                       vdb::Coord(box.max().x(), box.max().y(), b)),
        reinterpret_cast<ValueT *>(dst));
    vdb::tools::copyToDense(grid, dense);
    for (LeafT *leaf : leaves[s]) {
      typename LeafT::Buffer empty(vdb::PartialCreate(), grid.background());
      leaf->swap(empty); /* the values go with `empty` */
    }
    if (hash)
      hash->add(dst, n, C, false);
    if (grey && !vdbio_squeeze_grey(dst, n, data + done)) {
      vdbio_spread_grey(data, done);
      std::memcpy(data + 3 * done, dst, n * 3 * sizeof(float));
      grey = false;
    }
    done += n;
  }
  return grey ? 1 : C;
}

/* d->data over `box` at the grid's own indices: leaf by leaf
 * (vdbio_copy_release) for float and Vec3f grids, through an accessor for
 * the double ones, which need a conversion. Returns the channels stored. */
static int vdbio_copy_any(const vdb::GridBase::Ptr &g, const vdb::CoordBBox &box,
                          vdbio_dense_t *d, ck_hasher *hash, bool grey) {
  if (g->isType<vdb::FloatGrid>())
    return vdbio_copy_release(*vdb::gridPtrCast<vdb::FloatGrid>(g), box, d->data, hash, false);
  if (g->isType<vdb::Vec3SGrid>())
    return vdbio_copy_release(*vdb::gridPtrCast<vdb::Vec3SGrid>(g), box, d->data, hash, grey);
  vdbio_fill_any(g, box.min(), NULL, d);
  return d->channels;
}

/* The grid's checksum against the file's record: *checked = 1 when there is
 * one and it matches, 0 when the file has none; BK_ERR_INPUT naming the grid
 * when it does not match. */
static int vdbio_read_checked(const vdb::GridBase::Ptr &g, const vdb::MetaMap *meta,
                              const char *path, const char *name, int *checked, bk_error_t *err,
                              const ck_hasher *fed = nullptr) {
  std::string detail;
  *checked = 0;
  switch (vdbio_check_grid(*g, meta, name, detail, fed)) {
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
                             bk_error_t *err, bool *in_room = nullptr) {
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
  if (in_room)
    *in_room = d->data != NULL;
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

/* d stored `channels` per voxel in room made for d->channels: the room
 * shortened to what holds them (the heap's pages past them were never
 * touched, and are given back). */
static void vdbio_shrink_dense(vdbio_dense_t *d, int channels, bool in_room) {
  if (channels == d->channels)
    return;
  d->channels = channels;
  const size_t bytes = (size_t)d->nx * d->ny * d->nz * (size_t)channels * sizeof(float);
  if (in_room) {
    vdbio_dense_room_trim(bytes);
  } else if (float *p = (float *)std::realloc(d->data, bytes)) {
    d->data = p;
  }
}

/* The grid's active box grown by pad voxels on every side (one voxel at
 * the origin for an empty grid), refused when an axis would leave int or
 * hold more than GRID_MAX_AXIS voxels. */
static int vdbio_padded_box(const vdb::GridBase &g, int pad, const char *path,
                            const char *grid_name, vdb::CoordBBox *out, bk_error_t *err) {
  const vdb::CoordBBox box = g.evalActiveVoxelBoundingBox();
  if (box.empty()) {
    *out = vdb::CoordBBox(vdb::Coord(0), vdb::Coord(0));
    return BK_OK;
  }
  int64_t lo[3], hi[3]; /* in 64 bits: a padded box near the int limits must not wrap */
  for (int a = 0; a < 3; a++) {
    lo[a] = (int64_t)box.min()[a] - pad;
    hi[a] = (int64_t)box.max()[a] + pad;
    if (lo[a] < INT32_MIN || hi[a] > INT32_MAX || hi[a] - lo[a] + 1 > GRID_MAX_AXIS)
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: grid \"%s\": its active box spans %lld voxels along axis %d (with "
                     "pad %d), more than the %d a dense read allows",
                     path, grid_name, (long long)(hi[a] - lo[a] + 1), a, pad, GRID_MAX_AXIS);
  }
  *out = vdb::CoordBBox(vdb::Coord((int)lo[0], (int)lo[1], (int)lo[2]),
                        vdb::Coord((int)hi[0], (int)hi[1], (int)hi[2]));
  return BK_OK;
}

int vdbio_read_dense_direct(const char *path, const char *grid_name, int pad, vdbio_dense_t *out,
                            int *checked, int grey, bk_error_t *err) {
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

    vdb::CoordBBox box;
    if ((rc = vdbio_padded_box(*g, pad, path, grid_name, &box, err)))
      return refuse(rc);
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

    bool in_room = false, lanes = false;
    if ((rc = vdbio_alloc_dense(out, path, grid_name, err, &in_room)))
      return refuse(rc);
    /* the checksum fed by the copy, which it then reads instead of the tree */
    const bool feed = late_check && vdbio_checksum_recorded(meta.get(), grid_name, &lanes);
    ck_hasher hash(lanes);
    vdbio_shrink_dense(out, vdbio_copy_any(g, box, out, feed ? &hash : nullptr, grey != 0),
                       in_room);
    if (late_check && (rc = vdbio_read_checked(g, meta.get(), path, grid_name, checked, err,
                                               feed ? &hash : nullptr)))
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
