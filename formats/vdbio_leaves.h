/* vdbio_leaves.h: a grid's leaf buffers compressed on every core.
 *
 * OpenVDB writes a tree's data blocks (Tree::writeBuffers) leaf after leaf,
 * depth first, each compressed on the writing thread (LeafNode::writeBuffers:
 * the value mask, then io::writeCompressedValues: mask compression, then
 * Zip or Blosc); at 256^3 that was most of the write stage.
 * vdbio_write_leaves writes the same bytes in the same order: the leaves (in
 * the leaf iterator's order, which is writeBuffers' own) in windows of
 * VDBIO_WRITE_WINDOW, each thread writing runs of a window into buffers that
 * carry the stream's compression and background, the buffers then written
 * in order while the next window is compressed; at most two windows'
 * buffers are in memory. vdbio_parallel_tree is
 * a tree that writes its buffers so, for Archive's writer to call. Checked
 * byte for byte against OpenVDB's own by test_vdbio_tree, but for one
 * deliberate difference: under Blosc, a Vec3 leaf whose channels are equal
 * is compressed in larger elements (vdbio_write_grey_leaf), which
 * test_vdbio_tree reads back through OpenVDB instead.
 *
 * A leaf may also come without values (made with PartialCreate: its value
 * mask only, the buffer never allocated): the tree's `values` function then
 * gives a whole window's values at once (vdbio_write.cpp reads the grid in
 * rows across neighbouring leaves) into a window of scratch leaves, each
 * written in its leaf's place with that leaf's mask, so a grid's values
 * exist twice only a window at a time. */
#ifndef BAKER_VDBIO_LEAVES_H
#define BAKER_VDBIO_LEAVES_H

#include <blosc.h>
#include <openvdb/openvdb.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

static const size_t VDBIO_WRITE_WINDOW = 2048; /* leaves: 4-12 MB of values */
static const size_t VDBIO_WRITE_RUN = 64;      /* leaves per buffer */

/* The values of leaves[0..n) into out[0..n), LeafT::SIZE each (inactive
 * voxels: anything). */
template <typename LeafT>
using vdbio_window_values = std::function<void(const LeafT *const *leaves, size_t n,
                                               typename LeafT::ValueType *const *out)>;

/* An output stream's bytes appended to a string the caller reserved and
 * then takes whole (std::ostringstream grows by copying and copies again
 * in str(): twice more a grid's bytes). */
class vdbio_string_buf : public std::streambuf {
public:
  explicit vdbio_string_buf(size_t reserve) { bytes.reserve(reserve); }
  std::string bytes;

protected:
  std::streamsize xsputn(const char *s, std::streamsize n) override {
    bytes.append(s, (size_t)n);
    return n;
  }
  int_type overflow(int_type ch) override {
    if (!traits_type::eq_int_type(ch, traits_type::eof()))
      bytes.push_back(traits_type::to_char_type(ch));
    return traits_type::not_eof(ch);
  }
};

/* Blosc's element size for a Vec3 leaf whose three channels are equal
 * everywhere: grey light written as the RGB grid `radiance`, and its
 * `emission` in a grey medium. OpenVDB's bloscToStream shuffles 4-byte
 * elements, which leaves each byte's three equal copies side by side, too
 * short for LZ4's matches, and splits the shuffled block per byte plane;
 * with two Vec3s per element the equal channels' planes repeat whole and
 * nothing is split (Blosc splits elements of at most 16 bytes). Measured on
 * the sphere's radiance at 256^3 (docs/bench.md): 46 MB instead of 123 MB,
 * in about half the time. Any Blosc decoder reads it back: the element size
 * and shuffle are in each buffer's header. */
static const int VDBIO_GREY_TYPESIZE = 24;

/* Whether the three channels of every value of the leaf are equal (bit for
 * bit; the test only picks the element size, both decode the same). */
template <typename LeafT> static bool vdbio_equal_channels(const LeafT &leaf) {
  const uint32_t *v = reinterpret_cast<const uint32_t *>(leaf.buffer().data());
  uint32_t differ = 0;
  for (size_t i = 0; i < 3 * (size_t)LeafT::SIZE; i += 3)
    differ |= (v[i] ^ v[i + 1]) | (v[i] ^ v[i + 2]);
  return differ == 0;
}

