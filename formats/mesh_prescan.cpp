// mesh_prescan.cpp: the text pre-scan of mesh files, and the headers of
// binary ones (mesh_prescan.h; their bodies: mesh_prescan_binary.cpp).
//
// OpenMesh's ASCII readers fail quietly or without bound on bad text: they
// parse numbers with `istream >> float` (nan drops an OBJ vertex), loop for
// ever on header lines they cannot parse, and read counts and indices as
// unsigned sizes to allocate. Each case found by fuzzing is refused here,
// naming the file's line, before OpenMesh opens the file.
#include <cctype>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "mesh_prescan.h"

namespace {

// A cursor over a NUL-terminated text buffer that knows its line number.
struct text_cursor {
  const char *p;
  int line;
  void skip_space_in_line() {
    while (*p == ' ' || *p == '\t' || *p == '\r') p++;
  }
  // Skips whitespace and newlines (and '#' comments when asked).
  void skip_space(bool comments) {
    for (;;) {
      if (*p == '\n') {
        line++;
        p++;
      } else if (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\f' || *p == '\v') {
        p++;
      } else if (comments && *p == '#') {
        while (*p && *p != '\n') p++;
      } else {
        return;
      }
    }
  }
  void next_line() {
    while (*p && *p != '\n') p++;
    if (*p == '\n') {
      p++;
      line++;
    }
  }
  // Copies the next whitespace-delimited token of this line (or any line).
  std::string token(bool cross_lines, bool comments) {
    if (cross_lines)
      skip_space(comments);
    else
      skip_space_in_line();
    const char *s = p;
    while (*p && !isspace((unsigned char)*p)) p++;
    return std::string(s, (size_t)(p - s));
  }
};

// A text format's pre-scan stops at a NUL byte while OpenMesh reads on, so
// an OBJ, or an ASCII OFF or PLY, with one is refused (fuzz_mesh_obj hid a
// bad face behind one).
bool no_nul(const char *text, size_t len, std::string *msg) {
  const char *nul = (const char *)memchr(text, 0, len);
  if (!nul) return true;
  *msg = " a NUL byte at offset " + std::to_string(nul - text) + " (not a text file)";
  return false;
}

// Parses a whole token as a number (strtod accepts nan, inf and overflow).
bool parse_number(const std::string &tok, double *v) {
  if (tok.empty()) return false;
  char *end = nullptr;
  errno = 0;
  *v = strtod(tok.c_str(), &end);
  return end && *end == 0;
}

bool fits_float(double v) {
  return std::isfinite(v) && std::fabs(v) <= (double)FLT_MAX;
}

// Checks three coordinate tokens; fills msg and returns false when bad.
// msg becomes "LINE: WHO has ...", to follow "path:".
bool check_coords(const std::string tok[3], int line, const std::string &who, std::string *msg) {
  double v[3];
  for (int a = 0; a < 3; a++) {
    if (!parse_number(tok[a], &v[a])) {
      *msg = std::to_string(line) + ": " + who + ": expected three numbers, coordinate " +
             std::to_string(a + 1) + " is '" + tok[a] + "'";
      return false;
    }
  }
  for (int a = 0; a < 3; a++) {
    if (!fits_float(v[a])) {
      *msg = std::to_string(line) + ": " + who + " has a non-finite coordinate " + mesh_coords_text(v);
      if (std::isfinite(v[a])) *msg += " (overflows a 32-bit float)";
      return false;
    }
  }
  return true;
}

// An OBJ face line's vertex references ("f 1 2/7 -1//3"): at least one, each
// starting with its vertex index. OpenMesh 9 asserts (SIGABRT, the process
// dies) on a face that yields no vertex, e.g. "f" alone or "f /13"
// (found by fuzz_mesh_obj).
bool check_obj_face(text_cursor &c, std::string *msg) {
  int line = c.line, refs = 0;
  for (std::string t = c.token(false, false); !t.empty(); t = c.token(false, false), refs++) {
    if (t[0] == '#') break; // a trailing comment
    size_t d = (t[0] == '-' || t[0] == '+') ? 1 : 0;
    if (d >= t.size() || !isdigit((unsigned char)t[d])) {
      *msg = std::to_string(line) + ": face vertex \"" + t.substr(0, 40) +
             "\" does not start with a vertex number";
      return false;
    }
  }
  if (refs == 0) *msg = std::to_string(line) + ": face without vertices";
  return refs > 0;
}

bool is_obj_keyword(const char *p, char k) {
  return p[0] == k && (p[1] == ' ' || p[1] == '\t' || p[1] == '\r' || p[1] == '\n' || !p[1]);
}

// OBJ: every "v x y z" and "f ..." line. Returns the number of v lines
// through *count.
bool prescan_obj(const char *text, int *count, std::string *msg) {
  text_cursor c{text, 1};
  int n = 0;
  while (*c.p) {
    c.skip_space_in_line();
    if (is_obj_keyword(c.p, 'f')) {
      c.p++;
      if (!check_obj_face(c, msg)) return false;
    } else if (c.p[0] == 'v' && (c.p[1] == ' ' || c.p[1] == '\t')) {
      int line = c.line;
      c.p++;
      n++;
      std::string tok[3];
      for (int a = 0; a < 3; a++) tok[a] = c.token(false, false);
      if (!check_coords(tok, line, "vertex " + std::to_string(n), msg))
        return false;
    }
    c.next_line();
  }
  *count = n;
  return true;
}

// ASCII OFF: header "OFF" (or COFF, NOFF, CNOFF...), counts, then vertices.
// Vertex numbers are 0-based, as OFF faces use them. OpenMesh's OFF reader
// knows no '#' comments (it reads garbage after one), so they are refused.
// An OFF keyword: [ST][C][N][4][n]OFF, in that order.
bool is_off_keyword(const std::string &head) {
  static const char *const prefixes[] = {"ST", "C", "N", "4", "n"};
  size_t at = 0;
  for (const char *pre : prefixes)
    if (head.compare(at, strlen(pre), pre) == 0) at += strlen(pre);
  return head.compare(at, std::string::npos, "OFF") == 0;
}

bool is_count(const std::string &tok) {
  if (tok.empty() || tok.size() > 10) return false;
  for (char ch : tok)
    if (!isdigit((unsigned char)ch)) return false;
  return true;
}

// OpenMesh reserves memory for the declared counts before it reads a vertex
// (fuzz_mesh_off: a garbled header made it ask for 4.7 GB), so the counts
// must fit in the file: a vertex takes at least 6 bytes ("0 0 0\n"), a
// face 4 ("1 0\n").
bool check_off_counts(const std::string counts[3], size_t len, int line, std::string *msg) {
  if (!is_count(counts[0]) || !is_count(counts[1]) || !is_count(counts[2])) {
    *msg = std::to_string(line) + ": expected three counts after the OFF header, found \"" +
           counts[0].substr(0, 20) + " " + counts[1].substr(0, 20) + " " +
           counts[2].substr(0, 20) + "\"";
    return false;
  }
  double need = 6.0 * atof(counts[0].c_str()) + 4.0 * atof(counts[1].c_str());
  if (need <= (double)len) return true;
  *msg = std::to_string(line) + ": " + counts[0] + " vertices and " + counts[1] +
         " faces cannot fit in a file of " + std::to_string(len) + " bytes";
  return false;
}

// A list's count (an OFF face's, a PLY list property's): OpenMesh reads it
// as unsigned and then that many numbers, past the line and the file's end,
// keeping each: "-3" (fuzz_mesh_off) had it take 5 GB and growing. So the
// count must be a whole number whose entries fit in the `left` bytes after
// it (at least 2 each, " 0").
bool check_list_count(const std::string &tok, size_t left, int line, const std::string &who,
                      std::string *msg) {
  double n = 0;
  if (parse_number(tok, &n) && n >= 0 && n == std::floor(n) && n <= 0.5 * (double)left) return true;
  *msg = std::to_string(line) + ": " + who + ": its count of entries must be a whole number " +
         "that fits in the file, found '" + tok.substr(0, 20) + "'";
  return false;
}

// A face's vertex index: OpenMesh sizes an array by it, so 555555555 in a
// file of 8 vertices took 2 GB (fuzz_mesh_off). It must be one of the nv
// vertices.
bool check_vertex_index(const std::string &tok, double nv, int line, const std::string &who,
                        std::string *msg) {
  double k = 0;
  if (parse_number(tok, &k) && k >= 0 && k == std::floor(k) && k < nv) return true;
  *msg = std::to_string(line) + ": " + who + ": vertex index '" + tok.substr(0, 20) +
         "' is not one of the " + std::to_string((long)nv) + " vertices";
  return false;
}

// A list after its count token n (end: the text's end): the count checked
// (check_list_count), then its entries read, each a vertex index among nv
// (check_vertex_index) when nv >= 0. 1: read; 0: refused (*msg); -1: the
// text ended first (OpenMesh reports a truncated body).
int scan_list(text_cursor &c, const char *end, const std::string &n, double nv,
              const std::string &who, std::string *msg) {
  if (!check_list_count(n, (size_t)(end - c.p), c.line, who, msg)) return 0;
  for (long m = 0; m < (long)std::atof(n.c_str()); m++) {
    std::string k = c.token(true, false);
    if (k.empty()) return -1;
    if (nv >= 0 && !check_vertex_index(k, nv, c.line, who, msg)) return 0;
  }
  return 1;
}

// The faces of an ASCII OFF after its nv vertices: each one's list of
// vertex indices (scan_list), then in a COFF the rest of the line (its
// colour). OpenMesh reads a face's colour only in a COFF; in an OFF it
// takes one for the next face's count ("3 0 3 2 0222…2", fuzz_mesh_off:
// 3 GB of indices), so values after the indices are refused there. True
// also on a truncated body (OpenMesh reports it).
bool prescan_off_faces(text_cursor &c, const char *end, double nv, double nf, bool colours,
                       std::string *msg) {
  for (long i = 0; i < (long)nf; i++) {
    std::string n = c.token(true, false);
    if (n.empty()) return true;
    const int r = scan_list(c, end, n, nv, "face " + std::to_string(i), msg);
    if (r <= 0) return r < 0;
    const int line = c.line;
    const std::string more = colours ? "" : c.token(false, false);
    if (!more.empty()) {
      *msg = std::to_string(line) + ": face " + std::to_string(i) + ": \"" + more.substr(0, 20) +
             "\" after its vertex indices; OpenMesh reads face colours only in a COFF file";
      return false;
    }
    c.next_line();
  }
  return true;
}

bool prescan_off(const char *text, size_t len, std::string *msg) {
  text_cursor c{text, 1};
  std::string head = c.token(true, false);
  if (!is_off_keyword(head)) {
    *msg = std::to_string(c.line) + ": expected an OFF header ([ST][C][N][4][n]OFF), found \"" +
           head.substr(0, 20) + "\"";
    return false;
  }
  if (head.find('4') != std::string::npos || head.find('n') != std::string::npos) return true;
  // OpenMesh reads a body as binary when its first line has BINARY one
  // character after OFF; NaN passes through then, checked after reading
  const size_t off_end = (size_t)(c.p - text);
  if (off_end == head.size() && len >= off_end + 7 && text[off_end] != '\n' &&
      memcmp(text + off_end + 1, "BINARY", 6) == 0) {
    const size_t letters = head.size() - 3;
    const std::string flags = head.substr(0, letters);
    return prescan_off_binary(text, len, flags.find('N') != std::string::npos,
                              flags.find('C') != std::string::npos,
                              flags.compare(0, 2, "ST") == 0, msg);
  }
  // text from here on: the scan below stops at a NUL byte, OpenMesh reads on
  if (!no_nul(text, len, msg)) return false;
  // OpenMesh reads the counts from the second line, whatever follows OFF on
  // the first ("OFF 0 0\n13 -313" made it reserve 17 GB: fuzz_mesh_off)
  const std::string rest = c.token(false, false);
  if (!rest.empty()) {
    *msg = std::to_string(c.line) + ": \"" + rest.substr(0, 20) + "\" after " + head +
           ": OpenMesh reads the counts from the next line and nothing else on this one; put "
           "them there";
    return false;
  }
  c.next_line();
  const char *comment_msg = ": '#' comments are not supported by OpenMesh's OFF reader; remove them";
  std::string counts[3];
  for (int a = 0; a < 3; a++) {
    counts[a] = c.token(true, false);
    if (!counts[a].empty() && counts[a][0] == '#') {
      *msg = std::to_string(c.line) + comment_msg;
      return false;
    }
  }
  if (!check_off_counts(counts, len, c.line, msg)) return false;
  double nv = 0, nf = 0;
  if (!parse_number(counts[0], &nv) || nv < 0 || nv > 1e9 || !parse_number(counts[1], &nf))
    return true; // OpenMesh reports it
  for (long i = 0; i < (long)nv; i++) {
    c.skip_space(false);
    if (!*c.p) return true; // truncated: OpenMesh will notice
    int line = c.line;
    if (*c.p == '#') {
      *msg = std::to_string(line) + comment_msg;
      return false;
    }
    std::string tok[3];
    for (int a = 0; a < 3; a++) tok[a] = c.token(false, false);
    if (!check_coords(tok, line, "vertex " + std::to_string(i), msg)) return false;
    c.next_line(); // normals, colours and texture coordinates follow on the line
  }
  return prescan_off_faces(c, text + len, nv, nf, head.find('C') != std::string::npos, msg);
}

// OpenMesh 9 loops forever, its error messages piling up, on a header line
// it cannot parse (fuzz_mesh_ply_ascii: "property flotex_indices"). A
// known type's size and kind, for a binary body; false for an unknown one.
bool ply_type_layout(const std::string &t, int *bytes, bool *is_signed, bool *integer) {
  static const struct {
    const char *name;
    int bytes;
    bool is_signed, integer;
  } types[] = {{"char", 1, true, true},     {"int8", 1, true, true},    {"uchar", 1, false, true},
               {"uint8", 1, false, true},   {"short", 2, true, true},   {"int16", 2, true, true},
               {"ushort", 2, false, true},  {"uint16", 2, false, true}, {"int", 4, true, true},
               {"int32", 4, true, true},    {"uint", 4, false, true},   {"uint32", 4, false, true},
               {"float", 4, true, false},   {"float32", 4, true, false},
               {"double", 8, true, false},  {"float64", 8, true, false}};
  for (const auto &k : types)
    if (t == k.name) {
      *bytes = k.bytes, *is_signed = k.is_signed, *integer = k.integer;
      return true;
    }
  return false;
}

// The same loop on a format line whose version its stream cannot read as a
// number ("format ascii $.0", fuzz_mesh_ply_ascii; a hundred digits,
// which overflow its float: fuzz_mesh_ply_binary): a known type and a plain
// decimal version of at most 8 characters only.
bool is_ply_format(const std::string &type, const std::string &version) {
  if (type != "ascii" && type != "binary_little_endian" && type != "binary_big_endian") return false;
  if (version.empty() || version.size() > 8 || !isdigit((unsigned char)version[0])) return false;
  int dots = 0;
  for (char ch : version)
    if (ch == '.') dots++;
    else if (!isdigit((unsigned char)ch)) return false;
  return dots <= 1;
}

// OpenMesh reads a header line to its newline and takes what it can of it:
// text after a line's fields ("element face 8\fproperty ...", an end_header
// followed by a NUL and binary data with no newline) made it loop for ever
// (fuzz_mesh_ply_*). So each line must end after its fields.
bool ply_line_ends(text_cursor &c, const std::string &kw, std::string *msg) {
  c.skip_space_in_line();
  if (*c.p == '\n') return true;
  *msg = std::to_string(c.line) + ": the PLY header's " + kw + " line must end after its " +
         "fields, found " + (*c.p ? "more on it" : "no newline");
  return false;
}

// The rest of an "element NAME COUNT" line onto elems.
bool ply_element_line(text_cursor &c, std::vector<ply_element> &elems, std::string *msg) {
  ply_element e;
  e.name = c.token(false, false);
  std::string count = c.token(false, false);
  double n = 0;
  /* OpenMesh reads "nan" or "-1" as a huge count, and its stream fails for
   * good on ".0" (fuzz_mesh_ply_ascii: it then added elements until out of
   * memory); PLY counts are digits */
  if (!is_count(count) || !parse_number(count, &n) || n > 2147483647.0) {
    *msg = std::to_string(c.line) + ": element " + e.name +
           ": the count must be a whole number from 0 to 2147483647, found '" + count + "'";
    return false;
  }
  e.count = (long)n;
  elems.push_back(e);
  return true;
}

// The rest of a "property TYPE NAME" or "property list T T NAME" line onto
// the last element.
bool ply_property_line(text_cursor &c, ply_element &e, std::string *msg) {
  std::string type = c.token(false, false);
  ply_prop pr{};
  pr.list = type == "list";
  bool count_integer = true, typed = true;
  if (pr.list) {
    typed = ply_type_layout(c.token(false, false), &pr.count_bytes, &pr.count_signed,
                            &count_integer);
    type = c.token(false, false);
  }
  typed = ply_type_layout(type, &pr.bytes, &pr.is_signed, &pr.integer) && typed;
  pr.name = c.token(false, false);
  if (!typed || pr.name.empty()) {
    *msg = std::to_string(c.line) + ": a PLY property needs a known type and a name";
    return false;
  }
  if (!count_integer) {
    *msg = std::to_string(c.line) + ": property " + pr.name + ": a list's count must have an "
           "integer type";
    return false;
  }
  e.props.push_back(pr);
  return true;
}

// The line after "ply": OpenMesh takes its second and third words for the
// format and the version, whatever the first, and never reads another
// format line (a later one made the pre-scan walk a binary body as text).
bool ply_format_line(text_cursor &c, std::string *format, std::string *msg) {
  c.skip_space(false);
  const std::string kw = c.token(false, false);
  const std::string type = c.token(false, false), version = c.token(false, false);
  if (kw != "format" || !is_ply_format(type, version)) {
    *msg = std::to_string(c.line) + ": the line after 'ply' must read 'format ascii 1.0' (or " +
           "binary_little_endian / binary_big_endian), found '" + kw.substr(0, 20) + " " +
           type.substr(0, 20) + " " + version.substr(0, 20) + "'";
    return false;
  }
  *format = type;
  return ply_line_ends(c, kw, msg);
}

// An obj_info line: OpenMesh reads each of its words as a header keyword,
// so one that is "element", "property" or "end_header" is refused.
bool ply_obj_info_line(text_cursor &c, std::string *msg) {
  for (std::string w = c.token(false, false); !w.empty(); w = c.token(false, false))
    if (w == "element" || w == "property" || w == "end_header") {
      *msg = std::to_string(c.line) + ": obj_info text holds '" + w + "', which OpenMesh " +
             "reads as a header line; remove it";
      return false;
    }
  return true;
}

// Where a header line's fields end: its end, less trailing blanks.
const char *fields_end(const char *p) {
  const char *s = p;
  while (*p && *p != '\n') p++;
  while (p > s && (p[-1] == ' ' || p[-1] == '\t' || p[-1] == '\r')) p--;
  return p;
}

// The header up to and past end_header: its elements, its format ("ascii",
// "binary_little_endian" or "binary_big_endian"), and in *om_body where
// OpenMesh 9 takes a binary body to start: 12 bytes (14 after "\r\n")
// past where it stopped reading the line before end_header, which is the
// end of its fields, or for a comment the next line's start. False with
// *msg on a line OpenMesh would loop on or misread.
bool ply_header(text_cursor &c, std::vector<ply_element> &elems, std::string *format,
                const char **om_body, std::string *msg) {
  if (!ply_format_line(c, format, msg)) return false;
  const char *om_stop = fields_end(c.p);
  c.next_line();
  for (;;) {
    c.skip_space(false);
    // OpenMesh 9 loops forever on a header without end_header (found by
    // fuzz_mesh_ply_*); a NUL byte ends the header text here as well.
    if (!*c.p) {
      *msg = std::to_string(c.line) + ": the PLY header has no end_header line";
      return false;
    }
    std::string kw = c.token(false, false);
    if (kw == "obj_info") {
      if (!ply_obj_info_line(c, msg)) return false;
    } else if (kw == "element") {
      if (!ply_element_line(c, elems, msg)) return false;
    } else if (kw == "property" && !elems.empty()) {
      if (!ply_property_line(c, elems.back(), msg)) return false;
    } else if (kw == "end_header") {
      if (!ply_line_ends(c, kw, msg)) return false;
      c.next_line();
      *om_body = om_stop + (om_stop[0] == '\r' && om_stop[1] == '\n' ? 14 : 12);
      return true;
    } else if (kw != "comment" && kw != "obj_info") {
      *msg = std::to_string(c.line) + ": unknown PLY header line \"" + kw.substr(0, 20) + "\"";
      return false;
    }
    if (kw != "comment" && kw != "obj_info" && !ply_line_ends(c, kw, msg)) return false;
    om_stop = fields_end(c.p);
    c.next_line();
    if (kw == "comment") om_stop = c.p;
  }
}

// One element's rows of the ASCII body (end: the text's end; nv: the vertex
// element's count): for the "vertex" element, x, y and z checked as
// coordinates; every list read by scan_list, a face's checked as vertex
// indices. True also on a truncated body
// (OpenMesh reports it).
bool ply_element_rows(text_cursor &c, const char *end, const ply_element &e, double nv,
                      std::string *msg) {
  int ix = -1, iy = -1, iz = -1;
  const bool is_vertex = e.name == "vertex";
  for (size_t k = 0; k < e.props.size(); k++) {
    if (e.props[k].name == "x") ix = (int)k;
    if (e.props[k].name == "y") iy = (int)k;
    if (e.props[k].name == "z") iz = (int)k;
  }
  for (long i = 0; i < e.count; i++) {
    std::string tok[3];
    int line = -1;
    for (size_t k = 0; k < e.props.size(); k++) {
      std::string t = c.token(true, false);
      if (t.empty()) return true; // truncated: OpenMesh will notice
      if (line < 0) line = c.line;
      if (e.props[k].list) {
        const std::string who = e.name + " " + std::to_string(i) + ", " + e.props[k].name;
        const bool indices = e.name == "face" && e.props[k].name.rfind("vertex_ind", 0) == 0;
        const int r = scan_list(c, end, t, indices ? nv : -1.0, who, msg);
        if (r <= 0) return r < 0;
        continue;
      }
      if (is_vertex && (int)k == ix) tok[0] = t;
      if (is_vertex && (int)k == iy) tok[1] = t;
      if (is_vertex && (int)k == iz) tok[2] = t;
    }
    if (is_vertex && ix >= 0 && iy >= 0 && iz >= 0 &&
        !check_coords(tok, line, "vertex " + std::to_string(i), msg))
      return false;
  }
  return true;
}

// PLY: the header (OpenMesh takes "PLY" for "ply" too: fuzz_mesh_ply_ascii
// hid a header it loops on behind it); in an ASCII body every element's rows
// (ply_element_rows).
bool prescan_ply(const char *text, size_t len, std::string *msg) {
  text_cursor c{text, 1};
  const std::string magic = c.token(true, false);
  if (magic != "ply" && magic != "PLY") {
    *msg = "1: expected 'ply' on the first line, found '" + magic.substr(0, 20) + "'";
    return false;
  }
  std::vector<ply_element> elems;
  std::string format;
  const char *om_body = nullptr;
  if (!ply_header(c, elems, &format, &om_body, msg)) return false;
  const size_t at = (size_t)(c.p - text);
  if (format != "ascii" && om_body != c.p) {
    *msg = std::to_string(c.line - 1) + ": OpenMesh would read the binary body from byte " +
           std::to_string(om_body - text) + ", not " + std::to_string(at) + " where it starts" +
           " (after a comment or a blank line); remove the line before end_header";
    return false;
  }
  if (format != "ascii") // NaN passes through here, checked after reading
    return prescan_ply_binary(c.p, len - at, at, elems, format == "binary_big_endian", msg);
  if (!no_nul(text, len, msg)) return false;
  double nv = 0;
  for (const ply_element &e : elems)
    if (e.name == "vertex") nv = (double)e.count;
  for (const ply_element &e : elems)
    if (!ply_element_rows(c, text + len, e, nv, msg)) return false;
  return true;
}

// ASCII STL: every "vertex x y z"; a file whose size matches the binary
// layout (84 + 50 bytes per facet) is binary even when it starts with "solid".
bool prescan_stl(const char *text, size_t len, std::string *msg) {
  if (len >= 84) {
    uint32_t n;
    memcpy(&n, text + 80, 4);
    if (84 + 50 * (uint64_t)n == len) {
      // binary: OpenMesh merges vertices by position and loses a NaN's facet,
      // so look at the records here (normal, 3 vertices, attribute)
      for (uint32_t f = 0; f < n; f++)
        for (int q = 0; q < 3; q++) {
          float v[3];
          memcpy(v, text + 84 + 50 * (size_t)f + 12 + 12 * q, sizeof v);
          if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) {
            double d[3] = {v[0], v[1], v[2]};
            *msg = " facet " + std::to_string(f) + " vertex " + std::to_string(q) +
                   " has a non-finite coordinate " + mesh_coords_text(d);
            return false;
          }
        }
      return true;
    }
  }
  text_cursor c{text, 1};
  if (c.token(true, false) != "solid") {
    /* binary by its header, but the facet count does not match the size:
     * OpenMesh reads nothing and would only say "no triangles" */
    uint32_t n = 0;
    if (len >= 84) memcpy(&n, text + 80, 4);
    *msg = len < 84 ? " too short for a binary STL (" + std::to_string(len) + " bytes, at least 84)"
                    : " binary STL declares " + std::to_string(n) + " facets (" +
                          std::to_string(84 + 50 * (uint64_t)n) + " bytes) but is " +
                          std::to_string(len) + " bytes long, room for " +
                          std::to_string((len - 84) / 50) + " facets";
    return false;
  }
  long k = 0;
  for (;;) {
    std::string t = c.token(true, false);
    if (t.empty()) return true;
    if (t != "vertex") continue;
    int line = c.line;
    std::string tok[3];
    for (int a = 0; a < 3; a++) tok[a] = c.token(false, false);
    if (!check_coords(tok, line,
                      "facet " + std::to_string(k / 3) + " vertex " + std::to_string(k % 3), msg))
      return false;
    k++;
  }
}

} // namespace

std::string mesh_coords_text(const double v[3]) {
  char buf[128];
  snprintf(buf, sizeof buf, "(%g, %g, %g)", (double)(float)v[0], (double)(float)v[1],
           (double)(float)v[2]);
  return buf;
}

int mesh_prescan_file(const char *path, mesh_format fmt, int *obj_vertex_lines, bk_error_t *err) {
  char *text = nullptr;
  size_t len = 0;
  bk_error_t read_err;
  if (bk_read_file(path, &text, &len, &read_err) != BK_OK)
    return bk_fail(err, BK_ERR_INPUT, "%s", read_err.msg);
  std::string msg;
  bool ok = true;
  switch (fmt) {
  case FMT_OBJ: ok = no_nul(text, len, &msg) && prescan_obj(text, obj_vertex_lines, &msg); break;
  case FMT_OFF: ok = prescan_off(text, len, &msg); break;
  case FMT_PLY: ok = prescan_ply(text, len, &msg); break;
  case FMT_STL: ok = prescan_stl(text, len, &msg); break;
  default: break;
  }
  free(text);
  if (!ok) return bk_fail(err, BK_ERR_INPUT, "%s:%s", path, msg.c_str());
  return BK_OK;
}
