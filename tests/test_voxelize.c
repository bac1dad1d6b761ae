/* test_voxelize.c: the voxelization stage against analytic answers.
 *
 * Usage: test_voxelize CASE DIR [MESH]. Each case writes its files into DIR
 * (under the build directory) and fills a scene_t by hand, so the stage is
 * tested without the scene loader.
 *   sphere     icosphere of radius r: volume where n > (n_in+n_out)/2 at 64^3
 *              and 128^3 against 4/3 pi r^3 and the polyhedron's own volume
 *   profile    n at every voxel against w(d) of the sphere's signed distance
 *   smoothing  ior_smoothing 0.5 and 8: finite, bounded, transition width s
 *   bunny      the open Stanford bunny (MESH) fills: volume against the
 *              closed-hull volume, inside test against the winding number
 *   objects    nested spheres composited in order; transform applied
 *   ties       vertices on voxel centres: rays through vertices and edges
 *   open       a bottomless cube fills like the closed one; clipped objects
 *   medium     constants, ior_vdb and density_vdb; kernel-specialisation flags
 *   scan       the summary of a grey volume (one value per voxel) equals, bit
 *              for bit, the summary of the same values stored as RGB
 *   bad_input  missing, empty, NaN/Inf meshes: BK_ERR_INPUT naming the file */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "mesh.h"
#include "mesh_io.h"
#include "out_grids.h"
#include "vdbio.h"
#include "brick_grid.h"
#include "voxelize.h"
#include "vox_medium.h"
#include "test_util.h"

static const double PI = 3.14159265358979323846;

/* --- meshes -------------------------------------------------------------------- */

/* Icosphere: an icosahedron subdivided `level` times, vertices pushed onto the
 * sphere of radius r around c. */
static mesh_tris_t icosphere(int level, double r, const double c[3]) {
  const double t = (1.0 + sqrt(5.0)) / 2.0;
  double base[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                        {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                      {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                      {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                      {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  int nf = 20 << (2 * level), nv_max = 12 + 3 * nf;
  double *v = malloc(sizeof(double) * 3 * (size_t)nv_max);
  int *f = malloc(sizeof(int) * 3 * (size_t)nf), *g = malloc(sizeof(int) * 3 * (size_t)nf);
  int nv = 12, cur = 20;
  for (int i = 0; i < 12; i++) {
    double l = sqrt(base[i][0] * base[i][0] + base[i][1] * base[i][1] + base[i][2] * base[i][2]);
    for (int a = 0; a < 3; a++) v[3 * i + a] = base[i][a] / l;
  }
  memcpy(f, faces, sizeof faces);
  for (int l = 0; l < level; l++) {
    int next = 0;
    /* edge -> midpoint, so neighbours share it: key (min,max) in an
     * open-addressing table */
    size_t cap = (size_t)cur * 4 + 7;
    long long *keys = malloc(sizeof(long long) * cap);
    int *vals = malloc(sizeof(int) * cap);
    for (size_t i = 0; i < cap; i++) keys[i] = -1;
    for (int fi = 0; fi < cur; fi++) {
      int m[3];
      for (int e = 0; e < 3; e++) {
        int a = f[3 * fi + e], b = f[3 * fi + (e + 1) % 3];
        long long key = a < b ? (long long)a * nv_max + b : (long long)b * nv_max + a;
        size_t h = (size_t)(key * 2654435761u) % cap;
        while (keys[h] != -1 && keys[h] != key) h = (h + 1) % cap;
        if (keys[h] == -1) {
          double p[3], len = 0;
          for (int q = 0; q < 3; q++) {
            p[q] = v[3 * a + q] + v[3 * b + q];
            len += p[q] * p[q];
          }
          len = sqrt(len);
          for (int q = 0; q < 3; q++) v[3 * nv + q] = p[q] / len;
          keys[h] = key;
          vals[h] = nv++;
        }
        m[e] = vals[h];
      }
      int a = f[3 * fi], b = f[3 * fi + 1], c2 = f[3 * fi + 2];
      int tri[4][3] = {{a, m[0], m[2]}, {b, m[1], m[0]}, {c2, m[2], m[1]}, {m[0], m[1], m[2]}};
      memcpy(g + 3 * next, tri, sizeof tri);
      next += 4;
    }
    free(keys);
    free(vals);
    int *tmp = f;
    f = g;
    g = tmp;
    cur = next;
  }
  mesh_tris_t out;
  out.vertex_count = nv;
  out.triangle_count = cur;
  out.positions = malloc(sizeof(float) * 3 * (size_t)nv);
  out.indices = f;
  for (int i = 0; i < nv; i++)
    for (int a = 0; a < 3; a++) out.positions[3 * i + a] = (float)(c[a] + r * v[3 * i + a]);
  free(v);
  free(g);
  return out;
}

/* Enclosed volume by the divergence theorem, about `o` (for a closed mesh
 * any o gives the same answer; for a planar hole, o on its plane closes it). */
static double mesh_volume(const mesh_tris_t *m, const double o[3]) {
  double vol = 0.0;
  for (int t = 0; t < m->triangle_count; t++) {
    double p[3][3];
    for (int q = 0; q < 3; q++)
      for (int a = 0; a < 3; a++) p[q][a] = m->positions[3 * m->indices[3 * t + q] + a] - o[a];
    vol += p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) -
           p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0]) +
           p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]);
  }
  return vol / 6.0;
}

/* Smallest distance from c to the planes of the faces (the inradius of a
 * convex polyhedron around c). */
