// mesh_io.cpp: triangle meshes through OpenMesh, behind the C header mesh_io.h.
//
// OpenMesh's ASCII readers parse numbers with `istream >> float`, which fails
// on "nan" and "inf": the OBJ reader then silently drops the vertex (shifting
// every later index), and the OFF and PLY readers stop with garbage. So text
// files are pre-scanned for vertices whose coordinates do not parse or are not
// finite, and the loader names them; binary files carry NaN through, and the
// final check on OpenMesh's vertices catches them.
// GCC 12 flags OpenMesh's own PropertyT<Vec2f>::push_back (a value-initialised
// temporary) as maybe-uninitialized; the warning is about OpenMesh, not us.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <OpenMesh/Core/IO/MeshIO.hh> // before the kernel, so the readers register
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "isolate.h"
#include "mesh_io.h"
#include "mesh_prescan.h"

namespace {

typedef OpenMesh::TriMesh_ArrayKernelT<> om_mesh_t;

// Captures OpenMesh's omerr()/omlog()/omout() in a string while a mesh is
// read, so its chatter ("PolyMeshT::add_face: complex edge") does not reach
// the user's terminal unasked and can be quoted in our messages. Those streams
// write to std::cerr, std::clog and std::cout; their buffers are swapped for
// ours meanwhile. (Re-connecting OpenMesh's streams instead would leak:
// mostream::disconnect never frees what connect allocated.)
struct om_capture {
  std::ostringstream text;
  std::streambuf *saved[3];
  bool active;
  om_capture() : active(true) {
    saved[0] = std::cerr.rdbuf(text.rdbuf());
    saved[1] = std::clog.rdbuf(text.rdbuf());
    saved[2] = std::cout.rdbuf(text.rdbuf());
  }
  ~om_capture() { release(); }
  // OpenMesh passes a line on at '\n', the rest when flushed.
  void release() {
    if (!active) return;
    omerr().flush();
    omlog().flush();
    omout().flush();
    std::cerr.rdbuf(saved[0]);
    std::clog.rdbuf(saved[1]);
    std::cout.rdbuf(saved[2]);
    active = false;
  }
  // The captured lines on one line, repeats counted ("... complex edge (x12)"),
  // at most `max` characters. *topology_only tells whether every line is
  // OpenMesh refusing a non-manifold face, which mesh_check reports anyway.
  std::string summary(bool *topology_only, size_t max = 300) const {
    std::vector<std::string> lines;
    std::vector<int> counts;
    std::istringstream in(text.str());
    std::string line;
    long more = 0;
    *topology_only = true;
    while (std::getline(in, line)) {
      while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
      if (line.empty()) continue;
      if (line.find("complex edge") == std::string::npos &&
          line.find("complex vertex") == std::string::npos)
        *topology_only = false;
      size_t k = 0;
      while (k < lines.size() && lines[k] != line) k++;
      if (k == lines.size()) {
        if (lines.size() == 8) { // enough to say what happened
          more++;
          continue;
        }
        lines.push_back(line);
        counts.push_back(0);
      }
      counts[k]++;
    }
    std::string out;
    if (more) lines.push_back("and " + std::to_string(more) + " more"), counts.push_back(1);
    for (size_t k = 0; k < lines.size(); k++) {
      if (!out.empty()) out += "; ";
      out += lines[k];
      if (counts[k] > 1) out += " (x" + std::to_string(counts[k]) + ")";
    }
    if (out.size() > max) out = out.substr(0, max) + "...";
    return out;
  }
};

mesh_format format_of(const char *path, std::string *ext) {
  const char *slash = strrchr(path, '/');
  const char *dot = strrchr(slash ? slash : path, '.');
  ext->clear();
  if (!dot) return FMT_UNKNOWN;
  for (const char *c = dot; *c; c++) *ext += (char)tolower((unsigned char)*c);
  if (*ext == ".obj") return FMT_OBJ;
  if (*ext == ".ply") return FMT_PLY;
  if (*ext == ".off") return FMT_OFF;
  if (*ext == ".stl") return FMT_STL;
  return FMT_UNKNOWN;
}


// OpenMesh reads the file with its console chatter captured: the chatter
// becomes a log line (topology only), a warning, or part of the error.
// Refuses meshes without faces, with dropped vertices or too large for int.
int read_openmesh(const char *path, const std::string &ext, int obj_vertex_lines,
                  om_mesh_t &mesh, bk_error_t *err) {
  OpenMesh::IO::Options opts;
  bool read_ok;
  std::string chatter;
  bool topology_only = true;
  {
    om_capture capture;
    try {
      read_ok = OpenMesh::IO::read_mesh(mesh, path, opts);
    } catch (const std::exception &e) {
      capture.release();
      return bk_fail(err, BK_ERR_INPUT, "%s: OpenMesh failed to read it: %s", path, e.what());
    }
    capture.release();
    chatter = capture.summary(&topology_only);
  }
  if (!read_ok)
    return bk_fail(err, BK_ERR_INPUT, "%s: OpenMesh could not read it as %s%s%s", path,
                   ext.c_str() + 1, chatter.empty() ? "" : ": ", chatter.c_str());
  // faces OpenMesh could not attach are still read (with duplicated
  // vertices) and mesh_check counts them; anything else may have lost data
  if (!chatter.empty() && topology_only)
    bk_log(2, "%s: OpenMesh says: %s", path, chatter.c_str());
  else if (!chatter.empty())
    bk_warn("%s: OpenMesh says: %s", path, chatter.c_str());
  if (mesh.n_faces() == 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: contains no triangles (%zu vertices, 0 faces)%s%s", path,
                   (size_t)mesh.n_vertices(), chatter.empty() ? "" : "; OpenMesh says: ",
                   chatter.c_str());
  // OpenMesh only adds vertices (duplicates for complex edges), so fewer than
  // the file's "v" lines means it dropped some it could not parse.
  if (obj_vertex_lines >= 0 && (long)mesh.n_vertices() < (long)obj_vertex_lines)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: OpenMesh read only %zu of its %d vertices (a coordinate it cannot parse?)",
                   path, (size_t)mesh.n_vertices(), obj_vertex_lines);
  if (mesh.n_vertices() > (size_t)INT32_MAX / 3 || mesh.n_faces() > (size_t)INT32_MAX / 3)
    return bk_fail(err, BK_ERR_INPUT, "%s: too large (%zu vertices, %zu faces)", path,
                   (size_t)mesh.n_vertices(), (size_t)mesh.n_faces());
  return BK_OK;
}

