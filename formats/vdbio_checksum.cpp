/* vdbio_checksum.cpp: per-grid checksums in the file metadata (their
 * placeholders), and their check (`baker verify`). The rule is documented
 * in vdbio.h; the writer hashes the values it stores as it builds each
 * tree (vdbio_write.cpp), the checker the values it reads back over the
 * same box, both through the one hasher of vdbio_hash.h. */
#include "vdbio_internal.h"
#include "vdbio_hash.h"

#include <openvdb/tools/Dense.h>
#include <tbb/parallel_for.h>

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <chrono>
#include <new>
#include <stdexcept>
#include <random>
#include <string>
#include <vector>

namespace vdb = openvdb;

/* The metadata key of a grid's checksum under each rule (vdbio.h): the
 * eight-lane rule this baker writes, and the serial one of older files. An
 * older baker finds no key of its own in a newer file and reports the grids
 * unchecked, not corrupt. */
static std::string ck_key(const std::string &grid, bool lanes) {
  return (lanes ? "checksum_v2_" : "checksum_") + grid;
}

std::string vdbio_checksum_placeholder(uint64_t key, int g) {
  /* 16 characters, as ck_hex's; a key drawn per file keeps other metadata
   * (a scene path, say) from holding the same text */
  uint64_t h = key ^ (CK_PRIME * (uint64_t)(g + 1));
  h = (h ^ (h >> 29)) * 0xbf58476d1ce4e5b9ull;
  return "~" + ck_hex(h ^ (h >> 32)).substr(1);
}

uint64_t vdbio_checksum_key(void) {
  std::random_device rd;
  const uint64_t t = (uint64_t)std::chrono::steady_clock::now().time_since_epoch().count();
  return ((uint64_t)rd() << 32) ^ (uint64_t)rd() ^ t;
}

void vdbio_add_checksum_placeholders(const grid_dims_t *dims, const vdbio_grid_t *grids,
                                     int count, uint64_t key, vdb::MetaMap &file_meta) {
  char box[96];
  std::snprintf(box, sizeof box, "%d %d %d", dims->nx, dims->ny, dims->nz);
  file_meta.insertMeta("checksum_box", vdb::StringMetadata(box));
  for (int g = 0; g < count; g++)
    file_meta.insertMeta(ck_key(grids[g].name, true),
                         vdb::StringMetadata(vdbio_checksum_placeholder(key, g)));
}

/* --- checking ---------------------------------------------------------------- */

/* The hash of a grid read back, over the box, one z slice at a time (a
 * slice of dense values at most, whatever the grid's size). */
template <typename GridT>
static uint64_t ck_grid_hash(const GridT &grid, int nx, int ny, int nz, int ch, bool lanes) {
  using ValueT = typename GridT::ValueType;
  std::vector<float> slice((size_t)nx * (size_t)ny * (size_t)ch);
  ck_hasher h(lanes);
  for (int z = 0; z < nz; z++) {
    const vdb::CoordBBox box(vdb::Coord(0, 0, z), vdb::Coord(nx - 1, ny - 1, z));
    vdb::tools::Dense<ValueT, vdb::tools::LayoutXYZ> dense(
        box, reinterpret_cast<ValueT *>(slice.data()));
    vdb::tools::copyToDense(grid, dense);
    h.add(slice.data(), (size_t)nx * (size_t)ny, ch, false);
  }
  const ValueT b = grid.background();
  return h.finish(reinterpret_cast<const float *>(&b), ch);
}

/* Everything the grid stores outside the box (inactive tiles of its internal
 * nodes) must be the background the writer left there (its value is part
 * of the hash): a renderer sampling there sees those values, and
 * uncompressed files are mostly such tiles. The hash covers the box; this
 * covers the rest. */
template <typename GridT>
static bool ck_outside_is_background(const GridT &grid, int nx, int ny, int nz) {
  using TreeT = typename GridT::TreeType;
  const typename GridT::ValueType bg = grid.background();
  const vdb::CoordBBox box(vdb::Coord(0, 0, 0), vdb::Coord(nx - 1, ny - 1, nz - 1));
  /* the tiles of the internal nodes, then the voxels of the leaves that
   * reach outside the box (a leaf inside it is all hashed) */
  auto tile = grid.tree().cbeginValueAll();
  tile.setMaxDepth(TreeT::DEPTH - 2);
  for (; tile; ++tile) {
    vdb::CoordBBox b;
    tile.getBoundingBox(b);
    if (!box.isInside(b) && !(*tile == bg))
      return false;
  }
  for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
    if (box.isInside(leaf->getNodeBoundingBox()))
      continue;
    for (auto v = leaf->cbeginValueAll(); v; ++v)
      if (!box.isInside(v.getCoord()) && !(*v == bg))
        return false;
  }
  return true;
}

static std::string ck_meta(const vdb::MetaMap &meta, const std::string &key) {
  vdb::Metadata::ConstPtr m = meta[key];
  return m ? m->str() : std::string();
}

/* The grid's recorded checksum ("" if none) and whether it is the lane rule's. */
static std::string ck_recorded(const vdb::MetaMap &meta, const std::string &grid, bool &lanes) {
  std::string h = ck_meta(meta, ck_key(grid, true));
  lanes = !h.empty();
  return lanes ? h : ck_meta(meta, ck_key(grid, false));
}