static double mesh_inradius(const mesh_tris_t *m, const double c[3]) {
  double best = INFINITY;
  for (int t = 0; t < m->triangle_count; t++) {
    double p[3][3];
    for (int q = 0; q < 3; q++)
      for (int a = 0; a < 3; a++) p[q][a] = m->positions[3 * m->indices[3 * t + q] + a];
    double e1[3], e2[3], n[3];
    for (int a = 0; a < 3; a++) {
      e1[a] = p[1][a] - p[0][a];
      e2[a] = p[2][a] - p[0][a];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    double d = fabs(n[0] * (p[0][0] - c[0]) + n[1] * (p[0][1] - c[1]) + n[2] * (p[0][2] - c[2])) / l;
    if (d < best) best = d;
  }
  return best;
}

/* Generalized winding number at p (Jacobson et al. 2013): the solid angle of
 * every triangle (Van Oosterom-Strackee) over 4 pi. 1 inside a closed mesh,
 * 0 outside, fractional near holes. */
static double winding_number(const mesh_tris_t *m, const double p[3]) {
  double total = 0.0;
  for (int t = 0; t < m->triangle_count; t++) {
    double a[3][3], l[3];
    for (int q = 0; q < 3; q++) {
      for (int k = 0; k < 3; k++) a[q][k] = m->positions[3 * m->indices[3 * t + q] + k] - p[k];
      l[q] = sqrt(a[q][0] * a[q][0] + a[q][1] * a[q][1] + a[q][2] * a[q][2]);
    }
    double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                 a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                 a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    double d01 = a[0][0] * a[1][0] + a[0][1] * a[1][1] + a[0][2] * a[1][2];
    double d12 = a[1][0] * a[2][0] + a[1][1] * a[2][1] + a[1][2] * a[2][2];
    double d20 = a[2][0] * a[0][0] + a[2][1] * a[0][1] + a[2][2] * a[0][2];
    double den = l[0] * l[1] * l[2] + d01 * l[2] + d12 * l[0] + d20 * l[1];
    total += 2.0 * atan2(det, den);
  }
  return total / (4.0 * PI);
}

static void scene_init(scene_t *s, float lo, float hi, int resolution, float smoothing) {
  scene_defaults(s);
  snprintf(s->path, sizeof s->path, "%s/hand-made-scene", tu_dir);
  for (int a = 0; a < 3; a++) {
    s->bounds_min[a] = lo;
    s->bounds_max[a] = hi;
  }
  s->resolution = resolution;
  s->ior_smoothing = smoothing;
  snprintf(s->where_resolution, sizeof s->where_resolution, "test.json:3:5: grid.resolution");
}

static void object_init(scene_object_t *o, const char *mesh, float ior) {
  scene_object_defaults(o);
  snprintf(o->mesh, sizeof o->mesh, "%s", mesh);
  snprintf(o->where, sizeof o->where, "test.json:9:12: objects[0].mesh");
  o->ior = ior;
}

static int write_mesh(const char *name, const mesh_tris_t *m, char *path, size_t len) {
  bk_error_t err;
  tu_path(path, len, name);
  if (mesh_io_write_obj(path, m, &err) != BK_OK) {
    fprintf(stderr, "cannot write %s: %s\n", path, err.msg);
    tu_failures++;
    return 0;
  }
  return 1;
}

static int build(const scene_t *s, volume_t *v) {
  bk_error_t err;
  bk_timings_t timings = {0};
  int rc = vox_build(s, v, &timings, &err);
  if (rc != BK_OK) {
    fprintf(stderr, "vox_build failed (%d): %s\n", rc, err.msg);
    tu_failures++;
  }
  return rc == BK_OK;
}

/* Voxels (as volume) where n is above the mid value, and the smooth
 * estimate sum of w over the grid. */
static void inside_volume(const volume_t *v, float n_out, float n_in, double *count_vol,
                          double *smooth_vol) {
  const double vv = pow(v->dims.voxel_size, 3.0), mid = 0.5 * (n_in + n_out);
  size_t inside = 0;
  double wsum = 0.0;
  for (size_t i = 0; i < grid_count(&v->dims); i++) {
    if (v->ior[i] > mid) inside++;
    wsum += (v->ior[i] - n_out) / (n_in - n_out);
  }
  *count_vol = (double)inside * vv;
  *smooth_vol = wsum * vv;
}

/* --- cases ---------------------------------------------------------------------- */

static const double SPHERE_C[3] = {0.0123, -0.0311, 0.0217}; /* off the lattice's symmetry */
static const double SPHERE_R = 0.7;

static void case_sphere(void) {
  const int level = 5; /* its volume is 0.054% short of the sphere's; level 4: 0.22% */
  mesh_tris_t m = icosphere(level, SPHERE_R, SPHERE_C);
  char path[4096];
  if (!write_mesh("sphere.obj", &m, path, sizeof path)) return;
  const double exact = 4.0 / 3.0 * PI * pow(SPHERE_R, 3.0), poly = mesh_volume(&m, SPHERE_C);
  printf("icosphere level %d: %d triangles, r = %g; 4/3 pi r^3 = %.6f, polyhedron %.6f (%.3f%%)\n",
         level, m.triangle_count, SPHERE_R, exact, poly, 100.0 * (poly - exact) / exact);
  double err_sphere[2], err_poly[2];
  int res[2] = {64, 128};
  for (int ri = 0; ri < 2; ri++) {
    scene_t s;
    scene_object_t o;
    volume_t v;
    scene_init(&s, -1.0f, 1.0f, res[ri], 2.0f);
    object_init(&o, path, 1.5f);
    s.objects = &o;
    s.object_count = 1;
    if (!build(&s, &v)) continue;
    double count_vol, smooth_vol;
    inside_volume(&v, 1.0f, 1.5f, &count_vol, &smooth_vol);
    err_sphere[ri] = fabs(count_vol - exact) / exact;
    err_poly[ri] = fabs(count_vol - poly) / poly;
    printf("%3d^3: volume(n > 1.25) = %.6f: %.3f%% from the sphere, %.3f%% from the polyhedron; "
           "sum of w = %.6f (%.3f%% from the polyhedron)\n",
           res[ri], count_vol, 100.0 * err_sphere[ri], 100.0 * err_poly[ri], smooth_vol,
           100.0 * (smooth_vol - poly) / poly);
    EXPECT(v.has_refraction);
    EXPECT_NEAR(v.n_min, 1.0, 0.0);
    EXPECT_NEAR(v.n_max, 1.5, 0.0);
    EXPECT(v.homogeneous && v.grey); /* all sigma zero */
    vox_free(&v);
  }
  EXPECT(err_sphere[1] < 0.015);
  EXPECT(err_sphere[1] < err_sphere[0]);
  EXPECT(err_poly[1] < err_poly[0]);
  mesh_io_free(&m);
}

/* n at every voxel against the profile of the sphere's own signed distance.
 * The icosphere lies between its inscribed ball (r_in) and the sphere (r), so
 * its signed distance differs from the sphere's by at most r - r_in. */
static void case_profile(void) {
  mesh_tris_t m = icosphere(4, SPHERE_R, SPHERE_C);
  char path[4096];
  if (!write_mesh("profile.obj", &m, path, sizeof path)) return;
  const double r_in = mesh_inradius(&m, SPHERE_C);
  const float smoothings[2] = {2.0f, 3.5f};
  for (int si = 0; si < 2; si++) {
    const float s_vox = smoothings[si];
    scene_t s;
    scene_object_t o;
    volume_t v;
    scene_init(&s, -1.0f, 1.0f, 64, s_vox);
    object_init(&o, path, 1.5f);
    for (int ch = 0; ch < 3; ch++) o.sigma_a[ch] = 0.25f * (float)(ch + 1);
    s.objects = &o;
    s.object_count = 1;
    if (!build(&s, &v)) continue;
    const double vs = v.dims.voxel_size, slack = (SPHERE_R - r_in) / vs; /* voxels */
    /* |dw/dd| <= 1.5 / s */
    const double tol_w = 1.5 / s_vox * slack + 1e-5;
    double worst = 0.0;
    size_t transition = 0;
    for (int k = 0; k < v.dims.nz; k++)
      for (int j = 0; j < v.dims.ny; j++)
        for (int i = 0; i < v.dims.nx; i++) {
          float c[3];
          grid_voxel_center(&v.dims, i, j, k, c);
          double dx = c[0] - SPHERE_C[0], dy = c[1] - SPHERE_C[1], dz = c[2] - SPHERE_C[2];
          double d = (sqrt(dx * dx + dy * dy + dz * dz) - SPHERE_R) / vs;
          double t = (d + 0.5 * s_vox) / s_vox;
          t = t < 0 ? 0 : (t > 1 ? 1 : t);
          double w_expect = 1.0 - t * t * (3.0 - 2.0 * t);
          size_t idx = grid_index(&v.dims, i, j, k);
          double w = (v.ior[idx] - 1.0) / 0.5;
          if (fabs(w - w_expect) > worst) worst = fabs(w - w_expect);
          if (w > 0.0 && w < 1.0) transition++;
          /* sigma follows the same weight (σt = σa: σs is 0) */
          EXPECT_NEAR(vol_sigma_t(&v, idx, 2), 0.75 * w, 1e-5);
        }
    printf("smoothing %.1f voxels: worst |w - w(d_sphere)| = %.5f (tolerance %.5f from r - r_in = "
           "%.4f voxels), %zu voxels in transition\n",
           s_vox, worst, tol_w, slack, transition);
    EXPECT(worst <= tol_w);
    /* the transition shell is s voxels thick around a sphere of R voxels */
    double R = SPHERE_R / vs, shell = 4.0 / 3.0 * PI *
                                      (pow(R + 0.5 * s_vox, 3.0) - pow(R - 0.5 * s_vox, 3.0));
    EXPECT(fabs((double)transition - shell) < 0.05 * shell);
    EXPECT(!v.homogeneous && !v.grey);
    vox_free(&v);
  }
  mesh_io_free(&m);
}

static void case_smoothing(void) {
  mesh_tris_t m = icosphere(4, SPHERE_R, SPHERE_C);
  char path[4096];
  if (!write_mesh("smoothing.obj", &m, path, sizeof path)) return;
  const double exact = 4.0 / 3.0 * PI * pow(SPHERE_R, 3.0);
  const float smoothings[2] = {0.5f, 8.0f};
  const float n_out = 1.1f, n_in = 1.6f;
  for (int si = 0; si < 2; si++) {
    const float s_vox = smoothings[si];
    scene_t s;
    scene_object_t o;
    volume_t v;
    scene_init(&s, -1.0f, 1.0f, 64, s_vox);
    s.medium_ior = n_out;
    object_init(&o, path, n_in);
    s.objects = &o;
    s.object_count = 1;
    if (!build(&s, &v)) continue;
    size_t bad = 0;
    double max_step = 0.0;
    const grid_dims_t *d = &v.dims;
    for (int k = 0; k < d->nz; k++)
      for (int j = 0; j < d->ny; j++)
        for (int i = 0; i < d->nx; i++) {
          float n = v.ior[grid_index(d, i, j, k)];
          if (!isfinite(n) || n < n_out || n > n_in) bad++;
          if (i + 1 < d->nx) max_step = fmax(max_step, fabs(v.ior[grid_index(d, i + 1, j, k)] - n));
        }
    /* transition voxels along the x line through the centre: about s per crossing */
    int line = 0;
    float c[3];
    int jc = (int)floor((SPHERE_C[1] - d->origin[1]) / d->voxel_size);
    int kc = (int)floor((SPHERE_C[2] - d->origin[2]) / d->voxel_size);
    for (int i = 0; i < d->nx; i++) {
      float n = v.ior[grid_index(d, i, jc, kc)];
      if (n > n_out && n < n_in) line++;
    }
    grid_voxel_center(d, 0, jc, kc, c);
    double count_vol, smooth_vol;
    inside_volume(&v, n_out, n_in, &count_vol, &smooth_vol);
    /* the steepest step between neighbours: at most |dw/dd| = 1.5/s over one
     * voxel, and never more than the whole jump */
    double step_bound = fmin(1.0, 1.5 / s_vox) * (n_in - n_out) * 1.001;
    printf("smoothing %.1f: %zu voxels outside [%g, %g]; %d transition voxels on a diameter "
           "(expect ~%.0f); largest step %.4f (bound %.4f); volume error %.3f%%\n",
           s_vox, bad, n_out, n_in, line, 2.0 * s_vox, max_step, step_bound,
           100.0 * (count_vol - exact) / exact);
    EXPECT(bad == 0);
    EXPECT(line >= (int)floor(2.0 * s_vox) - 2 && line <= (int)ceil(2.0 * s_vox) + 2);
    EXPECT(max_step <= step_bound);
    EXPECT(fabs(count_vol - exact) / exact < 0.03);
    EXPECT_NEAR(v.n_min, n_out, 0.0);
    EXPECT_NEAR(v.n_max, n_in, 0.0);
    vox_free(&v);
  }
  mesh_io_free(&m);
}

/* The bunny's boundary vertices, for the closed-hull volume: returns their
 * centroid (its holes are nearly planar, so the divergence theorem about that
 * point adds almost nothing for the missing caps). */
static int cmp_ll(const void *x, const void *y) {
  long long a = *(const long long *)x, b = *(const long long *)y;
  return a < b ? -1 : a > b;
}

static void boundary_centroid(const mesh_tris_t *m, double out[3]) {
  /* count edge uses with a sorted list of (min,max) pairs */
  size_t ne = 3 * (size_t)m->triangle_count;
  long long *e = malloc(sizeof(long long) * ne);
  for (int t = 0; t < m->triangle_count; t++)
    for (int q = 0; q < 3; q++) {
      long long a = m->indices[3 * t + q], b = m->indices[3 * t + (q + 1) % 3];
      e[3 * t + q] = a < b ? a * m->vertex_count + b : b * m->vertex_count + a;
    }
  qsort(e, ne, sizeof *e, cmp_ll);
  double sum[3] = {0, 0, 0};
  int n = 0;
  for (size_t i = 0; i < ne;) {
    size_t j = i;
    while (j < ne && e[j] == e[i]) j++;
    if (j - i == 1) {
      long long ends[2] = {e[i] / m->vertex_count, e[i] % m->vertex_count};
      for (int k = 0; k < 2; k++, n++)
        for (int a = 0; a < 3; a++) sum[a] += m->positions[3 * ends[k] + a];
    }
    i = j;
  }
  for (int a = 0; a < 3; a++) out[a] = n ? sum[a] / n : 0.0;
  free(e);
}

static void case_bunny(const char *mesh_path) {
  mesh_tris_t m;
  bk_error_t err;
  if (mesh_io_read(mesh_path, &m, &err) != BK_OK) {
    fprintf(stderr, "%s\n", err.msg);
    tu_failures++;
    return;
  }
  mesh_report_t rep;
  EXPECT(mesh_check(&m, &rep, &err) == BK_OK);
  char summary[256];
  mesh_check_summary(&rep, summary, sizeof summary);
  printf("bunny: %s\n", summary);
  EXPECT(rep.boundary_edges > 0 && rep.boundary_loops > 0); /* it is open: the test means something */

  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int i = 0; i < m.vertex_count; i++)
    for (int a = 0; a < 3; a++) {
      lo[a] = fmin(lo[a], m.positions[3 * i + a]);
      hi[a] = fmax(hi[a], m.positions[3 * i + a]);
    }
  double bc[3], zero[3] = {0, 0, 0};
  boundary_centroid(&m, bc);
  double hull = fabs(mesh_volume(&m, bc)), about_origin = fabs(mesh_volume(&m, zero));
  printf("bunny: divergence volume about the boundary centroid %.4e, about the origin %.4e\n", hull,
         about_origin);

  scene_t s;
  scene_object_t o;
  volume_t v;
  scene_init(&s, 0.0f, 1.0f, 128, 2.0f);
  double pad = 0.05 * fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  for (int a = 0; a < 3; a++) {
    s.bounds_min[a] = (float)(lo[a] - pad);
    s.bounds_max[a] = (float)(hi[a] + pad);
  }
  object_init(&o, mesh_path, 1.5f);
  s.objects = &o;
  s.object_count = 1;
  if (!build(&s, &v)) {
    mesh_io_free(&m);
    return;
  }
  double count_vol, smooth_vol;
  inside_volume(&v, 1.0f, 1.5f, &count_vol, &smooth_vol);
  printf("bunny at %dx%dx%d: inside volume %.4e (%.2f%% from the closed hull), sum of w %.4e\n",
         v.dims.nx, v.dims.ny, v.dims.nz, count_vol, 100.0 * (count_vol - hull) / hull, smooth_vol);
  EXPECT(fabs(count_vol - hull) / hull < 0.03);

  /* a point known inside: the body's centroid, confirmed by the winding number */
  double centroid[3] = {0, 0, 0}, vol6 = 0.0;
  for (int t = 0; t < m.triangle_count; t++) {
    const float *p0 = m.positions + 3 * m.indices[3 * t], *p1 = m.positions + 3 * m.indices[3 * t + 1],
                *p2 = m.positions + 3 * m.indices[3 * t + 2];
    double q0[3], q1[3], q2[3];
    for (int a = 0; a < 3; a++) {
      q0[a] = p0[a] - bc[a];
      q1[a] = p1[a] - bc[a];
      q2[a] = p2[a] - bc[a];
    }
    double det = q0[0] * (q1[1] * q2[2] - q1[2] * q2[1]) - q0[1] * (q1[0] * q2[2] - q1[2] * q2[0]) +
                 q0[2] * (q1[0] * q2[1] - q1[1] * q2[0]);
    vol6 += det;
    for (int a = 0; a < 3; a++) centroid[a] += det * (q0[a] + q1[a] + q2[a]) / 4.0;
  }
  for (int a = 0; a < 3; a++) centroid[a] = centroid[a] / vol6 + bc[a];
  double wn = winding_number(&m, centroid);
  int ci = (int)floor((centroid[0] - v.dims.origin[0]) / v.dims.voxel_size);
  int cj = (int)floor((centroid[1] - v.dims.origin[1]) / v.dims.voxel_size);
  int ck = (int)floor((centroid[2] - v.dims.origin[2]) / v.dims.voxel_size);
  float n_centre = v.ior[grid_index(&v.dims, ci, cj, ck)];
  printf("bunny centroid (%.4f, %.4f, %.4f): winding number %.4f, n = %g\n", centroid[0],
         centroid[1], centroid[2], wn, n_centre);
  EXPECT(wn > 0.9);
  EXPECT(n_centre == 1.5f);

  /* voxel centres drawn with a fixed LCG: the inside flag must match the
   * winding number wherever that is clearly 0 or 1 */
  unsigned long long state = 12345;
  int tested = 0, disagree = 0, inside_samples = 0;
  for (int sample = 0; sample < 300; sample++) {
    int ijk[3], dims[3] = {v.dims.nx, v.dims.ny, v.dims.nz};
    for (int a = 0; a < 3; a++) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      ijk[a] = (int)((state >> 33) % (unsigned long long)dims[a]);
    }
    float c[3];
    grid_voxel_center(&v.dims, ijk[0], ijk[1], ijk[2], c);
    double p[3] = {c[0], c[1], c[2]};
    double w = winding_number(&m, p);
    if (w > 0.25 && w < 0.75) continue;
    tested++;
    int inside = v.ior[grid_index(&v.dims, ijk[0], ijk[1], ijk[2])] > 1.25f;
    inside_samples += inside;
    if (inside != (w > 0.5)) disagree++;
  }
  printf("bunny: %d sampled voxel centres, %d inside, %d disagree with the winding number\n",
         tested, inside_samples, disagree);
  EXPECT(tested >= 280);
  EXPECT(inside_samples >= 20);
  EXPECT(disagree <= 2);
  vox_free(&v);
  mesh_io_free(&m);
}