// The triangulated OpenMesh mesh as the flat arrays of mesh_tris_t. A
// non-finite coordinate is refused here, where the file's vertex number is
// still known.
int copy_triangles(const char *path, om_mesh_t &mesh, mesh_tris_t *out, bk_error_t *err) {
  int nv = (int)mesh.n_vertices(), nf = (int)mesh.n_faces();
  out->positions = (float *)bk_calloc((size_t)nv * 3, sizeof(float), path, err);
  out->indices = (int *)bk_calloc((size_t)nf * 3, sizeof(int), path, err);
  if (!out->positions || !out->indices) {
    mesh_io_free(out);
    return BK_ERR_RUNTIME;
  }
  for (int i = 0; i < nv; i++) {
    const om_mesh_t::Point &p = mesh.point(om_mesh_t::VertexHandle(i));
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      double v[3] = {p[0], p[1], p[2]};
      mesh_io_free(out);
      return bk_fail(err, BK_ERR_INPUT, "%s: vertex %d has a non-finite coordinate %s", path, i,
                     mesh_coords_text(v).c_str());
    }
    for (int a = 0; a < 3; a++) out->positions[3 * i + a] = p[a];
  }
  int t = 0;
  for (om_mesh_t::FaceHandle f : mesh.faces()) {
    int corner = 0;
    for (om_mesh_t::VertexHandle v : mesh.fv_range(f)) {
      if (corner < 3) out->indices[3 * t + corner] = v.idx();
      corner++;
    }
    if (corner != 3) {
      mesh_io_free(out);
      return bk_fail(err, BK_ERR_RUNTIME, "%s: face %d has %d corners after triangulation", path,
                     t, corner);
    }
    t++;
  }
  out->vertex_count = nv;
  out->triangle_count = nf;
  return BK_OK;
}

} // namespace