bool vdbio_checksum_recorded(const vdb::MetaMap *meta, const std::string &name, bool *lanes) {
  return meta && !ck_recorded(*meta, name, *lanes).empty();
}

bool vdbio_is_checksum_box(const vdb::MetaMap *meta, const vdb::CoordBBox &box) {
  int n[3] = {0, 0, 0};
  if (!meta || std::sscanf(ck_meta(*meta, "checksum_box").c_str(), "%d %d %d", &n[0], &n[1],
                           &n[2]) != 3 || n[0] < 1 || n[1] < 1 || n[2] < 1)
    return false;
  return box == vdb::CoordBBox(vdb::Coord(0, 0, 0), vdb::Coord(n[0] - 1, n[1] - 1, n[2] - 1));
}

vdbio_verify_status_t vdbio_check_grid(const vdb::GridBase &g, const vdb::MetaMap *meta,
                                       const std::string &name, std::string &detail,
                                       const ck_hasher *fed) {
  bool lanes = false;
  const std::string want = meta ? ck_recorded(*meta, name, lanes) : std::string();
  int box[3] = {0, 0, 0};
  if (meta && (std::sscanf(ck_meta(*meta, "checksum_box").c_str(), "%d %d %d", &box[0], &box[1],
                           &box[2]) != 3 || box[1] < 1 || box[2] < 1))
    box[0] = 0;
  if (want.empty() || box[0] < 1) {
    detail = "no checksum recorded";
    return VDBIO_VERIFY_UNCHECKED;
  }
  uint64_t h = 0;
  bool outside_ok = true;
  /* the caller's copy hashed as it was made: no second copy */
  if (const vdb::FloatGrid *f = dynamic_cast<const vdb::FloatGrid *>(&g)) {
    const float bg = f->background();
    h = fed ? fed->finish(&bg, 1) : ck_grid_hash(*f, box[0], box[1], box[2], 1, lanes);
    outside_ok = ck_outside_is_background(*f, box[0], box[1], box[2]);
  } else if (const vdb::Vec3SGrid *v = dynamic_cast<const vdb::Vec3SGrid *>(&g)) {
    const vdb::Vec3s bg = v->background();
    h = fed ? fed->finish(bg.asPointer(), 3) : ck_grid_hash(*v, box[0], box[1], box[2], 3, lanes);
    outside_ok = ck_outside_is_background(*v, box[0], box[1], box[2]);
  } else {
    detail = "unexpected type " + g.valueType();
    return VDBIO_VERIFY_CORRUPT;
  }
  char buf[160];
  if (!outside_ok) {
    std::snprintf(buf, sizeof buf,
                  "values other than the background outside the %dx%dx%d box it was written over",
                  box[0], box[1], box[2]);
    detail = buf;
    return VDBIO_VERIFY_CORRUPT;
  }
  const std::string got = ck_hex(h);
  if (got == want)
    return VDBIO_VERIFY_OK;
  detail = "checksum " + got + ", recorded " + want;
  return VDBIO_VERIFY_CORRUPT;
}

/* One grid: read, hash, compare. Read errors of one grid are that grid's
 * corruption (the file itself opened). Its metadata and transform are read
 * first, under the reader's parse limit (vdbio_isolate.cpp): a corrupt
 * string length there asks for gigabytes, and is refused at once. */
static void ck_verify_grid(vdb::io::File &file, const std::string &name, const vdb::MetaMap &meta,
                           vdbio_verify_grid_t *out) {
  std::snprintf(out->name, sizeof out->name, "%s", name.c_str());
  std::string detail;
  try {
    bool lanes;
    if (ck_recorded(meta, name, lanes).empty()) {
      out->status = VDBIO_VERIFY_UNCHECKED;
      detail = "no checksum recorded";
    } else {
      try {
        file.readGridMetadata(name);
      } catch (const std::bad_alloc &) {
        throw std::runtime_error("its metadata or transform asks for more memory than any "
                                 "grid's header needs");
      }
      vdbio_trees_next();
      vdb::GridBase::Ptr g = file.readGrid(name);
      out->status = vdbio_check_grid(*g, &meta, name, detail);
    }
  } catch (const std::bad_alloc &) {
    throw;
  } catch (const std::exception &e) {
    out->status = VDBIO_VERIFY_CORRUPT;
    detail = std::string("cannot be read: ") + e.what();
  }
  std::snprintf(out->detail, sizeof out->detail, "%s", detail.c_str());
}

int vdbio_verify_grid_direct(const char *path, const char *name, vdbio_verify_grid_t *out,
                             bk_error_t *err) {
  vdbio_init();
  try {
    vdb::io::File file(path);
    int rc = vdbio_open(file, path, nullptr, err);
    if (rc)
      return rc;
    vdb::MetaMap::Ptr meta = file.getMetadata();
    ck_verify_grid(file, name, *meta, out);
    file.close();
  } catch (const std::bad_alloc &) {
    return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory while verifying grid \"%s\"", path,
                   name);
  } catch (const std::exception &e) {
    return bk_fail(err, BK_ERR_INPUT, "%s: cannot read VDB file: %s", path, e.what());
  }
  return BK_OK;
}