/* Nested spheres: the inner one (listed later) overrides the outer one; the
 * inner mesh is a unit sphere placed by the object's transform. */
static void case_objects(void) {
  double c0[3] = {0, 0, 0};
  mesh_tris_t outer = icosphere(4, 0.7, SPHERE_C), unit = icosphere(3, 1.0, c0);
  char p_outer[4096], p_unit[4096];
  if (!write_mesh("outer.obj", &outer, p_outer, sizeof p_outer) ||
      !write_mesh("unit.obj", &unit, p_unit, sizeof p_unit))
    return;
  scene_t s;
  scene_object_t o[2];
  volume_t v;
  scene_init(&s, -1.0f, 1.0f, 64, 2.0f);
  s.medium_ior = 1.0f;
  for (int ch = 0; ch < 3; ch++) s.medium_sigma_s[ch] = 0.5f;
  object_init(&o[0], p_outer, 1.5f);
  for (int ch = 0; ch < 3; ch++) o[0].sigma_a[ch] = 0.1f * (float)(ch + 1);
  object_init(&o[1], p_unit, 1.2f);
  /* scale 0.3, a rotation (a sphere does not care), then moved to (0.2, 0.1, -0.1) */
  for (int a = 0; a < 3; a++) o[1].scale[a] = 0.3f;
  o[1].rotate_deg[1] = 30.0f;
  o[1].translate[0] = 0.2f;
  o[1].translate[1] = 0.1f;
  o[1].translate[2] = -0.1f;
  s.objects = o;
  s.object_count = 2;
  if (!build(&s, &v)) return;
  const grid_dims_t *d = &v.dims;
  size_t in_inner = 0, in_shell = 0, outside = 0, bad = 0;
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        float c[3];
        grid_voxel_center(d, i, j, k, c);
        double ri = sqrt(pow(c[0] - 0.2, 2) + pow(c[1] - 0.1, 2) + pow(c[2] + 0.1, 2)) / d->voxel_size;
        double ro = sqrt(pow(c[0] - SPHERE_C[0], 2) + pow(c[1] - SPHERE_C[1], 2) +
                         pow(c[2] - SPHERE_C[2], 2)) / d->voxel_size;
        size_t idx = grid_index(d, i, j, k);
        float st[3], ss[3];
        for (int ch = 0; ch < 3; ch++) st[ch] = vol_sigma_t(&v, idx, ch), ss[ch] = vol_sigma_s(&v, idx, ch);
        /* 1.5 voxels clear of each surface (s/2 plus the icospheres' sag) */
        if (ri < 0.3 / d->voxel_size - 1.5) {
          in_inner++;
          if (v.ior[idx] != 1.2f || st[0] != 0.0f || ss[0] != 0.0f) bad++;
        } else if (ri > 0.3 / d->voxel_size + 1.5 && ro < 0.7 / d->voxel_size - 1.5) {
          in_shell++;
          if (v.ior[idx] != 1.5f || st[2] != 0.3f || ss[1] != 0.0f) bad++;
        } else if (ro > 0.7 / d->voxel_size + 1.5) {
          outside++;
          if (v.ior[idx] != 1.0f || st[1] != 0.5f || ss[2] != 0.5f) bad++;
        }
      }
  printf("nested spheres: %zu inner, %zu shell, %zu outside voxels checked, %zu wrong\n", in_inner,
         in_shell, outside, bad);
  EXPECT(in_inner > 1000 && in_shell > 10000 && outside > 10000);
  EXPECT(bad == 0);
  EXPECT(!v.homogeneous && !v.grey && v.has_refraction);
  EXPECT_NEAR(v.n_min, 1.0, 0.0);
  EXPECT_NEAR(v.n_max, 1.5, 0.0);
  vox_free(&v);
  mesh_io_free(&outer);
  mesh_io_free(&unit);
}

