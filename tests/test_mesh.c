/* test_mesh.c: mesh reading (mesh_io), the scene transform and the topology
 * counts of mesh_check, on small meshes whose answers are known by hand.
 *
 * Usage: test_mesh CASE DIR, CASE one of io, binary, check, transform. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "mesh.h"
#include "mesh_io.h"
#include "test_util.h"

/* Reads `path`; checks the counts and that every vertex of `expect` (n of
 * them) is present. */
static void expect_mesh(const char *path, int vertices, int triangles, const float *expect, int n) {
  mesh_tris_t m;
  bk_error_t err;
  int rc = mesh_io_read(path, &m, &err);
  if (rc != BK_OK) {
    fprintf(stderr, "%s\n", err.msg);
    tu_failures++;
    return;
  }
  printf("%s: %d vertices, %d triangles\n", strrchr(path, '/') + 1, m.vertex_count,
         m.triangle_count);
  EXPECT(m.vertex_count == vertices);
  EXPECT(m.triangle_count == triangles);
  for (int i = 0; i < n; i++) {
    int found = 0;
    for (int v = 0; v < m.vertex_count && !found; v++)
      found = m.positions[3 * v] == expect[3 * i] && m.positions[3 * v + 1] == expect[3 * i + 1] &&
              m.positions[3 * v + 2] == expect[3 * i + 2];
    EXPECT(found);
  }
  for (int t = 0; t < 3 * m.triangle_count; t++)
    EXPECT(m.indices[t] >= 0 && m.indices[t] < m.vertex_count);
  mesh_io_free(&m);
}

