/* vdbio_write.cpp: dense arrays -> a VDB file (see vdbio.h).
 *
 * Like the rest of vdbio, it catches every exception and turns it into a
 * bk_error_t; the file is written under a temporary name and renamed, so a
 * failed write never leaves a half file where the output should be. */
#include "vdbio_internal.h"
#include "vdbio_hash.h"
#include "fdstream.h"
#include "vdbio_leaves.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tools/Prune.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>
#include <sstream>
#include <stdexcept>
#include <set>
#include <string>
#include <vector>

namespace vdb = openvdb;

static const char *const VDBIO_CENTERING =
    "cell-centred: voxel (i,j,k) covers the cube centred at indexToWorld(i,j,k)";

/* The transform that puts index (i,j,k) at the centre of our voxel (i,j,k). */
static vdb::math::Transform::Ptr vdbio_cell_centred_transform(const grid_dims_t *d) {
  const double vs = (double)d->voxel_size;
  vdb::math::Transform::Ptr xf = vdb::math::Transform::createLinearTransform(vs);
  xf->postTranslate(vdb::Vec3d((double)d->origin[0] + 0.5 * vs, (double)d->origin[1] + 0.5 * vs,
                               (double)d->origin[2] + 0.5 * vs));
  return xf;
}

/* Dense x-fastest array -> sparse grid, as tools::copyFromDense at
 * tolerance 0 builds it, leaf by leaf: a voxel whose channels are all zero
 * (or NaN: OpenVDB's !(|v - 0| > 0)) stays inactive at the background; an
 * 8^3 block with every voxel inactive is left out, one with every voxel
 * active and one value becomes an active tile, any other a leaf filled
 * directly from the array's rows (copyFromDense reads them along z, a whole
 * slice apart). Blocks are built in parallel and inserted in order, then
 * tiles pruned as copyFromDense does, so the tree is the same. Then the
 * background (and those inactive values) become `bg`, the value outside the
 * grid; the active voxels do not depend on bg. */
template <typename ValueT, int S> struct vdbio_block {
  /* source floats per voxel: the value's, or 1 for a grey Vec3 grid whose
   * one float stands for its three equal channels (the same tests) */
  static const int C = S;
  static ValueT value(const float *v) {
    if constexpr (S == 1) return ValueT(v[0]);
    else return *reinterpret_cast<const ValueT *>(v);
  }
  static bool is_background(const float *v) {
    for (int c = 0; c < C; c++)
      if (std::fabs(v[c]) > 0.0f) return false;
    return true;
  }
  /* One row of up to 8 voxels: bit x of the result is set where voxel x is
   * active (not background), and *differs where an active voxel is not
   * `first` (OpenVDB's isApproxEqual at tolerance 0, per channel). Without
   * branches, so that the compiler can vectorise the channels' tests. */
  static unsigned row_on(const float *r, int n, const float *first, bool *differs) {
    unsigned on = 0;
    bool diff = false;
    for (int x = 0; x < n; x++) {
      bool o = false, d = false;
      for (int c = 0; c < C; c++) {
        o |= std::fabs(r[C * x + c]) > 0.0f;
        d |= std::fabs(r[C * x + c] - first[c]) > 0.0f;
      }
      on |= (unsigned)o << x;
      diff |= o & d;
    }
    *differs |= diff;
    return on;
  }
};

/* What one 8^3 block becomes: nothing, an active tile of `tile`, or `leaf`. */
template <typename LeafT> struct vdbio_block_out {
  LeafT *leaf = nullptr;
  bool tile_on = false;
  typename LeafT::ValueType tile;
};

/* Whether every voxel of a full block has its first voxel's bits: a
 * constant medium's blocks, found with a row compare instead of the scan
 * below. Bit-equal voxels are equal and share their background state, so
 * the scan would find the same tile, or nothing. */
template <typename LeafT, int C, typename RowF>
static bool vdbio_block_uniform(const float *first, RowF row) {
  const int D = (int)LeafT::DIM;
  float pattern[3 * LeafT::DIM];
  for (int x = 0; x < D; x++) std::memcpy(pattern + C * x, first, C * sizeof(float));
  for (int z = 0; z < D; z++)
    for (int y = 0; y < D; y++)
      if (std::memcmp(row(y, z), pattern, C * D * sizeof(float)) != 0) return false;
  return true;
}

