// mesh_prescan_binary.cpp: the pre-scan of binary OFF and PLY bodies
// (mesh_prescan.h).
//
// OpenMesh 9 trusts a binary body's counts: it reserves memory for the
// header's vertex and face counts before it reads a vertex, and reads as
// many entries as a face's count says, past the file's end, keeping each
// (a count of -1 is four billion reads). So the body is walked here first,
// value by value as OpenMesh will walk it, and every count must fit in the
// bytes that follow it. Messages name the byte offset in the file.
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "mesh_prescan.h"

namespace {

// A cursor over a binary body; `at` is the file offset of `p`.
struct body_cursor {
  const unsigned char *p, *end;
  size_t at;
  bool big_endian;
  size_t left() const { return (size_t)(end - p); }
  void skip(size_t n) {
    p += n;
    at += n;
  }
  // An integer of `bytes` bytes (1, 2, 4 or 8); the caller checked left().
  int64_t take(int bytes, bool is_signed) {
    uint64_t u = 0;
    for (int k = 0; k < bytes; k++) {
      const unsigned byte = big_endian ? p[k] : p[bytes - 1 - k];
      u = (u << 8) | byte;
    }
    skip((size_t)bytes);
    if (is_signed && bytes < 8 && (u >> (8 * bytes - 1)) & 1) u |= ~0ull << (8 * bytes);
    return (int64_t)u;
  }
};

// " byte N: ", to follow "path:" (N: the file offset of what is named).
std::string at_text(size_t at) {
  return " byte " + std::to_string(at) + ": ";
}

bool ends_early(const body_cursor &b, const std::string &who, std::string *msg) {
  *msg = at_text(b.at) + "the binary body ends inside " + who;
  return false;
}

// A list's count and entries (an OFF face, a PLY list property): the count
// must leave room for its entries, and a face's entries must be among the
// nv vertices (OpenMesh sizes an array by an index) when nv >= 0.
bool scan_binary_list(body_cursor &b, const ply_prop &pr, double nv, const std::string &who,
                      std::string *msg) {
  if (b.left() < (size_t)pr.count_bytes) return ends_early(b, who, msg);
  const size_t count_at = b.at;
  const int64_t n = b.take(pr.count_bytes, pr.count_signed);
  if (n < 0 || (double)n * pr.bytes > (double)b.left()) {
    *msg = at_text(count_at) + who + ": its count of entries (" + std::to_string(n) +
           ") does not fit in the " + std::to_string(b.left()) + " bytes left";
    return false;
  }
  for (int64_t k = 0; k < n; k++) {
    const size_t value_at = b.at;
    const int64_t v = b.take(pr.bytes, pr.is_signed);
    if (nv >= 0 && (v < 0 || (double)v >= nv)) {
      *msg = at_text(value_at) + who + ": vertex index " + std::to_string(v) +
             " is not one of the " + std::to_string((long)nv) + " vertices";
      return false;
    }
  }
  return true;
}

bool is_face_indices(const ply_element &e, const ply_prop &pr) {
  return e.name == "face" && (pr.name == "vertex_indices" || pr.name == "vertex_index");
}

// The fewest bytes a row of e takes (a list as its count alone); the exact
// row size when it has no list.
size_t least_row_bytes(const ply_element &e, bool *has_list) {
  size_t bytes = 0;
  *has_list = false;
  for (const ply_prop &pr : e.props) {
    bytes += (size_t)(pr.list ? pr.count_bytes : pr.bytes);
    *has_list = *has_list || pr.list;
  }
  return bytes;
}

// What OpenMesh 9's binary PLY reader cannot walk the way the file is laid
// out: a list other than a face's vertex indices (it reads one value of
// it), a face property before the indices (it drops it from its layout),
// indices that are not integers, and rows of no bytes (nothing then bounds
// the count it reserves for).
bool check_binary_layout(const ply_element &e, std::string *msg) {
  for (size_t k = 0; k < e.props.size(); k++) {
    const ply_prop &pr = e.props[k];
    const std::string who = "element " + e.name + ", property " + pr.name;
    if (pr.list && !is_face_indices(e, pr)) {
      *msg = " " + who + ": OpenMesh's binary PLY reader reads only a face's vertex_indices "
             "as a list; it would misread this one and all that follows";
      return false;
    }
    if (pr.list && k > 0) {
      *msg = " " + who + ": OpenMesh's binary PLY reader skips the face properties before "
             "vertex_indices and would misread the faces; put vertex_indices first";
      return false;
    }
    if (pr.list && !pr.integer) {
      *msg = " " + who + ": vertex indices must be integers";
      return false;
    }
  }
  bool has_list;
  if (e.count > 0 && least_row_bytes(e, &has_list) == 0) {
    *msg = " element " + e.name + ": " + std::to_string(e.count) + " rows of no bytes each";
    return false;
  }
  return true;
}

// One element's rows: rows of scalars skipped whole, a face's rows walked
// list by list.
bool scan_ply_rows(body_cursor &b, const ply_element &e, double nv, std::string *msg) {
  bool has_list;
  const size_t row = least_row_bytes(e, &has_list);
  if (!has_list) {
    if ((double)e.count * (double)row <= (double)b.left()) {
      b.skip((size_t)e.count * row);
      return true;
    }
    *msg = at_text(b.at) + "element " + e.name + ": " + std::to_string(e.count) + " rows of " +
           std::to_string(row) + " bytes do not fit in the " + std::to_string(b.left()) +
           " bytes left";
    return false;
  }
  for (long i = 0; i < e.count; i++) {
    const std::string who = e.name + " " + std::to_string(i);
    for (const ply_prop &pr : e.props) {
      if (pr.list) {
        if (!scan_binary_list(b, pr, nv, who, msg)) return false;
      } else if (b.left() < (size_t)pr.bytes) {
        return ends_early(b, who, msg);
      } else {
        b.skip((size_t)pr.bytes);
      }
    }
  }
  return true;
}

} // namespace

