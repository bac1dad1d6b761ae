/* test_vdbio_tree.cpp: vdbio_write builds its sparse grids leaf by leaf from
 * the dense rows (formats/vdbio_write.cpp); the tree it writes must be the
 * one tools::copyFromDense at tolerance 0 (+ changeBackground) builds from
 * the same array: same topology, same values and active states everywhere,
 * same leaf and tile counts. And its leaves, compressed on every core
 * (formats/vdbio_leaves.h), must be the bytes OpenVDB's own serial
 * Tree::writeBuffers writes, for every compression and half float. The
 * array has what the two could disagree on:
 * a box that is not a whole number of 8^3 leaves, exact zeros and -0 and NaN
 * (inactive by OpenVDB's !(|v| > 0)), constant active blocks (tiles) next to
 * varying ones, a zero channel in a Vec3, a background other than 0.
 * And the dense read (vdbio_read_dense), which copies a grid a slab of z
 * slices at a time and frees each slab's leaves, must give every voxel of
 * grids deeper than one slab: baker's own (checksum on the copy, leaves
 * reaching outside the box kept for its test) and OpenVDB's (negative,
 * unaligned z, tiles, a background that is not 0).
 * Usage: test_vdbio_tree DIR */
#include <openvdb/openvdb.h>
#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tools/Dense.h>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

extern "C" {
#include "vdbio.h"
}
#include "vdbio_leaves.h"

namespace vdb = openvdb;

static int failures = 0;
#define CHECK(c, ...)                                                                    \
  do {                                                                                   \
    if (!(c)) {                                                                          \
      std::fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);                          \
      std::fprintf(stderr, __VA_ARGS__);                                                 \
      std::fprintf(stderr, "\n");                                                        \
      failures++;                                                                        \
    }                                                                                    \
  } while (0)

enum { NX = 37, NY = 20, NZ = 26 };

/* Channel c of voxel (i,j,k): fog blocks of one value, a varying ball, holes. */
static float value_at(int i, int j, int k, int c) {
  if (i < 8 && j < 8 && k < 8) return c == 1 ? 0.0f : 0.5f; /* constant block, zero channel */
  if (i >= 16 && i < 24 && j >= 8 && j < 16) return 0.0f; /* all background: no leaf */
  if (i == 30 && j == 3) return k % 3 == 0 ? -0.0f : NAN; /* inactive: -0, NaN */
  float d = std::sqrt(float((i - 25) * (i - 25) + (j - 12) * (j - 12) + (k - 13) * (k - 13)));
  if (d < 6.0f) return 1.0f + 0.01f * d + 0.001f * (float)c;
  return 0.25f; /* active and constant where whole leaves fit */
}

template <typename GridT>
static typename GridT::Ptr reference(std::vector<float> &data, float bg, int nx = NX, int ny = NY,
                                     int nz = NZ) {
  using ValueT = typename GridT::ValueType;
  const vdb::CoordBBox box(vdb::Coord(0), vdb::Coord(nx - 1, ny - 1, nz - 1));
  vdb::tools::Dense<ValueT, vdb::tools::LayoutXYZ> dense(box,
                                                         reinterpret_cast<ValueT *>(data.data()));
  typename GridT::Ptr g = GridT::create(vdb::zeroVal<ValueT>());
  vdb::tools::copyFromDense(dense, *g, vdb::zeroVal<ValueT>());
  if (bg != 0.0f) vdb::tools::changeBackground(g->tree(), ValueT(bg));
  return g;
}

static bool same_value(float a, float b) { return a == b || (std::isnan(a) && std::isnan(b)); }
static bool same_value(const vdb::Vec3s &a, const vdb::Vec3s &b) {
  return same_value(a[0], b[0]) && same_value(a[1], b[1]) && same_value(a[2], b[2]);
}