/* `slab`: the voxels of z slices z0.. (vdbio_slices), the block's among them.
 * A `deferred` leaf gets its value mask only (vdbio_window_fill gives its
 * values when it is written). */
template <typename LeafT, int S>
static void vdbio_build_block(const grid_dims_t *d, const float *slab, int z0,
                              const vdb::Coord &lo, bool deferred, vdbio_block_out<LeafT> &out) {
  using ValueT = typename LeafT::ValueType;
  using B = vdbio_block<ValueT, S>;
  const int C = B::C, D = (int)LeafT::DIM;
  const int ex = std::min(D, d->nx - lo[0]), ey = std::min(D, d->ny - lo[1]),
            ez = std::min(D, d->nz - lo[2]);
  auto row = [&](int y, int z) {
    return slab + (size_t)C * ((size_t)lo[0] + (size_t)d->nx * ((size_t)(lo[1] + y) +
                                                                (size_t)d->ny * (lo[2] - z0 + z)));
  };
  const float *first = row(0, 0);
  const bool first_bg = B::is_background(first);
  bool mixed = ex < D || ey < D || ez < D, any_on = false;
  if (!mixed && vdbio_block_uniform<LeafT, C>(first, row)) { /* the scan's result, sooner */
    if (first_bg) return;
    out.tile_on = true;
    out.tile = B::value(first);
    return;
  }
  unsigned char on[LeafT::DIM * LeafT::DIM]; /* per row (y, z): its active voxels' bits */
  const unsigned full = (1u << ex) - 1u;
  bool differs = false;
  for (int z = 0; z < ez; z++)
    for (int y = 0; y < ey; y++) {
      const unsigned bits = B::row_on(row(y, z), ex, first, &differs);
      on[y + D * z] = (unsigned char)bits;
      any_on |= bits != 0;
      mixed |= first_bg ? bits != 0 : bits != full;
    }
  if (!any_on) return; /* all inactive: the background */
  if (!mixed && !differs) { /* all active, one value */
    out.tile_on = true;
    out.tile = B::value(first);
    return;
  }
  LeafT *leaf = deferred ? new LeafT(vdb::PartialCreate(), lo, vdb::zeroVal<ValueT>(), false)
                         : new LeafT(lo, vdb::zeroVal<ValueT>(), false);
  ValueT *buf = deferred ? nullptr : leaf->buffer().data();
  for (int z = 0; z < ez; z++)
    for (int y = 0; y < ey; y++) {
      const float *r = row(y, z);
      for (unsigned bits = on[y + D * z]; bits; bits &= bits - 1u) {
        const int x = __builtin_ctz(bits);
        const vdb::Index n = LeafT::coordToOffset(vdb::Coord(x, y, z));
        if (buf) buf[n] = B::value(r + C * x);
        leaf->getValueMask().setOn(n);
      }
    }
  out.leaf = leaf;
}

/* A window of deferred leaves' values (vdbio_window_values), read across
 * the box of their 8^3 cells in rows: a leaf alone takes 64 rows of 8
 * voxels, each a cache line and often a page of its own, whereas one row
 * made across a run of neighbouring leaves serves them all at once. Each
 * row of cells is made only over its runs of leaves, so a sparse window
 * costs its leaves, not its box. A window whose box has over
 * VDBIO_WINDOW_SPREAD cells per leaf (leaves scattered far apart) is made
 * in halves instead, so the cell table stays small; one leaf always fits. */
static const size_t VDBIO_WINDOW_SPREAD = 16;