static const float TETRA[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
static const int TETRA_F[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};

static void case_io(void) {
  char p[4096];
  /* round trip through mesh_io_write_obj keeps floats bit for bit */
  float pos[12] = {0.1f, -0.3f, 1e-7f, 1.0f / 3.0f, 0, 0, 0, 12345.678f, 0, 0, 0, -2.5e-3f};
  mesh_tris_t m = {pos, 4, (int *)TETRA_F, 4};
  bk_error_t err;
  snprintf(p, sizeof p, "%s/roundtrip.obj", tu_dir);
  EXPECT(mesh_io_write_obj(p, &m, &err) == BK_OK);
  mesh_tris_t back;
  if (mesh_io_read(p, &back, &err) == BK_OK) {
    EXPECT(back.vertex_count == 4 && back.triangle_count == 4);
    EXPECT(back.vertex_count == 4 && memcmp(back.positions, pos, sizeof pos) == 0);
    EXPECT(back.triangle_count == 4 && memcmp(back.indices, TETRA_F, sizeof TETRA_F) == 0);
    mesh_io_free(&back);
  } else {
    fprintf(stderr, "%s\n", err.msg);
    tu_failures++;
  }
  /* polygons are fan-triangulated */
  tu_write_text("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", p, sizeof p);
  float quad[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  expect_mesh(p, 4, 2, quad, 4);
  tu_write_text("UPPER.OBJ", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
             p, sizeof p);
  expect_mesh(p, 4, 4, TETRA, 4);
  tu_write_text("tetra.off", "OFF\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
             "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n", p, sizeof p);
  expect_mesh(p, 4, 4, TETRA, 4);
  tu_write_text("tetra.ply",
             "ply\nformat ascii 1.0\ncomment inf is a word here\nelement vertex 4\n"
             "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
             "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0 255\n1 0 0 0\n0 1 0 0\n0 0 1 0\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
             p, sizeof p);
  expect_mesh(p, 4, 4, TETRA, 4);
  /* STL repeats vertices per facet; OpenMesh merges equal ones */
  char stl[4096];
  int n = snprintf(stl, sizeof stl, "solid tetra\n");
  for (int t = 0; t < 4; t++) {
    n += snprintf(stl + n, sizeof stl - (size_t)n, "facet normal 0 0 0\nouter loop\n");
    for (int q = 0; q < 3; q++) {
      const float *v = TETRA + 3 * TETRA_F[3 * t + q];
      n += snprintf(stl + n, sizeof stl - (size_t)n, "vertex %g %g %g\n", v[0], v[1], v[2]);
    }
    n += snprintf(stl + n, sizeof stl - (size_t)n, "endloop\nendfacet\n");
  }
  snprintf(stl + n, sizeof stl - (size_t)n, "endsolid tetra\n");
  tu_write_text("tetra.stl", stl, p, sizeof p);
  expect_mesh(p, 4, 4, TETRA, 4);
  /* binary STL, header starting with "solid" as some exporters write it */
  snprintf(p, sizeof p, "%s/tetra_binary.stl", tu_dir);
  FILE *f = fopen(p, "wb");
  if (f) {
    char header[80] = "solid but binary";
    unsigned count = 4;
    fwrite(header, 1, 80, f);
    fwrite(&count, 4, 1, f);
    for (int t = 0; t < 4; t++) {
      float rec[12] = {0};
      for (int q = 0; q < 3; q++) memcpy(rec + 3 + 3 * q, TETRA + 3 * TETRA_F[3 * t + q], 12);
      unsigned short attr = 0;
      fwrite(rec, 4, 12, f);
      fwrite(&attr, 2, 1, f);
    }
    fclose(f);
    expect_mesh(p, 4, 4, TETRA, 4);
  }
}

/* A binary file built value by value, in either byte order. */
typedef struct {
  unsigned char b[1024];
  size_t n;
  int big;
} bytes_t;

static void put(bytes_t *o, uint64_t v, int size) {
  for (int k = 0; k < size; k++)
    o->b[o->n++] = (unsigned char)(v >> (8 * (o->big ? size - 1 - k : k)));
}

static void put_text(bytes_t *o, const char *s) {
  memcpy(o->b + o->n, s, strlen(s));
  o->n += strlen(s);
}

static void save(const char *name, const bytes_t *o, char *p, size_t len) {
  tu_path(p, len, name);
  FILE *f = fopen(p, "wb");
  REQUIRE(f != NULL);
  fwrite(o->b, 1, o->n, f);
  fclose(f);
}

/* The tetrahedron's vertices as floats, then its faces, each a count of
 * count_bytes bytes and three ints; the last face's count and last index
 * replaced by last_count and last_index (3 and 3 for the true mesh). */
static void put_tetra(bytes_t *o, int count_bytes, int64_t last_count, int64_t last_index) {
  for (int k = 0; k < 12; k++) {
    uint32_t u;
    memcpy(&u, &TETRA[k], 4);
    put(o, u, 4);
  }
  for (int t = 0; t < 4; t++) {
    put(o, (uint64_t)(t == 3 ? last_count : 3), count_bytes);
    for (int q = 0; q < 3; q++)
      put(o, (uint64_t)(t == 3 && q == 2 ? last_index : TETRA_F[3 * t + q]), 4);
  }
}

/* A binary PLY of it; `tail` goes before end_header. */
static void ply_tetra(bytes_t *o, int big, long vertices, const char *count_type,
                      int64_t last_count, int64_t last_index, const char *tail) {
  char head[512];
  snprintf(head, sizeof head,
           "ply\nformat binary_%s_endian 1.0\ncomment made by test_mesh\nelement vertex %ld\n"
           "property float x\nproperty float y\nproperty float z\nelement face 4\n"
           "property list %s int vertex_indices\n%send_header\n",
           big ? "big" : "little", vertices, count_type, tail);
  *o = (bytes_t){.big = big};
  put_text(o, head);
  put_tetra(o, strcmp(count_type, "int") ? 1 : 4, last_count, last_index);
}

static void off_tetra(bytes_t *o, int64_t vertices, int64_t faces, int64_t last_count,
                      int64_t last_index) {
  *o = (bytes_t){0};
  put_text(o, "OFF BINARY\n");
  put(o, (uint64_t)vertices, 4);
  put(o, (uint64_t)faces, 4);
  put(o, 0, 4);
  put_tetra(o, 4, last_count, last_index);
}

/* mesh_io_read refuses path, naming it and saying `has`. */
static void expect_refused(const char *path, const char *has) {
  mesh_tris_t m;
  bk_error_t err;
  if (mesh_io_read(path, &m, &err) == BK_OK) {
    fprintf(stderr, "%s was read, expected a refusal saying '%s'\n", path, has);
    tu_failures++;
    mesh_io_free(&m);
    return;
  }
  printf("refused: %s\n", err.msg);
  EXPECT(strstr(err.msg, path) != NULL);
  EXPECT(strstr(err.msg, has) != NULL);
}

/* Binary OFF and PLY: the tetrahedron read in both PLY byte orders; counts
 * that do not fit in the file (OpenMesh reserves or reads by them: a face
 * count of -1 is four billion reads, each kept), indices beyond the
 * vertices, a short body and a list OpenMesh misreads are refused. */
static void case_binary(void) {
  char p[4096];
  bytes_t o;
  for (int big = 0; big <= 1; big++) {
    ply_tetra(&o, big, 4, "uchar", 3, 3, "");
    save(big ? "tetra_be.ply" : "tetra_le.ply", &o, p, sizeof p);
    expect_mesh(p, 4, 4, TETRA, 4);
  }
  ply_tetra(&o, 0, 4, "int", -1, 3, "");
  save("count_minus_one.ply", &o, p, sizeof p);
  expect_refused(p, "face 3: its count of entries (-1) does not fit in the");
  ply_tetra(&o, 0, 4, "uchar", 3, 555555555, "");
  save("index_huge.ply", &o, p, sizeof p);
  expect_refused(p, "face 3: vertex index 555555555 is not one of the 4 vertices");
  ply_tetra(&o, 1, 2000000000, "uchar", 3, 3, "");
  save("vertex_count_huge.ply", &o, p, sizeof p);
  expect_refused(p, "element vertex: 2000000000 rows of 12 bytes do not fit");
  ply_tetra(&o, 0, 4, "uchar", 3, 3, "");
  o.n -= 13; /* the last face: its count and three indices */
  save("short.ply", &o, p, sizeof p);
  expect_refused(p, "the binary body ends inside face 3");
  /* OpenMesh 9 then starts the body a byte late and misreads every face */
  ply_tetra(&o, 0, 4, "uchar", 3, 3, "comment last\n");
  save("comment_last.ply", &o, p, sizeof p);
  expect_refused(p, "OpenMesh would read the binary body from byte");
  tu_write_text("vertex_list.ply",
                "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
                "property list uchar float extra\nend_header\n",
                p, sizeof p);
  expect_refused(p, "reads only a face's vertex_indices as a list");

  off_tetra(&o, 4, 4, 3, 3);
  save("tetra.off", &o, p, sizeof p);
  expect_mesh(p, 4, 4, TETRA, 4);
  off_tetra(&o, 2000000000, 4, 3, 3);
  save("vertex_count_huge.off", &o, p, sizeof p);
  expect_refused(p, "2000000000 vertices of 12 bytes and 4 faces do not fit");
  off_tetra(&o, 4, 4, -1, 3);
  save("count_minus_one.off", &o, p, sizeof p);
  expect_refused(p, "face 3: its count of entries (4294967295) does not fit");
  off_tetra(&o, 4, 4, 3, 555555555);
  save("index_huge.off", &o, p, sizeof p);
  expect_refused(p, "vertex index 555555555 is not one of the 4 vertices");
}

static void check_counts(const char *what, const mesh_tris_t *m, int degenerate, int boundary,
                         int loops, int nonmanifold, const char *summary_has) {
  mesh_report_t r;
  bk_error_t err;
  EXPECT(mesh_check(m, &r, &err) == BK_OK);
  char summary[256];
  mesh_check_summary(&r, summary, sizeof summary);
  printf("%-28s %s\n", what, summary);
  EXPECT(r.degenerate_faces == degenerate);
  EXPECT(r.boundary_edges == boundary);
  EXPECT(r.boundary_loops == loops);
  EXPECT(r.nonmanifold_edges == nonmanifold);
  EXPECT(strstr(summary, summary_has) != NULL);
  mesh_check_log(what, &r);
}

static void case_check(void) {
  /* a unit cube, 12 triangles; face pairs in order -z, +z, -y, +y, -x, +x */
  float cube[24] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
  int cube_f[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                    3, 6, 2, 3, 7, 6, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
  mesh_tris_t m = {cube, 8, cube_f, 12};
  check_counts("closed cube", &m, 0, 0, 0, 0, "12 triangles, closed 2-manifold");
  m.indices = cube_f + 6; /* without -z */
  m.triangle_count = 10;
  check_counts("cube without its bottom", &m, 0, 4, 1, 0, "open: 4 boundary edges in 1 loop");
  int two_holes[24];
  memcpy(two_holes, cube_f + 12, sizeof two_holes); /* without -z and +z */
  m.indices = two_holes;
  m.triangle_count = 8;
  check_counts("cube without -z and +z", &m, 0, 8, 2, 0, "open: 8 boundary edges in 2 loops");

  /* the same cube with every triangle's vertices duplicated (an STL-like
   * soup): welding by position restores the closed cube */
  float soup[108];
  int soup_f[36];
  for (int i = 0; i < 36; i++) {
    memcpy(soup + 3 * i, cube + 3 * cube_f[i], 12);
    soup_f[i] = i;
  }
  mesh_tris_t s = {soup, 36, soup_f, 12};
  check_counts("cube as a soup", &s, 0, 0, 0, 0, "closed");

  /* three fins on one edge, a zero-area face and a face with a repeated vertex */
  float fins[18] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0, 2, 0, 0};
  int fins_f[15] = {0, 1, 2, 0, 1, 3, 0, 1, 4, 0, 1, 5, 2, 2, 3};
  mesh_tris_t fm = {fins, 6, fins_f, 3};
  check_counts("three fins", &fm, 0, 6, 1, 1, "1 non-manifold edge");
  fm.triangle_count = 5;
  /* the zero-area face (0,1,5) lies along edge (0,1): its two other edges are open */
  check_counts("fins + degenerate faces", &fm, 2, 8, 1, 1, "2 degenerate faces");

  /* OpenMesh duplicates the vertices of a face it cannot attach (a third face
   * on an edge); the weld must still see one non-manifold edge */
  char p[4096];
  tu_write_text("fins.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 -1 0\n"
             "f 1 2 3\nf 1 2 4\nf 1 2 5\n", p, sizeof p);
  mesh_tris_t om;
  bk_error_t err;
  if (mesh_io_read(p, &om, &err) == BK_OK) {
    printf("fins.obj through OpenMesh: %d vertices for 5 in the file\n", om.vertex_count);
    check_counts("fins.obj via OpenMesh", &om, 0, 6, 1, 1, "non-manifold");
    mesh_io_free(&om);
  } else {
    fprintf(stderr, "%s\n", err.msg);
    tu_failures++;
  }
}

static void transform_point(const float in[3], const float scale[3], const float rot[3],
                            const float tr[3], float out[3]) {
  scene_object_t o;
  memset(&o, 0, sizeof o);
  memcpy(o.scale, scale, sizeof o.scale);
  memcpy(o.rotate_deg, rot, sizeof o.rotate_deg);
  memcpy(o.translate, tr, sizeof o.translate);
  float p[3] = {in[0], in[1], in[2]};
  int idx[3] = {0, 0, 0};
  mesh_tris_t m = {p, 1, idx, 1};
  mesh_transform(&m, &o);
  memcpy(out, p, sizeof p);
}

static void expect_transform(const float in[3], const float scale[3], const float rot[3],
                             const float tr[3], const float want[3]) {
  float out[3];
  transform_point(in, scale, rot, tr, out);
  printf("(%g, %g, %g) scale (%g, %g, %g) rotate (%g, %g, %g) translate (%g, %g, %g) -> "
         "(%.6f, %.6f, %.6f)\n",
         in[0], in[1], in[2], scale[0], scale[1], scale[2], rot[0], rot[1], rot[2], tr[0], tr[1],
         tr[2], out[0], out[1], out[2]);
  for (int a = 0; a < 3; a++) EXPECT_NEAR(out[a], want[a], 1e-6);
}

static void case_transform(void) {
  const float one[3] = {1, 1, 1}, zero[3] = {0, 0, 0};
  const float x[3] = {1, 0, 0}, y[3] = {0, 1, 0}, z[3] = {0, 0, 1};
  /* right-handed: +90 about z takes x to y, about x takes y to z, about y z to x */
  expect_transform(x, one, (float[3]){0, 0, 90}, zero, y);
  expect_transform(y, one, (float[3]){90, 0, 0}, zero, z);
  expect_transform(z, one, (float[3]){0, 90, 0}, zero, x);
  /* X before Y: y -> z (about x) -> x (about y); the other order gives z */
  expect_transform(y, one, (float[3]){90, 90, 0}, zero, x);
  /* Y before Z: z -> x (about y) -> y (about z) */
  expect_transform(z, one, (float[3]){0, 90, 90}, zero, y);
  /* scale before rotation, translation last */
  expect_transform(x, (float[3]){2, 1, 1}, (float[3]){0, 0, 90}, (float[3]){1, 2, 3},
                   (float[3]){1, 4, 3});
  /* a rotation keeps lengths */
  float p[3] = {0.3f, -1.2f, 0.7f}, out[3];
  transform_point(p, one, (float[3]){17, -43, 121}, zero, out);
  EXPECT_NEAR(sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]),
             sqrt(0.09 + 1.44 + 0.49), 1e-6);
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: test_mesh CASE DIR\n");
    return 2;
  }
  tu_dir = argv[2];
  mkdir(tu_dir, 0777);
  if (!strcmp(argv[1], "io")) case_io();
  else if (!strcmp(argv[1], "binary")) case_binary();
  else if (!strcmp(argv[1], "check")) case_check();
  else if (!strcmp(argv[1], "transform")) case_transform();
  else {
    fprintf(stderr, "unknown case %s\n", argv[1]);
    return 2;
  }
  if (tu_failures) fprintf(stderr, "%d check(s) failed\n", tu_failures);
  return tu_failures ? 1 : 0;
}