template <typename GridT>
static void compare(const char *label, const GridT &got, const GridT &want, int nx = NX,
                    int ny = NY, int nz = NZ) {
  CHECK(got.tree().hasSameTopology(want.tree()), "%s: topology differs", label);
  CHECK(got.tree().leafCount() == want.tree().leafCount(), "%s: %u leaves, want %u", label,
        (unsigned)got.tree().leafCount(), (unsigned)want.tree().leafCount());
  CHECK(got.tree().activeTileCount() == want.tree().activeTileCount(), "%s: %u tiles, want %u",
        label, (unsigned)got.tree().activeTileCount(), (unsigned)want.tree().activeTileCount());
  CHECK(got.background() == want.background(), "%s: background differs", label);
  auto ga = got.getConstAccessor();
  auto wa = want.getConstAccessor();
  int bad = 0;
  for (int k = -2; k < nz + 2; k++)
    for (int j = -2; j < ny + 2; j++)
      for (int i = -2; i < nx + 2; i++) {
        const vdb::Coord c(i, j, k);
        if (ga.isValueOn(c) != wa.isValueOn(c) || !same_value(ga.getValue(c), wa.getValue(c)))
          bad++;
      }
  CHECK(bad == 0, "%s: %d voxels differ in value or state", label, bad);
}

/* x as a tree's value: a float, a grey Vec3 (three equal channels) or,
 * with `rgb`, a Vec3 of three different channels. */
static float tree_value(float x, bool, float *) { return x; }
static vdb::Vec3s tree_value(float x, bool rgb, vdb::Vec3s *) {
  return rgb ? vdb::Vec3s(x, 0.5f * x, x + 1.0f) : vdb::Vec3s(x);
}

/* A tree of more leaves than one write window: a varying field, holes of
 * background (inactive), a band of another inactive value. */
template <typename TreeT> static typename TreeT::Ptr many_leaves(float bg, bool rgb = false) {
  using ValueT = typename TreeT::ValueType;
  typename TreeT::Ptr t(new TreeT(ValueT(bg)));
  typename vdb::tree::ValueAccessor<TreeT> acc(*t);
  for (int k = 0; k < 160; k++)
    for (int j = 0; j < 96; j++)
      for (int i = 0; i < 200; i++) {
        const vdb::Coord c(i, j, k);
        const float x = std::sin(0.37f * (float)i) * std::cos(0.11f * (float)j) + 0.01f * (float)k;
        if (x < -0.6f) continue;                       /* background */
        if (x < -0.5f) acc.setValueOff(c, ValueT(2.0f)); /* a second inactive value */
        else acc.setValueOn(c, tree_value(x, rgb, (ValueT *)nullptr));
      }
  return t;
}

/* The leaf buffers `bytes` read back by OpenVDB into a copy of tree whose
 * values were all set to `mark` first. */
template <typename TreeT>
static typename TreeT::Ptr read_leaves(const TreeT &tree, const std::string &bytes,
                                       uint32_t compression, bool half, float mark) {
  using ValueT = typename TreeT::ValueType;
  const ValueT bg = tree.background();
  typename TreeT::Ptr t(new TreeT(tree));
  for (auto it = t->beginLeaf(); it; ++it) it->fill(ValueT(mark));
  std::istringstream is(bytes, std::ios_base::binary);
  vdb::io::setCurrentVersion(is);
  vdb::io::setDataCompression(is, compression);
  vdb::io::setGridBackgroundValuePtr(is, &bg);
  t->readBuffers(is, half);
  CHECK(is.peek() == EOF, "%zu bytes left after the leaves", bytes.size() - (size_t)is.tellg());
  return t;
}

/* vdbio_write_leaves against Tree::writeBuffers on one stream setting: the
 * same bytes, except where `grey` (a Vec3 tree of equal channels, Blosc:
 * vdbio_write_grey_leaf), where OpenVDB must read back the same leaves from
 * fewer bytes. */
template <typename TreeT>
static void compare_leaf_bytes(const char *label, const TreeT &tree, uint32_t compression,
                               bool half, bool grey = false) {
  const typename TreeT::ValueType bg = tree.background();
  std::ostringstream serial(std::ios_base::binary), parallel(std::ios_base::binary);
  for (std::ostringstream *s : {&serial, &parallel}) {
    vdb::io::setDataCompression(*s, compression);
    vdb::io::setGridBackgroundValuePtr(*s, &bg);
  }
  tree.TreeT::writeBuffers(serial, half);
  vdbio_write_leaves(tree, parallel, half);
  const std::string a = serial.str(), b = parallel.str();
  if (!(grey && (compression & vdb::io::COMPRESS_BLOSC))) {
    CHECK(a == b, "%s, compression %u, half %d: %zu bytes serial, %zu parallel, or the same "
          "count and other bytes", label, compression, (int)half, a.size(), b.size());
    return;
  }
  CHECK(b.size() < a.size() / 2, "%s, blosc: %zu bytes against OpenVDB's %zu", label, b.size(),
        a.size());
  auto want = read_leaves(tree, a, compression, half, 7.0f);
  auto got = read_leaves(tree, b, compression, half, -7.0f);
  size_t leaves = 0, differ = 0;
  for (auto g = got->cbeginLeaf(), w = want->cbeginLeaf(); g && w; ++g, ++w, ++leaves) {
    differ += g->getValueMask() != w->getValueMask();
    for (vdb::Index i = 0; i < g->SIZE; i++) differ += !same_value(g->getValue(i), w->getValue(i));
  }
  CHECK(leaves == tree.leafCount() && differ == 0, "%s, blosc: %zu of %zu leaves read, %zu "
        "values or masks differ", label, leaves, (size_t)tree.leafCount(), differ);
}