template <typename LeafT, int S>
static void vdbio_window_fill(const grid_dims_t &d, const vdbio_grid_t &g,
                              const LeafT *const *leaves, size_t n,
                              typename LeafT::ValueType *const *out) {
  using ValueT = typename LeafT::ValueType;
  using B = vdbio_block<ValueT, S>;
  const int C = S, D = (int)LeafT::DIM;
  vdb::Coord lo = leaves[0]->origin(), hi = lo;
  for (size_t i = 1; i < n; i++) {
    lo.minComponent(leaves[i]->origin());
    hi.maxComponent(leaves[i]->origin());
  }
  const int cx = (hi[0] - lo[0]) / D + 1, cy = (hi[1] - lo[1]) / D + 1,
            cz = (hi[2] - lo[2]) / D + 1;
  if (n > 1 && (size_t)cx * (size_t)cy * (size_t)cz > VDBIO_WINDOW_SPREAD * n) {
    const size_t h = n / 2;
    vdbio_window_fill<LeafT, S>(d, g, leaves, h, out);
    vdbio_window_fill<LeafT, S>(d, g, leaves + h, n - h, out + h);
    return;
  }
  std::vector<int> slot((size_t)cx * (size_t)cy * (size_t)cz, -1); /* cell -> leaf */
  auto cell = [&](int kx, int ky, int kz) {
    return (size_t)kx + (size_t)cx * ((size_t)ky + (size_t)cy * (size_t)kz);
  };
  for (size_t i = 0; i < n; i++) {
    const vdb::Coord o = leaves[i]->origin() - lo;
    slot[cell(o[0] / D, o[1] / D, o[2] / D)] = (int)i;
  }
  const int x0 = lo[0], x1 = std::min(hi[0] + D, d.nx), y1 = std::min(hi[1] + D, d.ny);
  /* a layer of cells along z per task: its leaves are that task's alone.
   * The rows of a run at the layer's 8 z are made together and written z
   * innermost, the leaves' own order: each cache line of a leaf is written
   * whole at once, not 12 bytes in each of 8 passes over the layer. */
  tbb::parallel_for(0, cz, [&](int kz) {
    const int za = lo[2] + D * kz, nzr = std::min(za + D, d.nz) - za;
    std::vector<float> made(g.data ? 0 : (size_t)C * (size_t)(x1 - x0) * (size_t)D);
    const float *rows[LeafT::DIM];
    for (int y = lo[1]; y < y1; y++) {
      const int ky = (y - lo[1]) / D;
      for (int ka = 0, kb; ka < cx; ka = kb) { /* the runs [ka, kb) of leaves */
        if (slot[cell(ka, ky, kz)] < 0) {
          kb = ka + 1;
          continue;
        }
        for (kb = ka + 1; kb < cx && slot[cell(kb, ky, kz)] >= 0;) kb++;
        const int xa = x0 + D * ka, xb = std::min(x0 + D * kb, x1);
        const size_t len = (size_t)(xb - xa);
        for (int z = 0; z < nzr; z++) {
          const size_t at = grid_index(&d, xa, y, za + z);
          float *m = made.data() + (size_t)C * len * (size_t)z;
          if (!g.data) g.fill(g.fill_ctx, at, at + len, m);
          rows[z] = g.data ? g.data + (size_t)C * at : m;
        }
        for (int k = ka; k < kb; k++) {
          const int xl = x0 + D * k, xh = std::min(xl + D, x1);
          ValueT *leaf = out[slot[cell(k, ky, kz)]];
          for (int x = xl; x < xh; x++) {
            ValueT *col = leaf + LeafT::coordToOffset(vdb::Coord(x - xl, y, za));
            const size_t from = (size_t)C * (size_t)(x - xa);
            for (int z = 0; z < nzr; z++) col[z] = B::value(rows[z] + from);
          }
        }
      }
    }
  });
}

const float *vdbio_slices(const grid_dims_t *d, const vdbio_grid_t &g, int z0, int nz,
                          std::vector<float> &buf) {
  const size_t C = g.type == VDBIO_VEC3 && !g.grey ? 3 : 1, plane = (size_t)d->nx * (size_t)d->ny;
  const size_t lo = plane * (size_t)z0, hi = plane * (size_t)(z0 + nz);
  if (g.data) return g.data + C * lo;
  buf.resize(C * (hi - lo));
  tbb::parallel_for(tbb::blocked_range<size_t>(lo, hi, 16384),
                    [&](const tbb::blocked_range<size_t> &r) {
                      g.fill(g.fill_ctx, r.begin(), r.end(), buf.data() + C * (r.begin() - lo));
                    });
  return buf.data();
}

