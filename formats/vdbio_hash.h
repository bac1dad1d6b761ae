/* vdbio_hash.h: the hash of a grid's values under the checksum rules of
 * vdbio.h, fed its values in box order (z slices, x fastest) by the writer
 * (vdbio_write.cpp, slab by slab as it builds each tree) and by the checker
 * (vdbio_checksum.cpp, from the values read back). C++ only. */
#ifndef BAKER_VDBIO_HASH_H
#define BAKER_VDBIO_HASH_H

#include <openvdb/Types.h>

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

static const uint64_t CK_OFFSET = 14695981039346656037ull, CK_PRIME = 1099511628211ull;
static const uint32_t CK_OFFSET32 = 2166136261u, CK_PRIME32 = 16777619u;

/* One value's bits under the rules of vdbio.h. */
static inline uint32_t ck_bits(float v, bool half) {
  if (half) v = static_cast<float>(openvdb::math::half(v));
  if (v == 0.0f) v = 0.0f; /* -0 -> +0 */
  uint32_t u;
  std::memcpy(&u, &v, sizeof u);
  return u;
}

/* The lane rule's word: the bits, or 0 for +-0 and NaN (a voxel of such
 * values is stored as inactive background and reads back as 0). */
static inline uint32_t ck_word(uint32_t u) {
  return (u & 0x7fffffffu) - 1u < 0x7f800000u ? u : 0u;
}

/* A grid's hash under either rule (vdbio.h), fed its values in box order. */
class ck_hasher {
public:
  explicit ck_hasher(bool lanes) : lanes_(lanes) {
    for (int j = 0; j < 8; j++) lane_[j] = CK_OFFSET32;
  }

  void add(const float *data, size_t voxels, int ch, bool half) {
    if (!lanes_) {
      serial_ = serial(data, voxels, ch, half, serial_);
      return;
    }
    const size_t words = voxels * (size_t)ch;
    size_t i = 0;
    auto one = [&](size_t k) {
      uint32_t u;
      std::memcpy(&u, data + k, sizeof u);
      if (half) u = ck_bits(data[k], true);
      lane_[pos_] = (lane_[pos_] ^ ck_word(u)) * CK_PRIME32;
      pos_ = (pos_ + 1) & 7;
    };
    while (i < words && pos_ != 0) one(i++);
    if (!half) i = lanes8(data, i, words);
    while (i < words) one(i++);
  }

  /* add() of `voxels` values each repeated ch times (a grey Vec3 grid's
   * (v, v, v): vdbio.h), through a small buffer instead of the grid's RGB
   * copy. */
  void add_spread(const float *data, size_t voxels, int ch, bool half) {
    /* 1024 voxels a call for up to 3 channels (the checksums written so
     * far), fewer for more, so that the buffer always holds them */
    float rgb[3 * 1024];
    const size_t chunk = ch <= 3 ? 1024 : sizeof rgb / sizeof rgb[0] / (size_t)ch;
    for (size_t i = 0; i < voxels; i += chunk) {
      const size_t n = std::min(chunk, voxels - i);
      for (size_t k = 0; k < n; k++)
        for (int c = 0; c < ch; c++) rgb[(size_t)ch * k + (size_t)c] = data[i + k];
      add(rgb, n, ch, half);
    }
  }

  /* The grid's background (its value outside the box, the same in every
   * channel when written) ends the hash, so that a changed background is a
   * changed checksum. */
  uint64_t finish(const float *bg, int ch) const {
    uint64_t h = lanes_ ? CK_OFFSET : serial_;
    for (int j = 0; lanes_ && j < 8; j++) h = (h ^ lane_[j]) * CK_PRIME;
    for (int c = 0; c < ch; c++) h = (h ^ ck_bits(bg[c], false)) * CK_PRIME;
    return h;
  }

private:
  /* the legacy rule: FNV-1a over 32-bit words, one chain */
  static uint64_t serial(const float *data, size_t voxels, int ch, bool half, uint64_t h) {
    for (size_t i = 0; i < voxels; i++) {
      const float *v = data + i * (size_t)ch;
      bool background = true; /* copyFromDense's test at tolerance 0 */
      for (int c = 0; c < ch; c++) background = background && !(std::fabs(v[c]) > 0.0f);
      for (int c = 0; c < ch; c++) {
        h ^= background ? 0u : ck_bits(v[c], half);
        h *= CK_PRIME;
      }
    }
    return h;
  }

  /* Words [i, words) eight at a time from lane 0 (GCC/Clang vectors: the
   * eight chains are independent, so this runs at memory speed); returns
   * where it stopped. */
  size_t lanes8(const float *data, size_t i, size_t words) {
    typedef uint32_t v4 __attribute__((vector_size(16)));
    v4 a, b;
    std::memcpy(&a, lane_, sizeof a);
    std::memcpy(&b, lane_ + 4, sizeof b);
    const v4 sign = {0x7fffffffu, 0x7fffffffu, 0x7fffffffu, 0x7fffffffu};
    const v4 inf = {0x7f800000u, 0x7f800000u, 0x7f800000u, 0x7f800000u};
    const v4 one = {1u, 1u, 1u, 1u};
    for (; i + 8 <= words; i += 8) {
      v4 x, y;
      std::memcpy(&x, data + i, sizeof x);
      std::memcpy(&y, data + i + 4, sizeof y);
      x &= (v4)((x & sign) - one < inf); /* ck_word: -1 where kept */
      y &= (v4)((y & sign) - one < inf);
      a = (a ^ x) * CK_PRIME32;
      b = (b ^ y) * CK_PRIME32;
    }
    std::memcpy(lane_, &a, sizeof a);
    std::memcpy(lane_ + 4, &b, sizeof b);
    return i;
  }

  bool lanes_;
  uint64_t serial_ = CK_OFFSET;
  uint32_t lane_[8];
  unsigned pos_ = 0; /* the lane of the next word */
};

static inline std::string ck_hex(uint64_t h) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%016" PRIx64, h);
  return buf;
}

#endif