static void test_leaf_bytes() {
  auto f = many_leaves<vdb::FloatTree>(0.5f);
  auto v = many_leaves<vdb::Vec3STree>(0.0f);
  auto rgb = many_leaves<vdb::Vec3STree>(0.0f, true);
  CHECK(f->leafCount() > 2 * VDBIO_WRITE_WINDOW, "only %u leaves", (unsigned)f->leafCount());
  std::vector<uint32_t> modes = {vdb::io::COMPRESS_NONE, vdb::io::COMPRESS_ACTIVE_MASK,
                                 vdb::io::COMPRESS_ZIP | vdb::io::COMPRESS_ACTIVE_MASK};
  if (vdb::io::Archive::hasBloscCompression())
    modes.push_back(vdb::io::COMPRESS_BLOSC | vdb::io::COMPRESS_ACTIVE_MASK);
  for (uint32_t m : modes)
    for (bool half : {false, true}) {
      compare_leaf_bytes("float", *f, m, half);
      compare_leaf_bytes("vec3s, grey", *v, m, half, true);
      compare_leaf_bytes("vec3s, rgb", *rgb, m, half);
    }
}

/* baker's own file of `count` grids over nx x ny x nz; false (a failed
 * check) when it cannot be written. */
static bool write_grids(const std::string &path, const vdbio_grid_t *grids, int count, int nx,
                        int ny, int nz, vdbio_compression_t compression) {
  grid_dims_t d = {};
  d.nx = nx, d.ny = ny, d.nz = nz;
  d.voxel_size = 0.1f;
  vdbio_write_opts_t opts = {};
  opts.compression = compression;
  bk_error_t err = {};
  const int rc = vdbio_write(path.c_str(), &d, grids, count, NULL, 0, &opts, &err);
  CHECK(rc == BK_OK, "vdbio_write %s: %s", path.c_str(), err.msg);
  return rc == BK_OK;
}

/* Sparse leaves: 3 in 7 of the 8^3 blocks of a box that is not a whole
 * number of them hold varying values, the rest background, so the leaves
 * of a write window fill less than half the box of their cells and are
 * made over runs of one to a few neighbours (vdbio_window_fill). Written
 * from a dense array and from a fill (the made-on-the-fly path), float and
 * Vec3, each against copyFromDense. */
enum { SX = 70, SY = 41, SZ = 50 };

static float sparse_value(size_t at, int c) {
  const int i = (int)(at % SX), j = (int)(at / SX % SY), k = (int)(at / SX / SY);
  const int bi = i / 8, bj = j / 8, bk = k / 8; /* runs of 1 to 4 blocks along x */
  return (bi * bi + 3 * bj * bi + 5 * bk + 2 * bj + bk * bi) % 7 < 3 ? 1.0f + 0.001f * (float)(i + 3 * j + 7 * k) + 0.1f * (float)c : 0.0f;
}

static void sparse_fill(const void *ctx, size_t lo, size_t hi, float *out) {
  const int ch = *static_cast<const int *>(ctx);
  for (size_t at = lo; at < hi; at++)
    for (int c = 0; c < ch; c++) *out++ = sparse_value(at, c);
}