/* The leaf's buffers, the bytes of LeafNode::writeBuffers with Blosc but its
 * values compressed in VDBIO_GREY_TYPESIZE elements. A leaf whose voxels are
 * all active (in full floats) is its value mask, the mask compression's
 * flag saying so and its values. Any other leaf is first written by
 * OpenVDB's own writer without the Blosc step, into `raw`: the value mask,
 * the flag, inactive values and selection mask, then the values raw (as
 * half floats with to_half: 4 Vec3s per element then), the last of those
 * bytes.
 * The values then go through Blosc as bloscToStream sends them (a 64-bit
 * size, negative for values stored raw where Blosc cannot compress them).
 * Returns false, having written nothing, where the leaf is not grey or the
 * stream is not Blosc's: OpenVDB's writer then writes it. */
template <typename LeafT>
static bool vdbio_write_grey_leaf(const LeafT &leaf, std::ostream &os, bool to_half,
                                  uint32_t compression, const void *background,
                                  vdbio_string_buf &raw, std::vector<char> &packed) {
  namespace io = openvdb::io;
  using ValueT = typename LeafT::ValueType;
  if (!(compression & io::COMPRESS_BLOSC) || !vdbio_equal_channels(leaf)) return false;
  const size_t value_bytes =
      to_half ? sizeof(typename io::RealToHalf<ValueT>::HalfT) : sizeof(ValueT);
  const typename LeafT::NodeMaskType &mask = leaf.getValueMask();
  const char *head, *values;
  size_t head_bytes, bytes;
  const int8_t all_active = io::NO_MASK_OR_INACTIVE_VALS;
  if (!to_half && (compression & io::COMPRESS_ACTIVE_MASK) && mask.isOn()) {
    raw.bytes.assign(mask.memUsage(), '\xff'); /* the mask's words, every bit on */
    raw.bytes.append(reinterpret_cast<const char *>(&all_active), 1);
    head = raw.bytes.data();
    head_bytes = raw.bytes.size();
    values = reinterpret_cast<const char *>(leaf.buffer().data());
    bytes = LeafT::SIZE * sizeof(ValueT);
  } else {
    raw.bytes.clear();
    std::ostream plain(&raw);
    io::setDataCompression(plain, compression & ~(uint32_t)io::COMPRESS_BLOSC);
    io::setGridBackgroundValuePtr(plain, background);
    leaf.writeBuffers(plain, to_half);
    const size_t flag_at = mask.memUsage();
    /* readCompressedValues' rule: all SIZE values, or the active ones */
    const bool all = (int8_t)raw.bytes[flag_at] == io::NO_MASK_AND_ALL_VALS;
    bytes = (all ? LeafT::SIZE : mask.countOn()) * value_bytes;
    if (bytes == 0 || raw.bytes.size() < flag_at + 1 + bytes) return false;
    head = raw.bytes.data();
    head_bytes = raw.bytes.size() - bytes;
    values = head + head_bytes;
  }
  packed.resize(bytes + BLOSC_MAX_OVERHEAD);
  const int n = blosc_compress_ctx(9, BLOSC_SHUFFLE, VDBIO_GREY_TYPESIZE, bytes, values,
                                   packed.data(), packed.size(), BLOSC_LZ4_COMPNAME, bytes, 1);
  const int64_t size = n > 0 ? (int64_t)n : -(int64_t)bytes;
  os.write(head, (std::streamsize)head_bytes);
  os.write(reinterpret_cast<const char *>(&size), sizeof size);
  os.write(n > 0 ? packed.data() : values, n > 0 ? (std::streamsize)n : (std::streamsize)bytes);
  return true;
}

/* One leaf's buffers onto a run's stream: grey Vec3 leaves by
 * vdbio_write_grey_leaf, every other one by OpenVDB's writer. */
template <typename LeafT>
static void vdbio_write_leaf(const LeafT &leaf, std::ostream &os, bool to_half,
                             uint32_t compression, const void *background,
                             vdbio_string_buf &raw, std::vector<char> &packed) {
  if constexpr (std::is_same<typename LeafT::ValueType, openvdb::Vec3s>::value)
    if (vdbio_write_grey_leaf(leaf, os, to_half, compression, background, raw, packed)) return;
  leaf.writeBuffers(os, to_half);
}

/* scratch, already holding leaf's values, takes leaf's mask; its voxels off
 * in the mask become zero, as the leaf's own buffer would hold them. */