bool prescan_ply_binary(const char *body, size_t left, size_t at,
                        const std::vector<ply_element> &elems, bool big_endian,
                        std::string *msg) {
  body_cursor b{(const unsigned char *)body, (const unsigned char *)body + left, at, big_endian};
  double nv = 0;
  for (const ply_element &e : elems)
    if (e.name == "vertex") nv = (double)e.count;
  for (const ply_element &e : elems) {
    if (!check_binary_layout(e, msg) || !scan_ply_rows(b, e, nv, msg)) return false;
    if (e.name == "face") break; // OpenMesh reads no further
  }
  return true;
}

// A binary OFF (OpenMesh 9, options as mesh_io asks them): the first line,
// then three little-endian 32-bit counts (vertices, faces, edges); each
// vertex three floats, then three more for N (normals), three ints for C
// (colours, read though not kept) and two floats for ST; each face a count
// and that many indices.
bool prescan_off_binary(const char *text, size_t len, bool normals, bool colours,
                        bool texcoords, std::string *msg) {
  const char *nl = (const char *)memchr(text, '\n', len);
  if (!nl) {
    *msg = " the OFF BINARY header line has no newline";
    return false;
  }
  const size_t at = (size_t)(nl + 1 - text);
  body_cursor b{(const unsigned char *)text + at, (const unsigned char *)text + len, at, false};
  if (b.left() < 12) return ends_early(b, "the vertex, face and edge counts", msg);
  const size_t counts_at = b.at;
  const int64_t nv = b.take(4, false), nf = b.take(4, false);
  b.skip(4);
  const size_t vertex_bytes = 12 + (normals ? 12 : 0) + (colours ? 12 : 0) + (texcoords ? 8 : 0);
  if ((double)nv * vertex_bytes + 4.0 * (double)nf > (double)b.left()) {
    *msg = at_text(counts_at) + std::to_string(nv) + " vertices of " + std::to_string(vertex_bytes) +
           " bytes and " + std::to_string(nf) + " faces do not fit in the " +
           std::to_string(b.left()) + " bytes left";
    return false;
  }
  b.skip((size_t)nv * vertex_bytes);
  const ply_prop indices{"vertex_indices", true, 4, false, 4, false, true};
  for (int64_t i = 0; i < nf; i++)
    if (!scan_binary_list(b, indices, (double)nv, "face " + std::to_string(i), msg)) return false;
  return true;
}