static void test_sparse_windows(const std::string &dir) {
  const size_t n = (size_t)SX * SY * SZ;
  std::vector<float> f(n), v(3 * n);
  for (size_t at = 0; at < n; at++) {
    f[at] = sparse_value(at, 0);
    for (int c = 0; c < 3; c++) v[3 * at + c] = sparse_value(at, c);
  }
  static const int one = 1, three = 3;
  const vdbio_grid_t grids[] = {{"data", VDBIO_FLOAT, f.data(), 0, 0.0f, NULL, NULL, 0},
                                {"fill", VDBIO_FLOAT, NULL, 0, 0.0f, sparse_fill, &one, 0},
                                {"fill3", VDBIO_VEC3, NULL, 1, 0.0f, sparse_fill, &three, 0}};
  const std::string path = dir + "/sparse.vdb";
  if (!write_grids(path, grids, 3, SX, SY, SZ, VDBIO_COMPRESS_ZIP))
    return;
  vdb::io::File file(path);
  file.open();
  auto want = reference<vdb::FloatGrid>(f, 0.0f, SX, SY, SZ);
  CHECK(want->tree().leafCount() * 2 < (size_t)9 * 6 * 7, "%u leaves: not sparse",
        (unsigned)want->tree().leafCount());
  compare("sparse data", *vdb::gridPtrCast<vdb::FloatGrid>(file.readGrid("data")), *want, SX, SY,
          SZ);
  compare("sparse fill", *vdb::gridPtrCast<vdb::FloatGrid>(file.readGrid("fill")), *want, SX, SY,
          SZ);
  compare("sparse fill Vec3", *vdb::gridPtrCast<vdb::Vec3SGrid>(file.readGrid("fill3")),
          *reference<vdb::Vec3SGrid>(v, 0.0f, SX, SY, SZ), SX, SY, SZ);
  file.close();
}

/* A grey Vec3 grid (vdbio_grid_t.grey: one float per voxel, from an array
 * and from a fill) is the RGB grid of its three equal channels: the tree
 * copyFromDense builds from that RGB array, and the checksum of the same
 * RGB array written as such. value_at's channel 0 has what the two paths
 * could disagree on: tiles, holes, -0 and NaN, and the box's ragged edge. */
static void grey_fill(const void *ctx, size_t lo, size_t hi, float *out) {
  const float *g = static_cast<const float *>(ctx);
  for (size_t at = lo; at < hi; at++) *out++ = g[at];
}

static void test_grey_grids(const std::string &dir) {
  const size_t n = (size_t)NX * NY * NZ;
  std::vector<float> grey(n), rgb(3 * n);
  for (int k = 0, at = 0; k < NZ; k++)
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++, at++) {
        grey[(size_t)at] = value_at(i, j, k, 0);
        for (int c = 0; c < 3; c++) rgb[3 * (size_t)at + (size_t)c] = grey[(size_t)at];
      }
  const float bg = 2.0f;
  const vdbio_grid_t grids[] = {{"rgb", VDBIO_VEC3, rgb.data(), 1, bg, NULL, NULL, 0},
                                {"grey", VDBIO_VEC3, grey.data(), 1, bg, NULL, NULL, 1},
                                {"grey_fill", VDBIO_VEC3, NULL, 1, bg, grey_fill, grey.data(), 1}};
  const std::string path = dir + "/grey.vdb";
  if (!write_grids(path, grids, 3, NX, NY, NZ, VDBIO_COMPRESS_BLOSC)) return;
  vdb::io::File file(path);
  file.open();
  auto want = reference<vdb::Vec3SGrid>(rgb, bg);
  for (const char *name : {"rgb", "grey", "grey_fill"})
    compare(name, *vdb::gridPtrCast<vdb::Vec3SGrid>(file.readGrid(name)), *want);
  vdb::MetaMap::Ptr meta = file.getMetadata();
  const std::string ck = meta->metaValue<std::string>("checksum_v2_rgb");
  CHECK(meta->metaValue<std::string>("checksum_v2_grey") == ck &&
            meta->metaValue<std::string>("checksum_v2_grey_fill") == ck,
        "grey checksums %s, %s against the RGB grid's %s",
        meta->metaValue<std::string>("checksum_v2_grey").c_str(),
        meta->metaValue<std::string>("checksum_v2_grey_fill").c_str(), ck.c_str());
  file.close();
}

/* vdbio_read_dense of `name` in path equals want (nx x ny x nz, ch floats
 * per voxel, x fastest) everywhere. */