// The read in a child (mesh_io_read): the child fills its copy of *out and
// sends the two counts and the arrays; the parent checks the counts and
// every index before it keeps them.
struct mesh_read_job : iso_job {
  const char *path;
  mesh_tris_t *out;
  const char *kind() const override { return "mesh"; }
  bool parses_first() const override { return false; }
  // OpenMesh has nothing to start: a hang is known sooner than a VDB's
  unsigned base_seconds() const override { return 10u; }
  int work(bk_error_t *err) override { return mesh_io_read_here(path, out, err); }
  bool send(int fd) override {
    const int32_t n[2] = {out->vertex_count, out->triangle_count};
    return iso_write(fd, n, sizeof n) &&
           iso_write(fd, out->positions, (size_t)n[0] * 3 * sizeof(float)) &&
           iso_write(fd, out->indices, (size_t)n[1] * 3 * sizeof(int));
  }
  int recv(int fd, bk_error_t *err) override {
    int32_t n[2];
    if (!iso_read(fd, n, sizeof n) || n[0] < 0 || n[1] < 0 || n[0] > INT32_MAX / 3 ||
        n[1] > INT32_MAX / 3)
      return -1;
    out->positions = (float *)bk_calloc((size_t)n[0] * 3 + 1, sizeof(float), path, err);
    out->indices = (int *)bk_calloc((size_t)n[1] * 3 + 1, sizeof(int), path, err);
    if (!out->positions || !out->indices) {
      mesh_io_free(out);
      return BK_ERR_RUNTIME;
    }
    out->vertex_count = n[0];
    out->triangle_count = n[1];
    bool ok = iso_read(fd, out->positions, (size_t)n[0] * 3 * sizeof(float)) &&
              iso_read(fd, out->indices, (size_t)n[1] * 3 * sizeof(int));
    for (int32_t k = 0; ok && k < 3 * n[1]; k++)
      ok = out->indices[k] >= 0 && out->indices[k] < n[0];
    if (!ok) mesh_io_free(out);
    return ok ? BK_OK : -1;
  }
};

extern "C" int mesh_io_read(const char *path, mesh_tris_t *out, bk_error_t *err) {
  memset(out, 0, sizeof *out);
  mesh_read_job job;
  job.path = path;
  job.out = out;
  return iso_run(job, path, err);
}

extern "C" int mesh_io_read_here(const char *path, mesh_tris_t *out, bk_error_t *err) {
  memset(out, 0, sizeof *out);
  std::string ext;
  mesh_format fmt = format_of(path, &ext);
  if (fmt == FMT_UNKNOWN)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: unknown mesh format '%s': expected .obj, .ply, .off or .stl", path,
                   ext.empty() ? "(no extension)" : ext.c_str());
  /* read twice, checked and then loaded: a pipe would be empty the second
   * time, and a device such as /dev/zero never ends */
  const bk_file_kind_t kind = bk_file_kind(path);
  if (kind == BK_FILE_PIPE || kind == BK_FILE_OTHER)
    return bk_fail(err, BK_ERR_INPUT, "%s: not a regular file", path);
  int obj_vertex_lines = -1;
  const char *skip = getenv("BAKER_MESH_NO_PRESCAN");
  int rc = skip && !strcmp(skip, "1") ? BK_OK : mesh_prescan_file(path, fmt, &obj_vertex_lines, err);
  if (rc != BK_OK) return rc;
  om_mesh_t mesh;
  rc = read_openmesh(path, ext, obj_vertex_lines, mesh, err);
  if (rc != BK_OK) return rc;
  return copy_triangles(path, mesh, out, err);
}

extern "C" int mesh_io_write_obj(const char *path, const mesh_tris_t *m, bk_error_t *err) {
  int rc = bk_check_output_dir(path, err);
  if (rc != BK_OK) return rc;
  char temp[4200];
  bk_temp_path(path, temp, sizeof temp);
  FILE *f = fopen(temp, "w");
  if (!f) return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot create %s: %s", path, temp, strerror(errno));
  fprintf(f, "# written by baker mesh_io_write_obj: %d vertices, %d triangles\n", m->vertex_count,
          m->triangle_count);
  // %.9g round-trips a float exactly
  for (int i = 0; i < m->vertex_count; i++)
    fprintf(f, "v %.9g %.9g %.9g\n", m->positions[3 * i], m->positions[3 * i + 1],
            m->positions[3 * i + 2]);
  for (int t = 0; t < m->triangle_count; t++)
    fprintf(f, "f %d %d %d\n", m->indices[3 * t] + 1, m->indices[3 * t + 1] + 1,
            m->indices[3 * t + 2] + 1);
  int bad = ferror(f);
  if (fclose(f) != 0 || bad) {
    remove(temp);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: write failed", path);
  }
  return bk_commit_temp(temp, path, err);
}

extern "C" void mesh_io_free(mesh_tris_t *m) {
  if (!m) return;
  free(m->positions);
  free(m->indices);
  memset(m, 0, sizeof *m);
}