/* A slab of 8^3 blocks at a time (its voxels made there for a grid made on
 * the fly), inserted in copyFromDense's order: x, then y, then z. With
 * `deferred` the leaves hold their masks only and their values are read
 * again as each is written (vdbio_leaves.h): the tree then costs its masks,
 * not a copy of the grid's values; *deferred_bytes: the values' bytes the
 * leaves would hold (the file's file_mem_bytes counts them). `hash`
 * (optional) is fed every slab in box order, beside the slab's blocks, so
 * the checksum needs no pass of its own over values made on the fly. */
template <typename GridT>
static typename GridT::Ptr vdbio_from_dense(const grid_dims_t *d, const vdbio_grid_t &g,
                                            bool deferred, size_t *deferred_bytes,
                                            ck_hasher *hash, bool half) {
  using ValueT = typename GridT::ValueType;
  using TreeT = typename GridT::TreeType;
  using LeafT = typename TreeT::LeafNodeType;
  static_assert(sizeof(ValueT) % sizeof(float) == 0, "float or Vec3s");
  const int D = (int)LeafT::DIM;
  const int lx = (d->nx + D - 1) / D, ly = (d->ny + D - 1) / D, lz = (d->nz + D - 1) / D;
  const size_t blocks = (size_t)lx * (size_t)ly;
  std::vector<vdbio_block_out<LeafT>> out(blocks);
  std::vector<float> buf;
  /* a tree whose leaves are compressed on every core when written */
  vdbio_parallel_tree<TreeT> *tree = new vdbio_parallel_tree<TreeT>(vdb::zeroVal<ValueT>());
  typename GridT::Ptr grid = GridT::create(typename TreeT::Ptr(tree));
  constexpr int C = (int)(sizeof(ValueT) / sizeof(float));
  const bool grey = C == 3 && g.grey; /* one float per voxel for three channels */
  if (deferred) {
    const grid_dims_t dims = *d;
    tree->values = [dims, g, grey](const LeafT *const *leaves, size_t n, ValueT *const *out) {
      if (grey) vdbio_window_fill<LeafT, 1>(dims, g, leaves, n, out);
      else vdbio_window_fill<LeafT, C>(dims, g, leaves, n, out);
    };
  }
  vdb::tree::ValueAccessor<TreeT> acc(grid->tree());
  for (int bz = 0; bz < lz; bz++) {
    const int z0 = D * bz;
    const int nzs = std::min(D, d->nz - z0);
    const float *slab = vdbio_slices(d, g, z0, nzs, buf);
    tbb::task_group hashing;
    const size_t voxels = (size_t)d->nx * (size_t)d->ny * (size_t)nzs;
    if (hash)
      hashing.run([&] {
        if (grey) hash->add_spread(slab, voxels, C, half);
        else hash->add(slab, voxels, C, half);
      });
    auto origin = [&](size_t b) { return vdb::Coord(D * (int)(b % lx), D * (int)(b / lx), z0); };
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks),
                      [&](const tbb::blocked_range<size_t> &r) {
                        for (size_t b = r.begin(); b != r.end(); b++) {
                          out[b] = vdbio_block_out<LeafT>();
                          const vdb::Coord at = origin(b);
                          if (grey) vdbio_build_block<LeafT, 1>(d, slab, z0, at, deferred, out[b]);
                          else vdbio_build_block<LeafT, C>(d, slab, z0, at, deferred, out[b]);
                        }
                      });
    for (size_t b = 0; b < blocks; b++) {
      if (out[b].leaf)
        acc.addLeaf(out[b].leaf);
      else if (out[b].tile_on)
        acc.addTile(1, origin(b), out[b].tile, true);
    }
    hashing.wait(); /* before the next slab reuses buf */
  }
  /* pruning looks at leaves' masks, never at their values: the internal
   * nodes above leaves are never constant */
  vdb::tools::pruneTiles(grid->tree(), vdb::zeroVal<ValueT>());
  const float bg = g.background;
  if (bg != 0.0f) /* it rewrites the leaves' inactive values: not for deferred ones */
    vdb::tools::changeBackground(grid->tree(), ValueT(bg));
  *deferred_bytes = deferred ? (size_t)grid->tree().leafCount() * LeafT::SIZE * sizeof(ValueT) : 0;
  return grid;
}

