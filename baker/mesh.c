/* mesh.c: scene transform and topology checks on triangle soups (see mesh.h). */
#include "mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void mesh_transform(mesh_tris_t *m, const scene_object_t *obj) {
  const double deg = 3.14159265358979323846 / 180.0;
  double c[3], s[3];
  for (int a = 0; a < 3; a++) {
    c[a] = cos(obj->rotate_deg[a] * deg);
    s[a] = sin(obj->rotate_deg[a] * deg);
  }
  /* R = Rz * Ry * Rx, so X is applied first */
  double rx[3][3] = {{1, 0, 0}, {0, c[0], -s[0]}, {0, s[0], c[0]}};
  double ry[3][3] = {{c[1], 0, s[1]}, {0, 1, 0}, {-s[1], 0, c[1]}};
  double rz[3][3] = {{c[2], -s[2], 0}, {s[2], c[2], 0}, {0, 0, 1}};
  double ryx[3][3], r[3][3];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      ryx[i][j] = 0.0;
      for (int k = 0; k < 3; k++) ryx[i][j] += ry[i][k] * rx[k][j];
    }
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      r[i][j] = 0.0;
      for (int k = 0; k < 3; k++) r[i][j] += rz[i][k] * ryx[k][j];
    }
  for (int v = 0; v < m->vertex_count; v++) {
    float *p = m->positions + 3 * (size_t)v;
    double q[3] = {p[0] * (double)obj->scale[0], p[1] * (double)obj->scale[1],
                   p[2] * (double)obj->scale[2]};
    for (int i = 0; i < 3; i++)
      p[i] = (float)(r[i][0] * q[0] + r[i][1] * q[1] + r[i][2] * q[2] + obj->translate[i]);
  }
}

/* --- topology --------------------------------------------------------------- */

typedef struct weld_key {
  float p[3];
  int index;
} weld_key_t;

static int cmp_weld(const void *a, const void *b) {
  const weld_key_t *x = a, *y = b;
  for (int i = 0; i < 3; i++) {
    if (x->p[i] < y->p[i]) return -1;
    if (x->p[i] > y->p[i]) return 1;
  }
  return 0;
}

static int cmp_u64(const void *a, const void *b) {
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return x < y ? -1 : x > y;
}

static int uf_find(int *parent, int x) {
  while (parent[x] != x) {
    parent[x] = parent[parent[x]]; /* path halving */
    x = parent[x];
  }
  return x;
}

/* Zero area: the height on the longest edge is below float resolution. */
static int zero_area(const float *a, const float *b, const float *c) {
  double e0[3], e1[3], e2[3], n[3];
  for (int i = 0; i < 3; i++) {
    e0[i] = (double)b[i] - a[i];
    e1[i] = (double)c[i] - a[i];
    e2[i] = (double)c[i] - b[i];
  }
  n[0] = e0[1] * e1[2] - e0[2] * e1[1];
  n[1] = e0[2] * e1[0] - e0[0] * e1[2];
  n[2] = e0[0] * e1[1] - e0[1] * e1[0];
  double area2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]; /* (2 A)^2 */
  double l0 = e0[0] * e0[0] + e0[1] * e0[1] + e0[2] * e0[2];
  double l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
  double l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  double lmax = fmax(l0, fmax(l1, l2));
  /* 2A = height * longest edge; height <= 1e-7 * longest edge */
  return area2 <= 1e-14 * lmax * lmax;
}

/* Welds equal positions: canon[v] is the id of the first of them in
 * sorted order. */
static void weld_vertices(const mesh_tris_t *m, weld_key_t *keys, int *canon,
                          mesh_report_t *out) {
  for (int v = 0; v < m->vertex_count; v++) {
    memcpy(keys[v].p, m->positions + 3 * (size_t)v, sizeof keys[v].p);
    keys[v].index = v;
  }
  qsort(keys, (size_t)m->vertex_count, sizeof *keys, cmp_weld);
  for (int v = 0; v < m->vertex_count; v++) {
    if (v > 0 && cmp_weld(&keys[v - 1], &keys[v]) == 0) {
      canon[keys[v].index] = canon[keys[v - 1].index];
    } else {
      canon[keys[v].index] = keys[v].index;
      out->welded_vertices++;
    }
  }
}

/* The edges as (min, max) welded ids, sorted; returns their count. A face
 * with a repeated vertex has no proper edges and would only hide its
 * neighbours' boundary, so it is left out. */
static size_t collect_edges(const mesh_tris_t *m, const int *canon, uint64_t *edges,
                            mesh_report_t *out) {
  size_t ne = 0;
  for (int t = 0; t < m->triangle_count; t++) {
    const int *f = m->indices + 3 * (size_t)t;
    int a = canon[f[0]], b = canon[f[1]], c = canon[f[2]];
    if (a == b || b == c || a == c) {
      out->degenerate_faces++;
      continue;
    }
    if (zero_area(m->positions + 3 * (size_t)a, m->positions + 3 * (size_t)b,
                  m->positions + 3 * (size_t)c))
      out->degenerate_faces++;
    int corner[3] = {a, b, c};
    for (int e = 0; e < 3; e++) {
      uint32_t p = (uint32_t)corner[e], q = (uint32_t)corner[(e + 1) % 3];
      edges[ne++] = p < q ? ((uint64_t)p << 32 | q) : ((uint64_t)q << 32 | p);
    }
  }
  qsort(edges, ne, sizeof *edges, cmp_u64);
  return ne;
}