/* Meshes with their vertices on voxel centres, so that rays run exactly
 * through vertices and edges (the octahedron, and the diagonals of the cube's
 * faces) or along faces (the cube): the inside votes must not be fooled.
 * Bounds of +-16.5/16 at resolution 33 give voxels of exactly 1/16 with a
 * voxel centre at the origin. With smoothing 1, voxels one lattice step or
 * more from the surface are exactly n_in or n_out, and voxels on it exactly
 * between. */
static void case_ties(void) {
  const int R = 10; /* voxels */
  const float h = (float)R / 16.0f;
  float octa[18] = {h, 0, 0, -h, 0, 0, 0, h, 0, 0, -h, 0, 0, 0, h, 0, 0, -h};
  int octa_f[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  float cube[24] = {-h, -h, -h, h, -h, -h, h, h, -h, -h, h, -h,
                    -h, -h, h,  h, -h, h,  h, h, h,  -h, h, h};
  int cube_f[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                    3, 6, 2, 3, 7, 6, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
  mesh_tris_t meshes[2] = {{octa, 6, octa_f, 8}, {cube, 8, cube_f, 12}};
  const char *names[2] = {"octahedron.obj", "cube.obj"};
  for (int mi = 0; mi < 2; mi++) {
    char path[4096];
    if (!write_mesh(names[mi], &meshes[mi], path, sizeof path)) continue;
    scene_t s;
    scene_object_t o;
    volume_t v;
    scene_init(&s, -16.5f / 16.0f, 16.5f / 16.0f, 33, 1.0f);
    s.crop_to_objects = 0; /* the ties are checked on the grid as given */
    object_init(&o, path, 1.5f);
    s.objects = &o;
    s.object_count = 1;
    if (!build(&s, &v)) continue;
    EXPECT(v.dims.nx == 33 && v.dims.voxel_size == 1.0f / 16.0f);
    size_t wrong = 0, inside = 0, expect_inside = 0, on_surface = 0;
    for (int k = 0; k < v.dims.nz; k++)
      for (int j = 0; j < v.dims.ny; j++)
        for (int i = 0; i < v.dims.nx; i++) {
          int x = abs(i - 16), y = abs(j - 16), z = abs(k - 16);
          int l = mi == 0 ? x + y + z : (x > y ? (x > z ? x : z) : (y > z ? y : z));
          float n = v.ior[grid_index(&v.dims, i, j, k)];
          if (l < R) {
            expect_inside++;
            wrong += n != 1.5f;
          } else if (l > R) {
            wrong += n != 1.0f;
          } else {
            on_surface++;
            wrong += fabsf(n - 1.25f) > 1e-4f;
          }
          inside += n > 1.25f + 1e-4f;
        }
    printf("%s: %zu voxels strictly inside (expected %zu), %zu on the surface, %zu wrong\n",
           names[mi], inside, expect_inside, on_surface, wrong);
    EXPECT(wrong == 0);
    EXPECT(inside == expect_inside);
    vox_free(&v);
  }
}

/* A cube without its bottom face fills exactly like the closed cube: rays
 * through the hole abstain, the two other axes decide. An object reaching
 * out of the grid is cut, not misclassified. */
static void case_open(void) {
  const float h = 0.61f; /* off the voxel lattice */
  float cube[24] = {-h, -h, -h, h, -h, -h, h, h, -h, -h, h, -h,
                    -h, -h, h,  h, -h, h,  h, h, h,  -h, h, h};
  /* -y first, so that dropping two triangles opens the bottom */
  int cube_f[36] = {0, 1, 5, 0, 5, 4, 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7,
                    3, 6, 2, 3, 7, 6, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
  mesh_tris_t closed = {cube, 8, cube_f, 12}, open = {cube, 8, cube_f + 6, 10};
  char p_closed[4096], p_open[4096];
  if (!write_mesh("closed_cube.obj", &closed, p_closed, sizeof p_closed) ||
      !write_mesh("open_cube.obj", &open, p_open, sizeof p_open))
    return;
  double vol[2] = {0, 0}, smooth;
  for (int c = 0; c < 2; c++) {
    scene_t s;
    scene_object_t o;
    volume_t v;
    scene_init(&s, -1.0f, 1.0f, 48, 2.0f);
    object_init(&o, c == 0 ? p_closed : p_open, 1.5f);
    s.objects = &o;
    s.object_count = 1;
    if (!build(&s, &v)) return;
    inside_volume(&v, 1.0f, 1.5f, &vol[c], &smooth);
    vox_free(&v);
  }
  /* voxel centres inside the cube: the same count on every axis */
  int per_axis = 0;
  for (int i = 0; i < 48; i++) per_axis += fabs(-1.0 + (i + 0.5) / 24.0) < h;
  double lattice = pow(per_axis, 3.0) * pow(2.0 / 48.0, 3.0);
  printf("cube: closed %.6f, without its bottom %.6f, voxel centres inside %.6f\n", vol[0], vol[1],
         lattice);
  EXPECT(vol[0] == vol[1]);
  EXPECT(fabs(vol[0] - lattice) < 1e-6 * lattice); /* voxel_size is a float */

  /* an icosphere centred on the grid's +x face: half of it is in the grid */
  double c[3] = {1.0, 0.0123, -0.0311};
  mesh_tris_t m = icosphere(4, 0.5, c);
  char path[4096];
  if (!write_mesh("clipped.obj", &m, path, sizeof path)) return;
  scene_t s;
  scene_object_t o;
  volume_t v;
  scene_init(&s, -1.0f, 1.0f, 64, 2.0f);
  object_init(&o, path, 1.5f);
  s.objects = &o;
  s.object_count = 1;
  if (build(&s, &v)) {
    double half = 0.5 * mesh_volume(&m, c), count_vol;
    inside_volume(&v, 1.0f, 1.5f, &count_vol, &smooth);
    printf("sphere cut by the grid's face: %.6f inside, half the polyhedron %.6f (%.3f%%)\n",
           count_vol, half, 100.0 * (count_vol - half) / half);
    EXPECT(fabs(count_vol - half) / half < 0.01);
    vox_free(&v);
  }
  /* one entirely outside is ignored with a warning */
  for (int a = 0; a < 3; a++) o.translate[a] = 5.0f;
  if (build(&s, &v)) {
    EXPECT(!v.has_refraction && v.n_max == 1.0f);
    vox_free(&v);
  }
  mesh_io_free(&m);
}

/* density_vdb's values are taken in chunks side by side (vox_medium.c):
 * negative densities become 0 wherever they are, and of two non-finite ones
 * far apart the earlier is reported (trilinear sampling at the voxel
 * centres spreads an infinity, as NaN, to the voxels below it on each axis,
 * so the one named lies at most one voxel below it on each axis). */
static void check_density_values(scene_t *s, const grid_dims_t *d, const float *rho,
                                 const char *path) {
  const size_t count = grid_count(d), plane = (size_t)d->nx * d->ny;
  float *bad = malloc(count * sizeof *bad);
  memcpy(bad, rho, count * sizeof *bad);
  for (size_t idx = 0; idx < count; idx += 97) bad[idx] = -1.0f; /* across every chunk */
  bk_error_t err;
  vdbio_grid_t g = {"density", VDBIO_FLOAT, bad, 0, 0.0f, NULL, NULL, 0};
  vdbio_write_opts_t opts = {VDBIO_COMPRESS_NONE, 0, NULL, NULL};
  EXPECT(vdbio_write(path, d, &g, 1, NULL, 0, &opts, &err) == BK_OK);
  volume_t v;
  if (build(s, &v)) {
    size_t wrong = 0;
    for (size_t idx = 0; idx < count; idx += 97)
      wrong += vol_sigma_s(&v, idx, 0) != 0.0f || vol_sigma_t(&v, idx, 2) != 0.0f;
    EXPECT(wrong == 0, "%zu voxels of negative density kept a non-zero sigma", wrong);
    vox_free(&v);
  }
  const size_t early = grid_index(d, 5, 6, 3), late = grid_index(d, 20, 18, 21);
  bad[early] = INFINITY; /* vdbio_write keeps no NaN: it reads back as inactive */
  bad[late] = -INFINITY;
  EXPECT(vdbio_write(path, d, &g, 1, NULL, 0, &opts, &err) == BK_OK);
  int rc = vox_build(s, &v, NULL, &err);
  const char *at = strstr(err.msg, "at voxel ");
  size_t named = at ? strtoull(at + 9, NULL, 10) : 0;
  printf("non-finite density: %s\n", err.msg);
  EXPECT(rc == BK_ERR_INPUT && at && strstr(err.msg, "medium.density_vdb") &&
             named <= early && named + 1 + d->nx + plane >= early,
         "non-finite density: rc %d, voxel %zu named, infinity written at %zu: %s", rc, named, early,
         err.msg);
  free(bad);
}

static void case_medium(void) {
  scene_t s;
  volume_t v;
  /* constants only: nothing varies */
  scene_init(&s, -1.0f, 1.0f, 16, 2.0f);
  s.medium_ior = 1.33f;
  for (int ch = 0; ch < 3; ch++) {
    s.medium_sigma_s[ch] = 0.5f;
    s.medium_sigma_a[ch] = 0.02f;
  }
  if (build(&s, &v)) {
    EXPECT(!v.has_refraction && v.homogeneous && v.grey);
    EXPECT_NEAR(v.n_min, 1.33f, 0.0);
    EXPECT_NEAR(v.n_max, 1.33f, 0.0);
    /* grey: σ stored once per voxel, the same value for every channel */
    EXPECT(v.sigma_channels == 1);
    size_t last = grid_count(&v.dims) - 1;
    for (int ch = 0; ch < 3; ch++) {
      EXPECT_NEAR(vol_sigma_s(&v, last, ch), 0.5f, 0.0);
      EXPECT_NEAR(vol_sigma_t(&v, last, ch), 0.52f, 1e-6);
    }
    vox_free(&v);
  }
  s.medium_sigma_a[1] = 0.03f;
  if (build(&s, &v)) {
    EXPECT(v.homogeneous && !v.grey && v.sigma_channels == 3);
    EXPECT_NEAR(vol_sigma_t(&v, grid_count(&v.dims) - 1, 1), s.medium_sigma_s[1] + 0.03f, 0.0);
    vox_free(&v);
  }

  /* ior_vdb and density_vdb written on the same grid: sampling at our voxel
   * centres must give the written values back; where the ior grid is zero
   * (inactive, zero background) n is raised to 1 */
  grid_dims_t d;
  bk_error_t err;
  scene_init(&s, -1.0f, 1.0f, 24, 2.0f);
  EXPECT(grid_dims_from_bounds(s.bounds_min, s.bounds_max, 24, "t", &d, &err) == BK_OK);
  size_t count = grid_count(&d);
  float *ior = calloc(count, sizeof *ior), *rho = calloc(count, sizeof *rho);
  for (int k = 0; k < d.nz; k++)
    for (int j = 0; j < d.ny; j++)
      for (int i = 0; i < d.nx; i++) {
        size_t idx = grid_index(&d, i, j, k);
        ior[idx] = k < 4 ? 0.0f : 1.0f + 0.01f * (float)k;
        rho[idx] = 0.1f * (float)i;
      }
  vdbio_grid_t g_ior = {"ior", VDBIO_FLOAT, ior, 0, 0.0f, NULL, NULL, 0}, g_rho = {"density", VDBIO_FLOAT, rho, 0, 0.0f, NULL, NULL, 0};
  char p_ior[4096], p_rho[4096];
  tu_path(p_ior, sizeof p_ior, "field_ior.vdb");
  tu_path(p_rho, sizeof p_rho, "field_density.vdb");
  vdbio_write_opts_t opts = {VDBIO_COMPRESS_NONE, 0, NULL, NULL};
  EXPECT(vdbio_write(p_ior, &d, &g_ior, 1, NULL, 0, &opts, &err) == BK_OK);
  EXPECT(vdbio_write(p_rho, &d, &g_rho, 1, NULL, 0, &opts, &err) == BK_OK);
  s.ior_vdb.present = 1;
  snprintf(s.ior_vdb.file, sizeof s.ior_vdb.file, "%s", p_ior);
  snprintf(s.ior_vdb.grid, sizeof s.ior_vdb.grid, "ior");
  snprintf(s.ior_vdb.where, sizeof s.ior_vdb.where, "test.json:5:3: medium.ior_vdb");
  s.density_vdb.present = 1;
  snprintf(s.density_vdb.file, sizeof s.density_vdb.file, "%s", p_rho);
  snprintf(s.density_vdb.grid, sizeof s.density_vdb.grid, "density");
  snprintf(s.density_vdb.where, sizeof s.density_vdb.where, "test.json:6:3: medium.density_vdb");
  for (int ch = 0; ch < 3; ch++) {
    s.medium_sigma_s[ch] = 0.5f * (float)(ch + 1);
    s.medium_sigma_a[ch] = 0.1f;
  }
  if (build(&s, &v)) {
    double worst_n = 0.0, worst_s = 0.0;
    for (size_t idx = 0; idx < count; idx++) {
      double n_expect = ior[idx] < 1.0f ? 1.0 : ior[idx];
      worst_n = fmax(worst_n, fabs(v.ior[idx] - n_expect));
      for (int ch = 0; ch < 3; ch++) {
        worst_s = fmax(worst_s, fabs(vol_sigma_s(&v, idx, ch) - s.medium_sigma_s[ch] * rho[idx]));
        worst_s = fmax(worst_s, fabs(vol_sigma_t(&v, idx, ch) -
                                     (s.medium_sigma_s[ch] + 0.1) * rho[idx]));
      }
    }
    printf("medium from VDB: worst |n - written| %.2e, worst |sigma - sigma*density| %.2e\n",
           worst_n, worst_s);
    EXPECT(worst_n < 1e-5);
    EXPECT(worst_s < 1e-5);
    EXPECT(v.has_refraction && !v.homogeneous && !v.grey);
    EXPECT_NEAR(v.n_min, 1.0, 0.0);
    EXPECT_NEAR(v.n_max, 1.0 + 0.01 * (d.nz - 1), 1e-6);
    vox_free(&v);
  }
  /* a grid that is not there names the key */
  snprintf(s.density_vdb.grid, sizeof s.density_vdb.grid, "smoke");
  int rc = vox_build(&s, &v, NULL, &err);
  printf("missing density grid: %s\n", err.msg);
  EXPECT(rc == BK_ERR_INPUT && strstr(err.msg, "medium.density_vdb") && strstr(err.msg, "smoke"));
  snprintf(s.density_vdb.grid, sizeof s.density_vdb.grid, "density");
  check_density_values(&s, &d, rho, p_rho);
  free(ior);
  free(rho);
}

/* vox_scan's grey path (sigma_channels 1) against its RGB path on the same
 * values: every flag, extreme and double sum must be identical, with and
 * without a g grid, where σs is 0 in places and varies elsewhere. */
static void scan_pair(int with_g, int uniform) {
  volume_t grey, rgb;
  memset(&grey, 0, sizeof grey);
  grey.dims.nx = 13, grey.dims.ny = 11, grey.dims.nz = 17;
  grey.dims.voxel_size = 0.1f;
  const size_t n = grid_count(&grey.dims);
  grey.ior = calloc(n, sizeof(float));
  grey.sigma_s = calloc(n, sizeof(float));
  grey.sigma_t = calloc(n, sizeof(float));
  grey.g = with_g ? calloc(n, sizeof(float)) : NULL;
  grey.sigma_channels = 1;
  for (size_t i = 0; i < n; i++) {
    grey.ior[i] = uniform ? 1.0f : 1.0f + 0.001f * (float)(i % 97);
    grey.sigma_s[i] = uniform || i % 7 == 0 ? 0.0f : 0.3f + 1e-3f * (float)(i % 31);
    grey.sigma_t[i] = grey.sigma_s[i] + (uniform ? 0.02f : 0.01f * (float)(i % 5));
    if (with_g) grey.g[i] = i % 11 ? 0.3f : 0.0f;
  }
  rgb = grey;
  rgb.sigma_channels = 3;
  rgb.sigma_s = malloc(3 * n * sizeof(float));
  rgb.sigma_t = malloc(3 * n * sizeof(float));
  for (size_t i = 0; i < 3 * n; i++) {
    rgb.sigma_s[i] = grey.sigma_s[i / 3];
    rgb.sigma_t[i] = grey.sigma_t[i / 3];
  }
  vox_scan_t a, b;
  vox_scan(&grey, &a);
  vox_scan(&rgb, &b);
  EXPECT(a.n_min == b.n_min && a.n_max == b.n_max, "n range %g..%g vs %g..%g", a.n_min, a.n_max,
         b.n_min, b.n_max);
  EXPECT(a.varies == b.varies && a.t_varies == b.t_varies && a.s_varies == b.s_varies);
  EXPECT(!a.coloured && !b.coloured && !a.t_coloured && !b.t_coloured && !a.s_coloured &&
         !b.s_coloured);
  EXPECT(a.g_varies == b.g_varies && a.g_set == b.g_set);
  EXPECT(a.varies == !uniform && a.g_varies == with_g);
  EXPECT(memcmp(&a.ss, &b.ss, sizeof a.ss) == 0 && memcmp(&a.st, &b.st, sizeof a.st) == 0 &&
             memcmp(&a.st_scattering, &b.st_scattering, sizeof a.st_scattering) == 0,
         "sums %a %a %a vs %a %a %a", a.ss, a.st, a.st_scattering, b.ss, b.st, b.st_scattering);
  EXPECT(a.scattering == b.scattering, "%zu vs %zu scattering voxels", a.scattering, b.scattering);
  printf("scan (g grid %d, uniform %d): ss %.9g st %.9g, %zu scattering voxels\n", with_g, uniform,
         a.ss, a.st, a.scattering);
  free(rgb.sigma_s), free(rgb.sigma_t);
  vox_free(&grey);
}

/* vox_summarise makes sigma_t, which held σa while the objects were
 * composited, the float sum σs + σa in every voxel and channel, and scans
 * it as vox_scan scans a volume that holds σt already (grey and RGB); the
 * code an RGB volume then keeps gives every value back (here nearly all
 * are table entries: the medium's coefficients are 0), as does the code a
 * grey volume keeps when the budget asks for it (code_grey: made in σs's
 * place, vox_code.c). */
static void summarise_pair(int channels, int code_grey) {
  volume_t v, t;
  memset(&v, 0, sizeof v);
  v.dims.nx = 9, v.dims.ny = 14, v.dims.nz = 11;
  v.dims.voxel_size = 0.1f;
  const size_t n = grid_count(&v.dims), m = n * (size_t)channels;
  v.sigma_channels = channels;
  v.ior = calloc(n, sizeof(float));
  v.sigma_s = malloc(m * sizeof(float));
  v.sigma_t = malloc(m * sizeof(float));
  for (size_t i = 0; i < n; i++) v.ior[i] = 1.0f + 0.01f * (float)(i % 13);
  for (size_t i = 0; i < m; i++) {
    v.sigma_s[i] = i % 5 ? 0.3f + 1e-3f * (float)(i % 29) : 0.0f;
    v.sigma_t[i] = 0.017f * (float)(i % 7); /* σa */
  }
  t = v;
  t.sigma_s = malloc(m * sizeof(float));
  t.sigma_t = malloc(m * sizeof(float));
  for (size_t i = 0; i < m; i++) {
    t.sigma_s[i] = v.sigma_s[i];
    t.sigma_t[i] = v.sigma_s[i] + v.sigma_t[i];
  }
  vox_scan_t b;
  vox_scan(&t, &b);
  v.code_grey = code_grey;
  vox_summarise(&v);
  const vox_scan_t *a = &v.scan;
  /* read back through the code (vox_code.h), bit for bit */
  size_t differ = 0;
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < channels; c++) {
      const float st = vol_sigma_t(&v, i, c), ss = vol_sigma_s(&v, i, c);
      differ += memcmp(&st, &t.sigma_t[(size_t)channels * i + c], sizeof st) != 0 ||
                memcmp(&ss, &t.sigma_s[(size_t)channels * i + c], sizeof ss) != 0;
    }
  /* RGB is coded, grey stays plain unless asked (vox_summarise) */
  const int coded = channels == 3 || code_grey;
  EXPECT(v.sigma_channels == channels && (v.sigma_code != NULL) == coded && differ == 0,
         "%d channels, code_grey %d: coded %d, %zu values are not sigma_s and sigma_s + sigma_a",
         channels, code_grey, v.sigma_code != NULL, differ);
  EXPECT(!coded || (!v.sigma_s && !v.sigma_t), "coded, yet the plain arrays are kept");
  EXPECT(a->varies == b.varies && a->coloured == b.coloured && a->t_varies == b.t_varies &&
         a->t_coloured == b.t_coloured && a->s_varies == b.s_varies &&
         a->s_coloured == b.s_coloured && a->n_min == b.n_min && a->n_max == b.n_max);
  EXPECT(a->ss == b.ss && a->st == b.st && a->st_scattering == b.st_scattering &&
             a->scattering == b.scattering,
         "%d channels: sums %a %a vs %a %a", channels, a->ss, a->st, b.ss, b.st);
  EXPECT(a->t_varies && a->coloured == (channels == 3));
  free(t.sigma_s), free(t.sigma_t);
  vox_free(&v);
}

/* n packed into bricks (brick_grid.h) comes back bit for bit over any
 * range, on a grid that is not a multiple of 8 on any axis, with -0.0
 * against 0.0 in a brick that is otherwise constant. */
static void case_bricks(void) {
  grid_dims_t d = {0};
  d.nx = 21, d.ny = 13, d.nz = 10;
  d.voxel_size = 0.1f;
  const size_t n = grid_count(&d);
  float *dense = malloc(n * sizeof(float)), *back = malloc(n * sizeof(float));
  REQUIRE(dense && back, "out of memory");
  for (size_t i = 0; i < n; i++) {
    const int x = (int)(i % 21), y = (int)(i / 21 % 13), z = (int)(i / (21 * 13));
    dense[i] = x > 15 && y > 8 ? 1.0f + 0.01f * (float)(i % 7) : 1.0f; /* a corner column varies */
    if (x < 8 && y < 8 && z >= 8) dense[i] = 0.0f; /* a brick of zeros ... */
  }
  dense[grid_index(&d, 3, 2, 9)] = -0.0f; /* ... but one: it differs by its bits */
  brick_grid_t g;
  bk_error_t err;
  REQUIRE(bg_build(&d, dense, &g, &err) == BK_OK, "bg_build: %s", err.msg);
  const size_t cuts[][2] = {{0, n}, {5, 6}, {7, 300}, {n - 17, n}, {400, 1700}};
  for (size_t c = 0; c < sizeof cuts / sizeof cuts[0]; c++) {
    memset(back, 0x7f, n * sizeof(float));
    bg_fill(&g, cuts[c][0], cuts[c][1], back + cuts[c][0]);
    const size_t lo = cuts[c][0], hi = cuts[c][1];
    EXPECT(memcmp(back + lo, dense + lo, (hi - lo) * sizeof(float)) == 0, "voxels %zu..%zu differ",
           lo, hi);
  }
  const size_t bricks = (size_t)g.bx * g.by * g.bz;
  size_t stored = 0;
  for (size_t b = 0; b < bricks; b++) stored += g.slot[b] >= 0;
  printf("bricks: %zu of %zu stored, %zu bytes for %zu voxels\n", stored, bricks, bg_bytes(&g), n);
  EXPECT(stored == 3, "%zu bricks stored, expected the corner column's 2 and the -0.0 one", stored);
  bg_free(&g);
  free(dense), free(back);
}

static void case_scan(void) {
  scan_pair(0, 0);
  scan_pair(1, 0);
  scan_pair(0, 1);
  summarise_pair(1, 0);
  summarise_pair(1, 1);
  summarise_pair(3, 0);
}

/* A homogeneous volume keeps one voxel's σs and σt (vox_summarise): every
 * voxel reads them through vox_sigma_index, and the write's extinction,
 * scattering and density fills give what the full arrays gave; one voxel
 * that differs makes the volume coded (vox_code.h), which gives them back
 * bit for bit. */
static void uniform_case(int channels, int odd_voxel, int code_grey) {
  volume_t v;
  memset(&v, 0, sizeof v);
  v.dims.nx = 7, v.dims.ny = 5, v.dims.nz = 6;
  v.dims.voxel_size = 0.1f;
  const size_t n = grid_count(&v.dims), m = n * (size_t)channels;
  const float s0[3] = {0.5f, 0.3f, 0.1f}, a0[3] = {0.02f, 0.22f, 0.42f};
  v.sigma_channels = channels;
  v.ior = calloc(n, sizeof(float));
  v.sigma_s = malloc(m * sizeof(float));
  v.sigma_t = malloc(m * sizeof(float)); /* σa until vox_summarise */
  for (size_t i = 0; i < n; i++) {
    v.ior[i] = 1.0f;
    for (int c = 0; c < channels; c++) {
      v.sigma_s[(size_t)channels * i + c] = s0[c];
      v.sigma_t[(size_t)channels * i + c] = a0[c];
    }
  }
  for (int c = 0; c < 3; c++) v.medium_s[c] = s0[c], v.medium_a[c] = a0[c];
  if (odd_voxel) v.sigma_s[m - 1] = 0.25f;
  v.code_grey = code_grey;
  vox_summarise(&v);
  EXPECT(v.homogeneous == !odd_voxel, "%d channels, odd voxel %d: homogeneous %d", channels,
         odd_voxel, v.homogeneous);
  /* the others are the medium at density 1: the odd voxel is the one entry
   * after the medium's coefficients (kernels/medium_code.h) */
  EXPECT(!odd_voxel || (channels == 1 && !code_grey) ||
             (v.sigma_code && v.sigma_code_floats == n + 2 * 2 * (size_t)channels),
         "%d channels, odd voxel: coded %d, %zu floats", channels, v.sigma_code != NULL,
         v.sigma_code_floats);
  const og_source_t src = {.vol = &v};
  float *ext = malloc(m * sizeof(float)), *sca = malloc(m * sizeof(float));
  float *rho = malloc(n * sizeof(float));
  og_extinction(&src, 0, n, ext);
  og_scattering(&src, 0, n, sca);
  og_density(&src, 0, n, rho);
  int bad = 0;
  for (size_t i = 0; i < n; i++) {
    float sum = 0.0f;
    for (int c = 0; c < 3; c++) {
      const int k = channels == 1 ? 0 : c;
      const float ss = odd_voxel && i == n - 1 && k == channels - 1 ? 0.25f : s0[k];
      const float st = ss + a0[k];
      sum += st;
      bad += vol_sigma_t(&v, i, c) != st || vol_sigma_s(&v, i, c) != ss;
      if (c < channels) bad += ext[(size_t)channels * i + c] != st || sca[(size_t)channels * i + c] != ss;
    }
    bad += rho[i] != sum / 3.0f;
  }
  EXPECT(bad == 0, "%d channels, odd voxel %d: %d values differ", channels, odd_voxel, bad);
  free(ext), free(sca), free(rho);
  vox_free(&v);
}

static void case_uniform(void) {
  uniform_case(1, 0, 0);
  uniform_case(1, 1, 0);
  uniform_case(1, 1, 1);
  uniform_case(3, 0, 0);
  uniform_case(3, 1, 0);
}

/* mesh_io_read and vox_build must both refuse with BK_ERR_INPUT, naming the
 * file and the problem (and, through vox_build, the scene key). */
static void expect_refusal(const char *path, const char *problem) {
  mesh_tris_t m;
  bk_error_t err;
  int rc = mesh_io_read(path, &m, &err);
  printf("%-22s -> %s\n", strrchr(path, '/') + 1, rc == BK_OK ? "(accepted)" : err.msg);
  EXPECT(rc == BK_ERR_INPUT);
  if (rc == BK_OK) {
    mesh_io_free(&m);
    return;
  }
  EXPECT(strstr(err.msg, path) != NULL);
  if (!strstr(err.msg, problem)) {
    fprintf(stderr, "  expected \"%s\" in the message\n", problem);
    tu_failures++;
  }
  scene_t s;
  scene_object_t o;
  volume_t v;
  scene_init(&s, -1.0f, 1.0f, 8, 2.0f);
  object_init(&o, path, 1.5f);
  s.objects = &o;
  s.object_count = 1;
  rc = vox_build(&s, &v, NULL, &err);
  EXPECT(rc == BK_ERR_INPUT);
  EXPECT(strstr(err.msg, "test.json:9:12: objects[0].mesh") != NULL);
  EXPECT(strstr(err.msg, path) != NULL && strstr(err.msg, problem) != NULL);
  EXPECT(v.ior == NULL);
}

static void case_bad_input(void) {
  char p[4096];
  const char *tail = "v 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n";
  char text[1024];
  snprintf(text, sizeof text, "v 0 0 0\nv 1 0 0\nv nan 1 0\n%s", tail);
  tu_write_text("nan.obj", text, p, sizeof p);
  expect_refusal(p, "vertex 3 has a non-finite coordinate (nan, 1, 0)");
  snprintf(text, sizeof text, "v 0 0 0\nv 1 0 0\nv 0 -inf 0\n%s", tail);
  tu_write_text("inf.obj", text, p, sizeof p);
  expect_refusal(p, "vertex 3 has a non-finite coordinate (0, -inf, 0)");
  snprintf(text, sizeof text, "v 0 0 0\nv 1e39 0 0\nv 0 1 0\n%s", tail);
  tu_write_text("overflow.obj", text, p, sizeof p);
  expect_refusal(p, "overflows a 32-bit float");
  snprintf(text, sizeof text, "v 0 0 0\nv 1 x 0\nv 0 1 0\n%s", tail);
  tu_write_text("garbled.obj", text, p, sizeof p);
  expect_refusal(p, "vertex 2: expected three numbers");
  tu_write_text("empty.obj", "", p, sizeof p);
  expect_refusal(p, "contains no triangles");
  tu_write_text("no_faces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", p, sizeof p);
  expect_refusal(p, "contains no triangles");
  tu_path(p, sizeof p, "missing.obj");
  remove(p);
  expect_refusal(p, "cannot open");
  tu_write_text("mesh.xyz", "0 0 0\n", p, sizeof p);
  expect_refusal(p, "unknown mesh format '.xyz'");
  tu_write_text("nan.off", "OFF\n4 4 0\n0 0 0\n1 0 0\nNaN 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n",
             p, sizeof p);
  expect_refusal(p, "vertex 2 has a non-finite coordinate (nan, 1, 0)");
  tu_write_text("nan.ply",
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
             "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n0 1 0\n0 inf 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n",
             p, sizeof p);
  expect_refusal(p, "vertex 3 has a non-finite coordinate (0, inf, 1)");
  tu_write_text("nan.stl",
             "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 nan 0\n"
             "endloop\nendfacet\nendsolid t\n",
             p, sizeof p);
  expect_refusal(p, "facet 0 vertex 2 has a non-finite coordinate (0, nan, 0)");
  /* binary STL: NaN passes through OpenMesh and is caught on its vertices */
  {
    tu_path(p, sizeof p, "nan_binary.stl");
    FILE *f = fopen(p, "wb");
    char header[80] = "binary stl with a nan";
    unsigned n = 1;
    float tri[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, NAN, 1, 0};
    unsigned short attr = 0;
    fwrite(header, 1, 80, f);
    fwrite(&n, 4, 1, f);
    fwrite(tri, 4, 12, f);
    fwrite(&attr, 2, 1, f);
    fclose(f);
    expect_refusal(p, "facet 0 vertex 2 has a non-finite coordinate (nan, 1, 0)");
  }
  tu_write_text("comment.off", "OFF\n4 4 0\n# vertices\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n",
             p, sizeof p);
  expect_refusal(p, ":3: '#' comments are not supported by OpenMesh's OFF reader");
  /* binary PLY: the NaN reaches OpenMesh's vertices and is caught there */
  {
    tu_path(p, sizeof p, "nan_binary.ply");
    FILE *f = fopen(p, "wb");
    fputs("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
          "property float y\nproperty float z\nelement face 4\n"
          "property list uchar int vertex_indices\nend_header\n", f);
    float v[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, NAN};
    fwrite(v, 4, 12, f);
    int faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    for (int t = 0; t < 4; t++) {
      unsigned char three = 3;
      fwrite(&three, 1, 1, f);
      fwrite(faces[t], 4, 3, f);
    }
    fclose(f);
    expect_refusal(p, "vertex 3 has a non-finite coordinate (0, 0, nan)");
  }
  /* a grid too large for this machine is refused before anything is allocated */
  scene_t s;
  volume_t v;
  bk_error_t err;
  scene_init(&s, -1.0f, 1.0f, 16000, 2.0f);
  int rc = vox_build(&s, &v, NULL, &err);
  printf("huge grid -> %s\n", err.msg);
  EXPECT(rc == BK_ERR_INPUT && strstr(err.msg, "grid.resolution") && v.ior == NULL);
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: test_voxelize CASE DIR [MESH]\n");
    return 2;
  }
  tu_dir = argv[2];
  mkdir(tu_dir, 0777); /* the parent is the build directory */
  bk_verbosity = 1;
  const char *c = argv[1];
  if (!strcmp(c, "sphere")) case_sphere();
  else if (!strcmp(c, "profile")) case_profile();
  else if (!strcmp(c, "smoothing")) case_smoothing();
  else if (!strcmp(c, "bunny") && argc > 3) case_bunny(argv[3]);
  else if (!strcmp(c, "objects")) case_objects();
  else if (!strcmp(c, "medium")) case_medium();
  else if (!strcmp(c, "scan")) case_scan();
  else if (!strcmp(c, "uniform")) case_uniform();
  else if (!strcmp(c, "bricks")) case_bricks();
  else if (!strcmp(c, "ties")) case_ties();
  else if (!strcmp(c, "open")) case_open();
  else if (!strcmp(c, "bad_input")) case_bad_input();
  else {
    fprintf(stderr, "unknown case %s\n", c);
    return 2;
  }
  if (tu_failures) fprintf(stderr, "%d check(s) failed\n", tu_failures);
  return tu_failures ? 1 : 0;
}