/* The arguments, checked before anything is written: a bad list is a bug in
 * the caller, reported with the path it was writing. */
static int vdbio_check_write_args(const char *path, const grid_dims_t *dims,
                                  const vdbio_grid_t *grids, int grid_count,
                                  const vdbio_meta_t *meta, int meta_count, bk_error_t *err) {
  if (!path || !path[0])
    return bk_fail(err, BK_ERR_INPUT, "vdbio_write: empty output path");
  if (!dims || dims->nx < 1 || dims->ny < 1 || dims->nz < 1 || !(dims->voxel_size > 0.0f) ||
      !std::isfinite(dims->voxel_size))
    return bk_fail(err, BK_ERR_RUNTIME, "%s: invalid grid dimensions for writing", path);
  if (grid_count < 0 || (grid_count > 0 && !grids) || meta_count < 0 || (meta_count > 0 && !meta))
    return bk_fail(err, BK_ERR_RUNTIME, "%s: invalid grid or metadata list for writing", path);
  std::set<std::string> seen;
  for (int g = 0; g < grid_count; g++) {
    if (!grids[g].name || !grids[g].name[0] || (!grids[g].data && !grids[g].fill) ||
        (grids[g].type != VDBIO_FLOAT && grids[g].type != VDBIO_VEC3) ||
        (grids[g].grey && grids[g].type != VDBIO_VEC3))
      return bk_fail(err, BK_ERR_RUNTIME,
                     "%s: grid %d has no name, no data, an unknown type or is grey but not Vec3",
                     path, g);
    if (!seen.insert(grids[g].name).second)
      return bk_fail(err, BK_ERR_RUNTIME, "%s: grid name \"%s\" is used twice", path,
                     grids[g].name);
  }
  for (int m = 0; m < meta_count; m++)
    if (!meta[m].key || !meta[m].key[0] || (meta[m].kind == VDBIO_META_STRING && !meta[m].s))
      return bk_fail(err, BK_ERR_RUNTIME, "%s: metadata entry %d has no key or no value", path,
                     m);
  return BK_OK;
}

/* One grid as a sparse grid with the cell-centred transform. Only scalar
 * grids are fog volumes: NanoVDB (and so nanovdb_validate, pbrt-v4,
 * Blender's NanoVDB path) rejects the fog class on vectors, which get no
 * class and vector_type invariant. Throws what OpenVDB throws (the caller
 * catches). */
static vdb::GridBase::Ptr vdbio_make_grid(const grid_dims_t *dims, const vdbio_grid_t &g,
                                          bool half, bool deferred, size_t *deferred_bytes,
                                          ck_hasher *hash) {
  vdb::GridBase::Ptr base;
  deferred = deferred && g.background == 0.0f; /* changeBackground needs the values */
  if (g.type == VDBIO_FLOAT) {
    base = vdbio_from_dense<vdb::FloatGrid>(dims, g, deferred, deferred_bytes, hash, half);
    base->setGridClass(vdb::GRID_FOG_VOLUME);
  } else {
    vdb::Vec3SGrid::Ptr v =
        vdbio_from_dense<vdb::Vec3SGrid>(dims, g, deferred, deferred_bytes, hash, half);
    /* unset means the OpenVDB default, which is also invariant; set it
     * explicitly so readers (Houdini) see the metadata */
    if (g.vector_invariant)
      v->setVectorType(vdb::VEC_INVARIANT);
    v->setGridClass(vdb::GRID_UNKNOWN);
    base = v;
  }
  base->setName(g.name);
  base->setTransform(vdbio_cell_centred_transform(dims));
  base->setSaveFloatAsHalf(half);
  return base;
}

/* The file's metadata: the caller's entries, then a creator, the voxel
 * centring and the world box as vectors unless the caller gave its own. */