/* Counts boundary (one face) and non-manifold (more than two) edges, and
 * joins the ends of each boundary edge in the union-find `parent`. */
static void classify_edges(const uint64_t *edges, size_t ne, int vertices, int *parent,
                           mesh_report_t *out) {
  for (int v = 0; v < vertices; v++) parent[v] = v;
  for (size_t i = 0; i < ne;) {
    size_t j = i;
    while (j < ne && edges[j] == edges[i]) j++;
    size_t uses = j - i;
    if (uses == 1) {
      out->boundary_edges++;
      int p = uf_find(parent, (int)(edges[i] >> 32)), q = uf_find(parent, (int)(edges[i] & 0xffffffffu));
      if (p != q) parent[p] = q;
    } else if (uses > 2) {
      out->nonmanifold_edges++;
    }
    i = j;
  }
}

/* One loop per union-find root among the boundary vertices; `seen` (zeroed,
 * one per vertex) marks the roots already counted. */
static void count_loops(const uint64_t *edges, size_t ne, int *parent, int *seen,
                        mesh_report_t *out) {
  for (size_t i = 0; i < ne;) {
    size_t j = i;
    while (j < ne && edges[j] == edges[i]) j++;
    if (j - i == 1) {
      int ends[2] = {(int)(edges[i] >> 32), (int)(edges[i] & 0xffffffffu)};
      for (int k = 0; k < 2; k++) {
        int root = uf_find(parent, ends[k]);
        if (!seen[root]) {
          seen[root] = 1;
          out->boundary_loops++;
        }
      }
    }
    i = j;
  }
}

int mesh_check(const mesh_tris_t *m, mesh_report_t *out, bk_error_t *err) {
  memset(out, 0, sizeof *out);
  out->triangles = m->triangle_count;
  out->vertices = m->vertex_count;
  if (m->vertex_count <= 0 || m->triangle_count <= 0) return BK_OK;

  const size_t nv = (size_t)m->vertex_count;
  weld_key_t *keys = bk_calloc(nv, sizeof *keys, "mesh check: weld keys", err);
  int *canon = bk_calloc(nv, sizeof *canon, "mesh check: welded ids", err);
  int *parent = bk_calloc(nv, sizeof *parent, "mesh check: loops", err);
  uint64_t *edges = bk_calloc((size_t)m->triangle_count * 3, sizeof *edges, "mesh check: edges", err);
  int rc = keys && canon && parent && edges ? BK_OK : BK_ERR_RUNTIME;
  if (rc == BK_OK) {
    weld_vertices(m, keys, canon, out);
    const size_t ne = collect_edges(m, canon, edges, out);
    classify_edges(edges, ne, m->vertex_count, parent, out);
    memset(canon, 0, nv * sizeof *canon); /* no longer needed: the loops' marks */
    count_loops(edges, ne, parent, canon, out);
  }
  free(keys);
  free(canon);
  free(parent);
  free(edges);
  return rc;
}

int mesh_check_is_clean(const mesh_report_t *r) {
  return r->boundary_edges == 0 && r->nonmanifold_edges == 0 && r->degenerate_faces == 0;
}

void mesh_check_summary(const mesh_report_t *r, char *buf, size_t len) {
  int n = snprintf(buf, len, "%d triangles", r->triangles);
  if (mesh_check_is_clean(r)) {
    snprintf(buf + n, len - (size_t)n, ", closed 2-manifold");
    return;
  }
  const char *sep = ", ";
  if (r->boundary_edges && (size_t)n < len) {
    n += snprintf(buf + n, len - (size_t)n, "%sopen: %d boundary edge%s in %d loop%s", sep,
                  r->boundary_edges, r->boundary_edges == 1 ? "" : "s", r->boundary_loops,
                  r->boundary_loops == 1 ? "" : "s");
    sep = "; ";
  }
  if (r->nonmanifold_edges && (size_t)n < len) {
    n += snprintf(buf + n, len - (size_t)n, "%s%d non-manifold edge%s", sep, r->nonmanifold_edges,
                  r->nonmanifold_edges == 1 ? "" : "s");
    sep = "; ";
  }
  if (r->degenerate_faces && (size_t)n < len)
    snprintf(buf + n, len - (size_t)n, "%s%d degenerate face%s", sep, r->degenerate_faces,
             r->degenerate_faces == 1 ? "" : "s");
}

void mesh_check_log(const char *name, const mesh_report_t *r) {
  char summary[256];
  mesh_check_summary(r, summary, sizeof summary);
  if (mesh_check_is_clean(r))
    bk_log(1, "%s: %s", name, summary);
  else
    bk_warn("%s: %s; filled by a 3-axis ray-parity vote", name, summary);
}