template <typename LeafT> static void vdbio_take_mask(const LeafT &leaf, LeafT &scratch) {
  using ValueT = typename LeafT::ValueType;
  const typename LeafT::NodeMaskType &mask = leaf.getValueMask();
  scratch.setValueMask(mask);
  ValueT *buf = scratch.buffer().data();
  for (auto off = mask.beginOff(); off; ++off) buf[off.pos()] = openvdb::zeroVal<ValueT>();
}

template <typename TreeT>
void vdbio_write_leaves(const TreeT &tree, std::ostream &os, bool to_half,
                        const vdbio_window_values<typename TreeT::LeafNodeType> &values = nullptr) {
  using LeafT = typename TreeT::LeafNodeType;
  std::vector<const LeafT *> leaves;
  leaves.reserve(tree.leafCount());
  for (auto it = tree.cbeginLeaf(); it; ++it) leaves.push_back(it.getLeaf());
  const uint32_t compression = openvdb::io::getDataCompression(os);
  const void *background = openvdb::io::getGridBackgroundValuePtr(os);
  /* the runs of window w, compressed on every core into runs[w % 2] */
  std::vector<std::string> runs[2];
  /* where `values` gives them, the window's values, made straight into
   * scratch leaves written in the leaves' place (one window is compressed
   * at a time) */
  std::vector<std::unique_ptr<LeafT>> scratch;
  std::vector<typename LeafT::ValueType *> given;
  if (values) {
    scratch.resize(std::min(leaves.size(), VDBIO_WRITE_WINDOW));
    for (auto &leaf : scratch) {
      leaf.reset(new LeafT);
      given.push_back(leaf->buffer().data());
    }
  }
  auto compress = [&](size_t w) {
    const size_t end = std::min(leaves.size(), w + VDBIO_WRITE_WINDOW);
    std::vector<std::string> &out = runs[(w / VDBIO_WRITE_WINDOW) % 2];
    if (values) values(leaves.data() + w, end - w, given.data());
    out.assign((end - w + VDBIO_WRITE_RUN - 1) / VDBIO_WRITE_RUN, std::string());
    tbb::parallel_for(size_t(0), out.size(), [&](size_t r) {
      const size_t lo = w + r * VDBIO_WRITE_RUN, hi = std::min(end, lo + VDBIO_WRITE_RUN);
      /* a leaf's values with its masks and headers: room for most runs */
      vdbio_string_buf bytes((hi - lo) * (sizeof(typename LeafT::ValueType) * LeafT::SIZE + 256));
      std::ostream run(&bytes);
      openvdb::io::setDataCompression(run, compression);
      openvdb::io::setGridBackgroundValuePtr(run, background);
      vdbio_string_buf raw(sizeof(typename LeafT::ValueType) * LeafT::SIZE + 256);
      std::vector<char> packed;
      for (size_t i = lo; i < hi; i++) {
        const LeafT *leaf = leaves[i];
        if (values && leaf->buffer().empty()) {
          vdbio_take_mask(*leaves[i], *scratch[i - w]);
          leaf = scratch[i - w].get();
        }
        vdbio_write_leaf(*leaf, run, to_half, compression, background, raw, packed);
      }
      out[r] = std::move(bytes.bytes);
    });
  };
  if (!leaves.empty()) compress(0);
  /* a window is written while the next one is compressed: the stream
   * takes one thread, the compression the others (and the writer's, once
   * it has written) */
  for (size_t w = 0; w < leaves.size(); w += VDBIO_WRITE_WINDOW) {
    tbb::task_group next;
    if (w + VDBIO_WRITE_WINDOW < leaves.size())
      next.run([&, w] { compress(w + VDBIO_WRITE_WINDOW); });
    for (const std::string &r : runs[(w / VDBIO_WRITE_WINDOW) % 2])
      os.write(r.data(), (std::streamsize)r.size());
    next.wait();
  }
}

template <typename TreeT> class vdbio_parallel_tree : public TreeT {
public:
  explicit vdbio_parallel_tree(const typename TreeT::ValueType &background) : TreeT(background) {}
  void writeBuffers(std::ostream &os, bool to_half) const override {
    vdbio_write_leaves(static_cast<const TreeT &>(*this), os, to_half, values);
  }
  /* the values of leaves made without them (set before the tree is written) */
  vdbio_window_values<typename TreeT::LeafNodeType> values;
};

#endif