static int vdbio_file_meta(const char *path, const grid_dims_t *d, const vdbio_meta_t *meta,
                           int meta_count, vdb::MetaMap &file_meta, bk_error_t *err) {
  for (int m = 0; m < meta_count; m++) {
    switch (meta[m].kind) {
    case VDBIO_META_STRING:
      file_meta.insertMeta(meta[m].key, vdb::StringMetadata(meta[m].s));
      break;
    case VDBIO_META_INT:
      file_meta.insertMeta(meta[m].key, vdb::Int64Metadata((int64_t)meta[m].i));
      break;
    case VDBIO_META_FLOAT:
      file_meta.insertMeta(meta[m].key, vdb::DoubleMetadata(meta[m].f));
      break;
    default:
      return bk_fail(err, BK_ERR_RUNTIME, "%s: metadata \"%s\" has an unknown kind %d", path,
                     meta[m].key, (int)meta[m].kind);
    }
  }
  if (!file_meta["creator"])
    file_meta.insertMeta("creator", vdb::StringMetadata("baker " BAKER_VERSION));
  if (!file_meta["voxel_centering"])
    file_meta.insertMeta("voxel_centering", vdb::StringMetadata(VDBIO_CENTERING));
  const vdb::Vec3d lo(d->origin[0], d->origin[1], d->origin[2]);
  const vdb::Vec3d size(d->nx * (double)d->voxel_size, d->ny * (double)d->voxel_size,
                        d->nz * (double)d->voxel_size);
  if (!file_meta["grid_bounds_min"])
    file_meta.insertMeta("grid_bounds_min", vdb::Vec3DMetadata(lo));
  if (!file_meta["grid_bounds_max"])
    file_meta.insertMeta("grid_bounds_max", vdb::Vec3DMetadata(lo + size));
  return BK_OK;
}

/* io::File::write opens its own std::ofstream and never checks it, so a full
 * disk gives a short file that looks written. The same archive writer, onto
 * a stream whose failures we see (Archive::write is protected). */
class vdbio_checked_archive : public vdb::io::Archive {
public:
  /* key: the checksum placeholders' (vdbio_add_checksum_placeholders);
   * tell: the caller's grid_done, called as each grid is in the file */
  vdbio_checked_archive(uint64_t key, const vdbio_write_opts_t *tell) : key_(key), tell_(tell) {}
  /* 0, or the errno of the first failed write or close. */
  int write_file(const char *tmp, const grid_dims_t *dims, const vdbio_grid_t *grids, int count,
                 bool half, const vdb::MetaMap &meta) const {
    bk_fd_streambuf sb(tmp);
    std::ostream os(&sb);
    if (!sb.error()) write_grids(os, dims, grids, count, half, meta);
    os.flush();
    int e = sb.close_file();
    return e ? e : (os.fail() ? EIO : 0);
  }

private:
  /* Archive::writeGrid (OpenVDB 10, seekable) without its delayed-load
   * metadata. That metadata holds each leaf's compressed size, which
   * OpenVDB 10 finds by compressing the whole grid once more before writing
   * it (a third of a large grid's write); OpenVDB 11 and later neither write
   * nor read it, and OpenVDB 10 reads files without it. The layout is
   * otherwise the same. */
  void write_grid(vdb::io::GridDescriptor &gd, const vdb::GridBase::Ptr &grid,
                  size_t deferred_bytes, std::ostream &os,
                  vdb::io::StreamMetadata::Ptr &file_sm) const {
    /* the stream metadata varies per grid: a copy of the file's, whose
     * pointer (the stream keeps the address of the Ptr) is put back after */
    vdb::io::StreamMetadata::Ptr sm(new vdb::io::StreamMetadata(*file_sm));
    sm->setHalfFloat(grid->saveFloatAsHalf());
    sm->gridMetadata() = static_cast<const vdb::MetaMap &>(*grid);
    vdb::io::setStreamMetadataPtr(os, sm, /*transfer=*/false);
    gd.writeHeader(os);
    const std::streampos offsets = os.tellp(); /* rewritten once they are known */
    gd.writeStreamPos(os);
    gd.setGridPos(os.tellp());
    setGridCompression(os, *grid);
    vdb::GridBase::Ptr meta = grid->copyGrid(); /* shallow: the tree is shared */
    if (vdb::io::getWriteGridStatsMetadata(os)) {
      meta->addStatsMetadata();
      /* the tree's size with its deferred leaves' values, as loaded */
      const int64_t mem = meta->metaValue<int64_t>(vdb::GridBase::META_FILE_MEM_BYTES);
      meta->removeMeta(vdb::GridBase::META_FILE_MEM_BYTES);
      meta->insertMeta(vdb::GridBase::META_FILE_MEM_BYTES,
                       vdb::Int64Metadata(mem + (int64_t)deferred_bytes));
      const uint32_t compression = vdb::io::getDataCompression(os);
      meta->insertMeta(vdb::GridBase::META_FILE_COMPRESSION,
                       vdb::StringMetadata(vdb::io::compressionToString(compression)));
    }
    meta->writeMeta(os);
    grid->writeTransform(os);
    grid->writeTopology(os);
    gd.setBlockPos(os.tellp());
    grid->writeBuffers(os);
    gd.setEndPos(os.tellp());
    os.seekp(offsets, std::ios_base::beg);
    gd.writeStreamPos(os);
    gd.seekToEnd(os);
    vdb::io::setStreamMetadataPtr(os, file_sm, /*transfer=*/false);
  }