static void compare_dense(const char *label, const std::string &path, const char *name,
                          const std::vector<float> &want, int nx, int ny, int nz, int ch) {
  vdbio_dense_t d = {};
  bk_error_t err = {};
  if (vdbio_read_dense(path.c_str(), name, 0, &d, &err) != BK_OK) {
    CHECK(false, "%s: vdbio_read_dense: %s", label, err.msg);
    return;
  }
  CHECK(d.nx == nx && d.ny == ny && d.nz == nz && d.channels == ch, "%s: %dx%dx%d x %d", label,
        d.nx, d.ny, d.nz, d.channels);
  size_t bad = 0, n = (size_t)nx * ny * nz * ch;
  for (size_t at = 0; d.nx == nx && d.ny == ny && d.nz == nz && at < n; at++)
    bad += !same_value(d.data[at], want[at]);
  CHECK(bad == 0, "%s: %zu of %zu values differ", label, bad, n);
  vdbio_dense_free(&d);
}

static void test_dense_slabs(const std::string &dir) {
  /* baker's own file, 150 slices deep (three slabs), its x and y edges in
   * leaves that reach outside the box; corners set so the box is the array */
  const int nx = 21, ny = 18, nz = 150;
  const size_t n = (size_t)nx * ny * nz;
  std::vector<float> f(n), v(3 * n);
  for (size_t at = 0; at < n; at++) {
    const int i = (int)(at % nx), j = (int)(at / nx % ny), k = (int)(at / nx / ny);
    const float x = (i / 8 + j / 8 + k / 8) % 3 == 0 ? 0.0f : 1.0f + 0.001f * (float)(i + 7 * j + 31 * k);
    f[at] = at == 0 || at == n - 1 ? 2.0f : x;
    for (int c = 0; c < 3; c++) v[3 * at + c] = f[at] + 0.5f * (float)c;
  }
  const vdbio_grid_t grids[] = {{"f", VDBIO_FLOAT, f.data(), 0, 0.0f, NULL, NULL, 0},
                                {"v", VDBIO_VEC3, v.data(), 1, 0.0f, NULL, NULL, 0}};
  const std::string own = dir + "/slabs.vdb";
  if (!write_grids(own, grids, 2, nx, ny, nz, VDBIO_COMPRESS_BLOSC))
    return;
  compare_dense("slabs float", own, "f", f, nx, ny, nz, 1);
  compare_dense("slabs Vec3", own, "v", v, nx, ny, nz, 3);

  /* OpenVDB's: z from -13 to 150, x from -5, background 0.5, an 8^3 tile */
  vdb::FloatGrid::Ptr g = vdb::FloatGrid::create(0.5f);
  g->setName("g");
  auto acc = g->getAccessor();
  const vdb::Coord lo(-5, 3, -13), hi(30, 20, 150);
  for (int k = lo.z(); k <= hi.z(); k += 3)
    for (int j = lo.y(); j <= hi.y(); j += 2)
      for (int i = lo.x(); i <= hi.x(); i += 5) acc.setValue(vdb::Coord(i, j, k), 0.01f * (float)(i + j + k));
  acc.setValue(lo, 7.0f);
  acc.setValue(hi, 8.0f);
  g->tree().fill(vdb::CoordBBox(vdb::Coord(8, 8, 64), vdb::Coord(15, 15, 71)), 3.0f, true);
  const std::string other = dir + "/slabs_openvdb.vdb";
  vdb::io::File out(other);
  out.write({g});
  out.close();
  const vdb::Coord dim = hi - lo + vdb::Coord(1);
  std::vector<float> want((size_t)dim.x() * dim.y() * dim.z());
  for (int k = 0; k < dim.z(); k++)
    for (int j = 0; j < dim.y(); j++)
      for (int i = 0; i < dim.x(); i++)
        want[(size_t)i + (size_t)dim.x() * ((size_t)j + (size_t)dim.y() * k)] =
            acc.getValue(lo.offsetBy(i, j, k));
  compare_dense("slabs OpenVDB's", other, "g", want, dim.x(), dim.y(), dim.z(), 1);
}

/* Vec3f grids read with `grey`: one whose channels agree everywhere comes
 * back as one channel, ones that differ in one voxel (in the first slab, in
 * the last) as three with every value exact, each checksum checked on the
 * way (vdbio_read_dense_verified_all). */
static void test_dense_grey(const std::string &dir) {
  const int nx = 19, ny = 10, nz = 150;
  const size_t n = (size_t)nx * ny * nz;
  std::vector<float> grey(3 * n), first, last;
  for (size_t at = 0; at < n; at++)
    for (int c = 0; c < 3; c++)
      grey[3 * at + c] = (at / nx / ny) % 9 == 4 ? 0.0f : 1.0f + 0.01f * (float)(at % 97);
  first = last = grey;
  first[3 * 5 + 2] += 0.5f;             /* slice 0 */
  last[3 * (n - nx * ny + 3) + 1] = 0.25f; /* slice 149 */
  const vdbio_grid_t grids[] = {{"grey", VDBIO_VEC3, grey.data(), 1, 0.0f, NULL, NULL, 0},
                                {"first", VDBIO_VEC3, first.data(), 1, 0.0f, NULL, NULL, 0},
                                {"last", VDBIO_VEC3, last.data(), 1, 0.0f, NULL, NULL, 0}};
  const std::string path = dir + "/grey.vdb";
  if (!write_grids(path, grids, 3, nx, ny, nz, VDBIO_COMPRESS_BLOSC))
    return;
  bk_error_t err = {};
  const char *names[3] = {"grey", "first", "last"};
  const int want_ch[3] = {1, 3, 3}, ask[3] = {1, 1, 1};
  const std::vector<float> *want[3] = {&grey, &first, &last};
  vdbio_dense_t out[3];
  int checked[3];
  if (vdbio_read_dense_verified_all(path.c_str(), 3, names, ask, out, checked, NULL, NULL,
                                    &err) != BK_OK) {
    CHECK(false, "grey read: %s", err.msg);
    return;
  }
  for (int g = 0; g < 3; g++) {
    const int ch = out[g].channels;
    CHECK(ch == want_ch[g] && checked[g] == 1 && out[g].nz == nz, "grey read %s: %d channels, "
          "checked %d", names[g], ch, checked[g]);
    size_t bad = 0;
    for (size_t at = 0; ch == want_ch[g] && out[g].nz == nz && at < n * ch; at++)
      bad += !same_value(out[g].data[at], (*want[g])[ch == 1 ? 3 * at : at]);
    CHECK(bad == 0, "grey read %s: %zu values differ", names[g], bad);
    vdbio_dense_free(&out[g]);
  }
}

int main(int argc, char **argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: test_vdbio_tree DIR\n");
    return 2;
  }
  vdb::initialize();
  const std::string path = std::string(argv[1]) + "/tree.vdb";
  std::vector<float> f((size_t)NX * NY * NZ), v((size_t)3 * NX * NY * NZ);
  for (int k = 0; k < NZ; k++)
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++) {
        size_t at = (size_t)i + (size_t)NX * ((size_t)j + (size_t)NY * k);
        f[at] = value_at(i, j, k, 0);
        for (int c = 0; c < 3; c++) v[3 * at + c] = value_at(i, j, k, c);
      }
  grid_dims_t d = {};
  d.nx = NX, d.ny = NY, d.nz = NZ;
  d.voxel_size = 0.1f;
  const vdbio_grid_t grids[] = {{"f0", VDBIO_FLOAT, f.data(), 0, 0.0f, NULL, NULL, 0},
                                {"f1", VDBIO_FLOAT, f.data(), 0, 1.0f, NULL, NULL, 0},
                                {"v0", VDBIO_VEC3, v.data(), 1, 0.0f, NULL, NULL, 0}};
  vdbio_write_opts_t opts = {};
  opts.compression = VDBIO_COMPRESS_NONE;
  bk_error_t err = {};
  if (vdbio_write(path.c_str(), &d, grids, 3, NULL, 0, &opts, &err) != BK_OK) {
    std::fprintf(stderr, "vdbio_write: %s\n", err.msg);
    return 1;
  }
  vdb::io::File file(path);
  file.open();
  compare("f0", *vdb::gridPtrCast<vdb::FloatGrid>(file.readGrid("f0")),
          *reference<vdb::FloatGrid>(f, 0.0f));
  compare("f1 (background 1)", *vdb::gridPtrCast<vdb::FloatGrid>(file.readGrid("f1")),
          *reference<vdb::FloatGrid>(f, 1.0f));
  compare("v0", *vdb::gridPtrCast<vdb::Vec3SGrid>(file.readGrid("v0")),
          *reference<vdb::Vec3SGrid>(v, 0.0f));
  file.close();
  test_leaf_bytes();
  test_sparse_windows(argv[1]);
  test_grey_grids(argv[1]);
  test_dense_slabs(argv[1]);
  test_dense_grey(argv[1]);
  if (failures) std::fprintf(stderr, "test_vdbio_tree: %d check(s) failed\n", failures);
  else std::printf("test_vdbio_tree: ok\n");
  return failures ? 1 : 0;
}