  /* Archive::write (OpenVDB 10, seekable), the same bytes, with each grid's
   * tree built just before it is written and freed after: one tree at a
   * time instead of all of them. The names are unique and not empty
   * (vdbio_check_write_args) and no two grids share a tree, so the
   * descriptors need neither suffixes nor instancing. Each grid is hashed
   * as its tree is built; the checksums go over their placeholders at the
   * end. */
  void write_grids(std::ostream &os, const grid_dims_t *dims, const vdbio_grid_t *grids,
                   int count, bool half, const vdb::MetaMap &meta) const {
    vdb::io::StreamMetadata::Ptr sm = vdb::io::getStreamMetadataPtr(os);
    if (!sm) {
      sm.reset(new vdb::io::StreamMetadata);
      vdb::io::setStreamMetadataPtr(os, sm, /*transfer=*/false);
    }
    vdb::io::setDataCompression(os, compression());
    vdb::io::setWriteGridStatsMetadata(os, isGridStatsMetadataEnabled());
    writeHeader(os, /*seekable=*/true);
    std::ostringstream meta_bytes(std::ios_base::out | std::ios_base::binary);
    meta.writeMeta(meta_bytes);
    const std::string file_meta = meta_bytes.str();
    const std::streampos meta_at = os.tellp();
    os.write(file_meta.data(), (std::streamsize)file_meta.size());
    const int32_t n = count;
    os.write(reinterpret_cast<const char *>(&n), sizeof n);
    std::vector<std::string> hex((size_t)count);
    for (int g = 0; g < count; g++) {
      double t = bk_now_ms();
      size_t deferred_bytes;
      ck_hasher hash(true);
      vdb::GridBase::Ptr grid = vdbio_make_grid(dims, grids[g], half, true, &deferred_bytes, &hash);
      const float bg[3] = {grids[g].background, grids[g].background, grids[g].background};
      hex[(size_t)g] = ck_hex(hash.finish(bg, grids[g].type == VDBIO_VEC3 ? 3 : 1));
      const double t_built = bk_now_ms();
      vdb::io::GridDescriptor gd(grid->getName(), grid->type(), grid->saveFloatAsHalf());
      write_grid(gd, grid, deferred_bytes, os, sm);
      /* per-grid compression options (mask compression) reset, as Archive::write does */
      vdb::io::setDataCompression(os, compression());
      bk_log(2, "write: grid %s %.0f ms (tree and checksum %.0f ms)", grids[g].name,
             bk_now_ms() - t, t_built - t);
      grid.reset();
      if (tell_) {
        t = bk_now_ms();
        tell_->grid_done(tell_->grid_done_ctx, g);
        bk_log(2, "write: grid %s released in %.0f ms", grids[g].name, bk_now_ms() - t);
      }
    }
    put_checksums(os, meta_at, file_meta, hex, count);
  }

  /* Each grid's checksum over its placeholder in the file metadata. */
  void put_checksums(std::ostream &os, std::streampos meta_at, const std::string &file_meta,
                     const std::vector<std::string> &hex, int count) const {
    for (int g = 0; g < count; g++) {
      const std::string mark = vdbio_checksum_placeholder(key_, g);
      const size_t at = file_meta.find(mark);
      if (at == std::string::npos || file_meta.find(mark, at + 1) != std::string::npos ||
          hex[(size_t)g].size() != mark.size())
        throw std::runtime_error("checksum placeholder " + mark + " not found once");
      os.seekp(meta_at + (std::streamoff)at, std::ios_base::beg);
      os.write(hex[(size_t)g].data(), (std::streamsize)mark.size());
    }
    os.seekp(0, std::ios_base::end);
  }

  uint64_t key_;
  const vdbio_write_opts_t *tell_;
};

/* Zip by default; Blosc only where this OpenVDB was built with it. */
static uint32_t vdbio_compression(const char *path, const vdbio_write_opts_t *opts) {
  uint32_t comp = vdb::io::COMPRESS_ZIP | vdb::io::COMPRESS_ACTIVE_MASK;
  if (opts && opts->compression == VDBIO_COMPRESS_NONE) {
    comp = vdb::io::COMPRESS_NONE;
  } else if (opts && opts->compression == VDBIO_COMPRESS_BLOSC) {
    if (vdb::io::Archive::hasBloscCompression())
      comp = vdb::io::COMPRESS_BLOSC | vdb::io::COMPRESS_ACTIVE_MASK;
    else
      bk_warn("%s: this OpenVDB has no Blosc compression; writing with Zip instead", path);
  }
  return comp;
}

int vdbio_write(const char *path, const grid_dims_t *dims, const vdbio_grid_t *grids,
                int grid_count, const vdbio_meta_t *meta, int meta_count,
                const vdbio_write_opts_t *opts, bk_error_t *err) {
  int rc = vdbio_check_write_args(path, dims, grids, grid_count, meta, meta_count, err);
  if (rc)
    return rc;
  rc = bk_check_output_dir(path, err);
  if (rc)
    return rc;

  char tmp[4096];
  bk_temp_path(path, tmp, sizeof tmp);
  vdbio_init();
  try {
    vdb::MetaMap file_meta;
    rc = vdbio_file_meta(path, dims, meta, meta_count, file_meta, err);
    if (rc)
      return rc;
    const bool nano = vdbio_is_nano_path(path), half = opts && opts->half_float;
    if (nano) { /* NanoVDB files carry no file metadata, so no checksums */
      std::vector<std::string> names;
      for (int g = 0; g < grid_count; g++) names.push_back(grids[g].name);
      size_t unused; /* NanoVDB converts whole trees: every leaf holds its values */
      nvdbio_write(
          tmp, names,
          [&](int g) { return vdbio_make_grid(dims, grids[g], half, false, &unused, nullptr); },
          [&](int g) { /* in the file */
            if (opts && opts->grid_done) opts->grid_done(opts->grid_done_ctx, g);
          });
    } else {
      double t_file = bk_now_ms();
      const uint64_t key = vdbio_checksum_key();
      vdbio_add_checksum_placeholders(dims, grids, grid_count, key, file_meta);
      vdbio_checked_archive archive(key, opts && opts->grid_done ? opts : nullptr);
      archive.setCompression(vdbio_compression(path, opts));
      if (int e = archive.write_file(tmp, dims, grids, grid_count, half, file_meta)) {
        remove(tmp);
        return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write %s: %s", path, tmp, strerror(e));
      }
      bk_log(2, "write: file %.0f ms", bk_now_ms() - t_file);
    }
  } catch (const std::bad_alloc &) {
    remove(tmp);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory while writing the VDB file", path);
  } catch (const std::exception &e) {
    remove(tmp);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write VDB file: %s", path, e.what());
  } catch (...) {
    remove(tmp);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write VDB file: unknown error", path);
  }
  return bk_commit_temp(tmp, path, err);
}
