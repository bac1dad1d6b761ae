/* voxelize.c: meshes and the medium -> n, sigma_s, sigma_t on the grid.
 *
 * Per object, in voxel index space (voxel (i,j,k) centred at integer (i,j,k)):
 * 1. unsigned distance: every triangle visits the voxels of its bounding box
 *    grown by the band (ior_smoothing/2 + VOX_BAND_MARGIN voxels) and keeps
 *    the smallest exact point-triangle distance; a plane-distance test skips
 *    most voxels before the closest-point computation;
 * 2. inside: rays along x, y and z through the voxel centres; triangles are
 *    binned per ray by their 2D bounding boxes, hits found with exact-sign
 *    edge functions and the top-left fill rule (a ray through a shared edge
 *    or vertex counts exactly once), depths sorted, parity taken;
 * 3. blend: w(d) from the signed distance, composited over what is there.
 * One thread: the passes are memory-light and the armadillo at 256^3 takes
 * seconds. */
#include "voxelize.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "mesh.h"
#include "mesh_io.h"
#include "vox_crop.h"
#include "vox_medium.h"

/* Scratch per voxel of an object's region: squared distance + inside vote. */
#define VOX_SCRATCH_BYTES (sizeof(float) + sizeof(signed char))
/* Show progress from this many voxels (or triangles) on. */
#define VOX_PROGRESS_MIN_VOXELS (1u << 21)

/* The smoothing profile (see voxelize.h): 1 inside, 0 outside, 0.5 on the
 * surface, smoothstep in between. d and s in voxels. */
static float vox_weight(float d, float s) {
  float t = (d + 0.5f * s) / s;
  if (t <= 0.0f) return 1.0f;
  if (t >= 1.0f) return 0.0f;
  return 1.0f - t * t * (3.0f - 2.0f * t);
}

/* A box of voxels, inclusive bounds, with its own x-fastest scratch layout. */
typedef struct vox_region {
  int lo[3], hi[3], n[3];
  size_t count;
} vox_region_t;

static size_t region_index(const vox_region_t *r, int i, int j, int k) {
  return (size_t)(i - r->lo[0]) +
         (size_t)r->n[0] * ((size_t)(j - r->lo[1]) + (size_t)r->n[1] * (size_t)(k - r->lo[2]));
}

/* First and last integer voxel coordinate in [lo, hi] at or above v / at or
 * below v (lo > hi when none); safe for huge or infinite v. */
static int cell_from(float v, int lo, int hi) {
  if (!(v > (float)lo)) return lo;
  if (v > (float)hi) return hi + 1;
  return (int)ceilf(v);
}
static int cell_to(float v, int lo, int hi) {
  if (!(v < (float)hi)) return hi;
  if (v < (float)lo) return lo - 1;
  return (int)floorf(v);
}

/* --- distance ---------------------------------------------------------------- */
static float dot3(const float a[3], const float b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static float seg_dist2(const float p[3], const float a[3], const float b[3]) {
  float ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  float ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  float len2 = dot3(ab, ab), t = len2 > 0.0f ? dot3(ap, ab) / len2 : 0.0f;
  t = t < 0.0f ? 0.0f : (t > 1.0f ? 1.0f : t);
  float q[3] = {ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]};
  return dot3(q, q);
}

/* Squared distance from p to triangle abc (Ericson, Real-Time Collision
 * Detection 5.1.5); `plane2` is the squared plane distance, exact in the
 * face region. */
static float tri_dist2(const float p[3], const float a[3], const float b[3], const float c[3],
                       float plane2) {
  float ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  float ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  float ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  float d1 = dot3(ab, ap), d2 = dot3(ac, ap);
  if (d1 <= 0.0f && d2 <= 0.0f) return dot3(ap, ap);
  float bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
  float d3 = dot3(ab, bp), d4 = dot3(ac, bp);
  if (d3 >= 0.0f && d4 <= d3) return dot3(bp, bp);
  float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f) return seg_dist2(p, a, b);
  float cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
  float d5 = dot3(ab, cp), d6 = dot3(ac, cp);
  if (d6 >= 0.0f && d5 <= d6) return dot3(cp, cp);
  float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f) return seg_dist2(p, a, c);
  float va = d3 * d6 - d5 * d4;
  if (va <= 0.0f && (d4 - d3) >= 0.0f && (d5 - d6) >= 0.0f) return seg_dist2(p, b, c);
  return plane2;
}

/* Smallest squared distance to the object's triangles within the band, for
 * every voxel of the region (band^2 where no triangle is that close). */
static void vox_distance(const mesh_tris_t *m, const vox_region_t *r, float band, float *dist2,
                         bk_progress_t *prog, uint64_t prog_base) {
  const float band2 = band * band;
  for (size_t v = 0; v < r->count; v++) dist2[v] = band2;
  for (int t = 0; t < m->triangle_count; t++) {
    const float *a = m->positions + 3 * (size_t)m->indices[3 * t];
    const float *b = m->positions + 3 * (size_t)m->indices[3 * t + 1];
    const float *c = m->positions + 3 * (size_t)m->indices[3 * t + 2];
    int lo[3], hi[3], empty = 0;
    for (int ax = 0; ax < 3; ax++) {
      float mn = fminf(a[ax], fminf(b[ax], c[ax])) - band;
      float mx = fmaxf(a[ax], fmaxf(b[ax], c[ax])) + band;
      lo[ax] = cell_from(mn, r->lo[ax], r->hi[ax]);
      hi[ax] = cell_to(mx, r->lo[ax], r->hi[ax]);
      if (lo[ax] > hi[ax]) empty = 1;
    }
    if (empty) continue;
    float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                  e1[0] * e2[1] - e1[1] * e2[0]};
    float nlen = sqrtf(dot3(n, n));
    int flat = !(nlen > 0.0f) || !isfinite(nlen);
    if (!flat)
      for (int ax = 0; ax < 3; ax++) n[ax] /= nlen;
    for (int k = lo[2]; k <= hi[2]; k++)
      for (int j = lo[1]; j <= hi[1]; j++) {
        float *row = dist2 + region_index(r, lo[0], j, k);
        float p[3] = {0.0f, (float)j, (float)k};
        float base = n[1] * ((float)j - a[1]) + n[2] * ((float)k - a[2]) - n[0] * a[0];
        for (int i = lo[0]; i <= hi[0]; i++) {
          float *cur = row + (i - lo[0]);
          p[0] = (float)i;
          float d2;
          if (flat) {
            /* zero-area triangle: its edges are all there is */
            d2 = fminf(seg_dist2(p, a, b), fminf(seg_dist2(p, b, c), seg_dist2(p, a, c)));
          } else {
            float plane = base + n[0] * (float)i;
            float plane2 = plane * plane;
            if (plane2 >= *cur) continue; /* cannot beat what is there */
            d2 = tri_dist2(p, a, b, c, plane2);
          }
          if (d2 < *cur) *cur = d2;
        }
      }
    if ((t & 1023) == 0) bk_progress_update(prog, prog_base + (uint64_t)t);
  }
}

/* --- inside test --------------------------------------------------------------- */
/* Edge function of edge a->b at p: twice the signed area of (a, b, p),
 * evaluated with the endpoints in a canonical order so that the two triangles
 * sharing an edge get exactly opposite values (watertight ray tests). Not
 * inlined, so the compiler cannot contract it differently at different call
 * sites. */
__attribute__((noinline)) static double edge_fn(double ax, double ay, double bx, double by,
                                                double px, double py) {
  if (ax < bx || (ax == bx && ay < by)) return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
  return -((ax - bx) * (py - by) - (ay - by) * (px - bx));
}

/* The top-left rule for a counter-clockwise triangle (y up): a point exactly
 * on an edge belongs to the triangle when the edge is a left edge (going down)
 * or a top edge (horizontal, going left). Of two triangles on opposite sides
 * of an edge exactly one owns it. */
static int owns_edge(double ax, double ay, double bx, double by, double e) {
  if (e != 0.0) return e > 0.0;
  return (by < ay) || (by == ay && bx < ax);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

static void sort_hits(double *h, int n) {
  if (n > 24) {
    qsort(h, (size_t)n, sizeof *h, cmp_double);
    return;
  }
  for (int i = 1; i < n; i++) {
    double x = h[i];
    int j = i - 1;
    while (j >= 0 && h[j] > x) {
      h[j + 1] = h[j];
      j--;
    }
    h[j + 1] = x;
  }
}

/* Bins the triangles into the ray columns under their 2D bounding boxes:
 * bins[start[col] .. start[col + 1]) are the triangles column col may hit.
 * Two passes, counting and then filling, so that one allocation holds every
 * bin; `start` has columns + 1 zeroed entries. */
static int vox_bin_columns(const mesh_tris_t *m, const vox_region_t *r, int bx, int cx,
                           size_t *start, int **bins_out, bk_error_t *err) {
  const int nb = r->n[bx], nc = r->n[cx];
  const size_t columns = (size_t)nb * (size_t)nc;
  int *bins = NULL;
  for (int pass = 0; pass < 2; pass++) {
    for (int t = 0; t < m->triangle_count; t++) {
      const int *f = m->indices + 3 * (size_t)t;
      float mnb = INFINITY, mxb = -INFINITY, mnc = INFINITY, mxc = -INFINITY;
      for (int q = 0; q < 3; q++) {
        const float *p = m->positions + 3 * (size_t)f[q];
        mnb = fminf(mnb, p[bx]);
        mxb = fmaxf(mxb, p[bx]);
        mnc = fminf(mnc, p[cx]);
        mxc = fmaxf(mxc, p[cx]);
      }
      int b0 = cell_from(mnb, r->lo[bx], r->hi[bx]), b1 = cell_to(mxb, r->lo[bx], r->hi[bx]);
      int c0 = cell_from(mnc, r->lo[cx], r->hi[cx]), c1 = cell_to(mxc, r->lo[cx], r->hi[cx]);
      for (int cc = c0; cc <= c1; cc++)
        for (int bb = b0; bb <= b1; bb++) {
          size_t col = (size_t)(bb - r->lo[bx]) + (size_t)nb * (size_t)(cc - r->lo[cx]);
          if (pass == 0)
            start[col + 1]++;
          else
            bins[start[col]++] = t;
        }
    }
    if (pass == 0) {
      for (size_t col = 0; col < columns; col++) start[col + 1] += start[col];
      bins = bk_calloc(start[columns] ? start[columns] : 1, sizeof *bins, "voxelize: ray bins", err);
      if (!bins) return BK_ERR_RUNTIME;
    } else {
      /* the fill advanced every start to the next column's start: shift back */
      for (size_t col = columns; col > 0; col--) start[col] = start[col - 1];
      start[0] = 0;
    }
  }
  *bins_out = bins;
  return BK_OK;
}

/* Depths along axis `ax` at which the ray through (pb, pc) crosses the `count`
 * triangles `tris` (unsorted, into *hits, which grows as needed). Edge-on
 * triangles and edges the top-left rule gives to a neighbour add nothing, so
 * a ray through a shared edge or vertex is counted once. */
static int vox_column_hits(const mesh_tris_t *m, const int *tris, size_t count, int ax, int bx,
                           int cx, double pb, double pc, double **hits, int *hit_cap, int *nh_out,
                           bk_error_t *err) {
  int nh = 0;
  for (size_t e = 0; e < count; e++) {
    const int *f = m->indices + 3 * (size_t)tris[e];
    const float *v0 = m->positions + 3 * (size_t)f[0];
    const float *v1 = m->positions + 3 * (size_t)f[1];
    const float *v2 = m->positions + 3 * (size_t)f[2];
    double x0 = v0[bx], y0 = v0[cx], x1 = v1[bx], y1 = v1[cx], x2 = v2[bx], y2 = v2[cx];
    double z0 = v0[ax], z1 = v1[ax], z2 = v2[ax];
    double area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0);
    if (area == 0.0) continue; /* edge-on to the ray: its neighbours decide */
    if (area < 0.0) {          /* make it counter-clockwise */
      double tx = x1, ty = y1, tz = z1;
      x1 = x2, y1 = y2, z1 = z2;
      x2 = tx, y2 = ty, z2 = tz;
    }
    double e01 = edge_fn(x0, y0, x1, y1, pb, pc);
    if (!owns_edge(x0, y0, x1, y1, e01)) continue;
    double e12 = edge_fn(x1, y1, x2, y2, pb, pc);
    if (!owns_edge(x1, y1, x2, y2, e12)) continue;
    double e20 = edge_fn(x2, y2, x0, y0, pb, pc);
    if (!owns_edge(x2, y2, x0, y0, e20)) continue;
    double sum = e01 + e12 + e20;
    if (!(sum > 0.0)) continue;
    if (nh == *hit_cap) {
      double *bigger = realloc(*hits, 2 * (size_t)*hit_cap * sizeof **hits);
      if (!bigger) return bk_fail(err, BK_ERR_RUNTIME, "voxelize: out of memory for ray hits");
      *hits = bigger;
      *hit_cap *= 2;
    }
    /* barycentric depth: each edge function weighs the opposite vertex */
    (*hits)[nh++] = (e12 * z0 + e20 * z1 + e01 * z2) / sum;
  }
  *nh_out = nh;
  return BK_OK;
}

/* Walks column (bb, cc) along `ax` with its sorted hits: a voxel centre past
 * an odd number of hits is inside (+1), past an even number outside (-1). */
static void vox_column_vote(const vox_region_t *r, int ax, int bx, int cx, int bb, int cc,
                            const double *hits, int nh, signed char *vote) {
  const size_t stride[3] = {1, (size_t)r->n[0], (size_t)r->n[0] * (size_t)r->n[1]};
  size_t idx[3];
  idx[ax] = 0;
  idx[bx] = (size_t)(bb - r->lo[bx]);
  idx[cx] = (size_t)(cc - r->lo[cx]);
  signed char *cell = vote + idx[0] * stride[0] + idx[1] * stride[1] + idx[2] * stride[2];
  int h = 0;
  for (int a = r->lo[ax]; a <= r->hi[ax]; a++, cell += stride[ax]) {
    while (h < nh && hits[h] < (double)a) h++;
    *cell += (h & 1) ? 1 : -1;
  }
}

/* Rays along axis `ax` through the region's voxel centres. Each ray column
 * adds +1 (inside) or -1 (outside) to the vote of its voxels by hit parity;
 * a column with an odd number of hits crossed an open boundary and abstains. */
static int vox_parity_axis(const mesh_tris_t *m, const vox_region_t *r, int ax, signed char *vote,
                           bk_progress_t *prog, uint64_t prog_base, uint64_t prog_span,
                           bk_error_t *err) {
  /* the column's 2D axes, lower one first: neighbouring columns then write
   * neighbouring bytes of the vote array, which keeps the y and z passes in cache */
  const int bx = ax == 0 ? 1 : 0, cx = ax == 2 ? 1 : 2;
  const int nb = r->n[bx], nc = r->n[cx];
  const size_t columns = (size_t)nb * (size_t)nc;
  size_t *start = NULL;
  int *bins = NULL;
  double *hits = NULL;
  int rc = BK_OK, hit_cap = 64;

  start = bk_calloc(columns + 1, sizeof *start, "voxelize: ray columns", err);
  hits = bk_calloc((size_t)hit_cap, sizeof *hits, "voxelize: ray hits", err);
  if (!start || !hits) {
    rc = BK_ERR_RUNTIME;
    goto error;
  }
  rc = vox_bin_columns(m, r, bx, cx, start, &bins, err);
  if (rc) goto error;

  for (size_t col = 0; col < columns; col++) {
    int bb = r->lo[bx] + (int)(col % (size_t)nb), cc = r->lo[cx] + (int)(col / (size_t)nb);
    int nh = 0;
    rc = vox_column_hits(m, bins + start[col], start[col + 1] - start[col], ax, bx, cx, bb, cc,
                         &hits, &hit_cap, &nh, err);
    if (rc) goto error;
    if (nh & 1) continue; /* open boundary crossed: abstain */
    sort_hits(hits, nh);
    vox_column_vote(r, ax, bx, cx, bb, cc, hits, nh, vote);
    if ((col & 4095) == 0)
      bk_progress_update(prog, prog_base + prog_span * (uint64_t)col / (uint64_t)columns);
  }

error:
  free(start);
  free(bins);
  free(hits);
  return rc;
}

/* --- compositing --------------------------------------------------------------- */
/* Composites one object over the volume: x += w (x_object - x). */
static void vox_blend(const scene_object_t *obj, const vox_region_t *r, float band, float smoothing,
                      const float *dist2, const signed char *vote, volume_t *out) {
  const float band2 = band * band;
  const grid_dims_t *d = &out->dims;
  for (int k = r->lo[2]; k <= r->hi[2]; k++)
    for (int j = r->lo[1]; j <= r->hi[1]; j++) {
      size_t rv = region_index(r, r->lo[0], j, k);
      size_t gv = grid_index(d, r->lo[0], j, k);
      for (int i = r->lo[0]; i <= r->hi[0]; i++, rv++, gv++) {
        int inside = vote[rv] > 0;
        float w;
        if (dist2[rv] >= band2) {
          w = inside ? 1.0f : 0.0f;
        } else {
          float dd = sqrtf(dist2[rv]);
          w = vox_weight(inside ? -dd : dd, smoothing);
        }
        if (w <= 0.0f) continue;
        const int C = out->sigma_channels;
        /* sigma_t holds σa until vox_summarise */
        float *s = out->sigma_s + (size_t)C * gv, *a = out->sigma_t + (size_t)C * gv;
        if (out->g) out->g[gv] = w >= 1.0f ? obj->g : out->g[gv] + w * (obj->g - out->g[gv]);
        if (out->ior_rb) vox_blend_dispersion(obj, w, gv, grid_count(d), out->ior_rb);
        if (w >= 1.0f) { /* exactly the object's values, so interiors stay homogeneous */
          out->ior[gv] = obj->ior;
          for (int ch = 0; ch < C; ch++) {
            s[ch] = obj->sigma_s[ch];
            a[ch] = obj->sigma_a[ch];
          }
          continue;
        }
        out->ior[gv] += w * (obj->ior - out->ior[gv]);
        for (int ch = 0; ch < C; ch++) {
          s[ch] += w * (obj->sigma_s[ch] - s[ch]);
          a[ch] += w * (obj->sigma_a[ch] - a[ch]);
        }
      }
    }
}

/* --- the stage ------------------------------------------------------------------- */
/* Per-object scratch, kept across objects and grown to the largest region. */
typedef struct vox_scratch {
  float *dist2;
  signed char *vote;
  size_t cap;
} vox_scratch_t;

/* The grid, the memory it needs and the volume filled with the medium: what
 * the objects are composited over. Refuses a grid that cannot fit before
 * allocating anything. */
static int vox_prepare(const scene_t *scene, const char *grid_where, const float box[2][3],
                       volume_t *out, bk_error_t *err) {
  int rc = vox_grid_for(scene, scene->resolution, box[0], box[1], &out->whole, &out->dims,
                        out->crop_off, &out->cropped, err);
  if (rc) return rc;
  if (out->cropped)
    bk_log(1, "voxelize: vacuum medium: baking the %dx%dx%d voxels around the objects, from "
              "voxel (%d, %d, %d) of the %dx%dx%d grid (grid.crop_to_objects: false bakes it all)",
           out->dims.nx, out->dims.ny, out->dims.nz, out->crop_off[0], out->crop_off[1],
           out->crop_off[2], out->whole.nx, out->whole.ny, out->whole.nz);
  if (!(scene->ior_smoothing > 0.0f) || !isfinite(scene->ior_smoothing))
    return bk_fail(err, BK_ERR_INPUT, "%s: grid.ior_smoothing: expected a positive number of voxels, got %g",
                   grid_where, scene->ior_smoothing);
  const grid_dims_t *d = &out->dims;
  /* a scene whose medium and objects are all grey gives a grey volume: its
   * coefficients once per voxel from the start; others RGB until
   * vox_summarise finds the volume grey after all */
  const size_t C = (size_t)(out->sigma_channels = scene_is_grey(scene) ? 1 : 3);
  /* everything this stage holds at once: the volume, an object's scratch
   * (at most the whole grid), and the density field while it is applied */
  /* a g grid only when an object's phase differs from the medium's */
  int g_grid = 0;
  for (int i = 0; i < scene->object_count; i++)
    if (scene->objects[i].g != scene->medium_g) g_grid = 1;
  size_t per_voxel = VOX_BYTES_PER_VOXEL(C) + (g_grid ? sizeof(float) : 0) +
                     (scene->object_count > 0 ? VOX_SCRATCH_BYTES : 0) +
                     (scene->density_vdb.present ? sizeof(float) : 0) +
                     (scene_has_dispersion(scene) ? 2 * sizeof(float) : 0);
  rc = grid_check_memory(d, per_voxel, grid_where, err);
  if (rc) return rc;

  const size_t count = grid_count(d);
  out->ior = bk_calloc(count, sizeof(float), "voxelize: ior grid", err);
  out->sigma_s = bk_calloc(count, C * sizeof(float), "voxelize: sigma_s grid", err);
  out->sigma_t = bk_calloc(count, C * sizeof(float), "voxelize: sigma_t grid", err);
  if (!out->ior || !out->sigma_s || !out->sigma_t) return BK_ERR_RUNTIME;
  if (g_grid) {
    out->g = bk_calloc(count, sizeof(float), "voxelize: g grid", err);
    if (!out->g) return BK_ERR_RUNTIME;
    for (size_t i = 0; i < count; i++) out->g[i] = scene->medium_g;
  }
  double t_medium = bk_now_ms();
  rc = vox_medium(scene, out, err);
  if (rc) return rc;
  bk_log(2, "voxelize: medium %.0f ms", bk_now_ms() - t_medium);
  return BK_OK;
}

/* World (the transform applied) -> voxel index space (voxel centres at
 * integers); lo and hi get the mesh's bounds there. A vertex the transform
 * sent to infinity is an input error, not a silent hole in the inside test. */
static int vox_to_index_space(mesh_tris_t *mesh, const scene_object_t *obj, const char *where,
                              const grid_dims_t *d, float lo[3], float hi[3], bk_error_t *err) {
  for (int a = 0; a < 3; a++) {
    lo[a] = INFINITY;
    hi[a] = -INFINITY;
  }
  for (int v = 0; v < mesh->vertex_count; v++) {
    float *p = mesh->positions + 3 * (size_t)v;
    for (int a = 0; a < 3; a++) {
      if (!isfinite(p[a]))
        return bk_fail(err, BK_ERR_INPUT,
                       "%s: %s: the object's transform takes vertex %d to a non-finite position",
                       where, obj->mesh, v);
      p[a] = (float)(((double)p[a] - d->origin[a]) / d->voxel_size - 0.5);
      if (!isfinite(p[a]))
        return bk_fail(err, BK_ERR_INPUT,
                       "%s: %s: the object's transform takes vertex %d beyond %g voxels from the grid",
                       where, obj->mesh, v, (double)FLT_MAX);
      lo[a] = fminf(lo[a], p[a]);
      hi[a] = fmaxf(hi[a], p[a]);
    }
  }
  return BK_OK;
}

/* The voxels within `band` of the mesh's bounds, clipped to the grid: the
 * only ones the object can change. Returns 0 when none are left. */
static int vox_region_around(const float lo[3], const float hi[3], float band,
                             const grid_dims_t *d, vox_region_t *r) {
  int n[3] = {d->nx, d->ny, d->nz}, outside = 0;
  r->count = 1;
  for (int a = 0; a < 3; a++) {
    float l = floorf(lo[a] - band), h = ceilf(hi[a] + band);
    r->lo[a] = l < 0.0f ? 0 : (l > (float)(n[a] - 1) ? n[a] : (int)l);
    r->hi[a] = h > (float)(n[a] - 1) ? n[a] - 1 : (h < 0.0f ? -1 : (int)h);
    if (r->lo[a] > r->hi[a]) outside = 1;
    r->n[a] = r->hi[a] - r->lo[a] + 1;
    r->count *= outside ? 1 : (size_t)r->n[a];
  }
  return !outside;
}

/* Room for `count` voxels of scratch (the old contents are not kept) with
 * every inside vote at zero. */
static int vox_scratch_fit(vox_scratch_t *s, size_t count, bk_error_t *err) {
  if (count > s->cap) {
    free(s->dist2);
    free(s->vote);
    s->vote = NULL;
    s->dist2 = bk_calloc(count, sizeof *s->dist2, "voxelize: distance scratch", err);
    if (s->dist2) s->vote = bk_calloc(count, sizeof *s->vote, "voxelize: inside votes", err);
    if (!s->dist2 || !s->vote) return BK_ERR_RUNTIME;
    s->cap = count;
  }
  memset(s->vote, 0, count * sizeof *s->vote);
  return BK_OK;
}

/* The three passes over one object's region (distance, inside votes along
 * x, y and z, blend), a quarter of the progress bar each for the first four. */
static int vox_object_passes(const scene_object_t *obj, const mesh_tris_t *mesh,
                             const vox_region_t *r, float band, float smoothing,
                             vox_scratch_t *s, bk_progress_t *prog, volume_t *out,
                             bk_error_t *err) {
  uint64_t tris = (uint64_t)mesh->triangle_count;
  prog->total = 4 * tris;
  double t1 = bk_now_ms();
  vox_distance(mesh, r, band, s->dist2, prog, 0);
  double t2 = bk_now_ms();
  for (int ax = 0; ax < 3; ax++) {
    int rc = vox_parity_axis(mesh, r, ax, s->vote, prog, tris * (uint64_t)(1 + ax), tris, err);
    if (rc) return rc;
  }
  double t3 = bk_now_ms();
  vox_blend(obj, r, band, smoothing, s->dist2, s->vote, out);
  bk_log(2, "%s: %dx%dx%d voxels around it: distance %.0f ms, inside votes %.0f ms, blend %.0f ms",
         obj->mesh, r->n[0], r->n[1], r->n[2], t2 - t1, t3 - t2, bk_now_ms() - t3);
  bk_progress_update(prog, prog->total);
  return BK_OK;
}

int vox_meshes_load(const scene_t *scene, vox_meshes_t *m, bk_error_t *err) {
  memset(m, 0, sizeof *m);
  for (int a = 0; a < 3; a++) m->box[0][a] = INFINITY, m->box[1][a] = -INFINITY;
  m->mesh = bk_calloc((size_t)scene->object_count + 1, sizeof *m->mesh, "voxelize: meshes", err);
  if (!m->mesh) return BK_ERR_RUNTIME;
  m->count = scene->object_count;
  for (int oi = 0; oi < scene->object_count; oi++) {
    const scene_object_t *obj = &scene->objects[oi];
    char buf[VOX_WHERE_MAX];
    mesh_tris_t *mesh = &m->mesh[oi];
    int rc = vox_read_mesh(obj, vox_object_where(scene, oi, buf), mesh, &m->load_ms, err);
    if (rc) return rc;
    mesh_report_t report;
    double t_check = bk_now_ms();
    if ((rc = mesh_check(mesh, &report, err))) return rc;
    mesh_check_log(obj->mesh, &report);
    bk_log(2, "%s: topology check %.0f ms", obj->mesh, bk_now_ms() - t_check);
    mesh_transform(mesh, obj);
    vox_mesh_bounds(mesh, m->box[0], m->box[1]);
    m->tris += mesh->triangle_count;
    m->check_ms += bk_now_ms() - t_check;
  }
  return BK_OK;
}

void vox_meshes_free(vox_meshes_t *m) {
  for (int oi = 0; m->mesh && oi < m->count; oi++) mesh_io_free(&m->mesh[oi]);
  free(m->mesh);
  memset(m, 0, sizeof *m);
}

int vox_build(const scene_t *scene, volume_t *out, bk_timings_t *timings, bk_error_t *err) {
  vox_meshes_t meshes;
  int rc = vox_meshes_load(scene, &meshes, err);
  if (!rc) return vox_build_meshes(scene, &meshes, 0, out, timings, err);
  vox_meshes_free(&meshes);
  memset(out, 0, sizeof *out);
  return rc;
}

int vox_build_meshes(const scene_t *scene, vox_meshes_t *meshes, int code_grey, volume_t *out,
                     bk_timings_t *timings, bk_error_t *err) {
  vox_scratch_t scratch = {0};
  bk_progress_t prog = {0};
  char label[48];
  const long long total_tris = meshes->tris;
  const double load_ms = meshes->load_ms, t_start = bk_now_ms();
  const char *grid_where = scene->where_resolution[0] ? scene->where_resolution : scene->path;

  memset(out, 0, sizeof *out);
  out->code_grey = code_grey;
  /* the objects' world box is for a vacuum's crop (vox_crop.h) */
  int rc = vox_prepare(scene, grid_where, (const float(*)[3])meshes->box, out, err);
  if (rc) goto error;
  const grid_dims_t *d = &out->dims;
  const size_t count = grid_count(d);
  const float smoothing = scene->ior_smoothing;
  const float band = 0.5f * smoothing + VOX_BAND_MARGIN;
  bk_progress_begin(&prog, "voxelize", 1);
  if (count < VOX_PROGRESS_MIN_VOXELS || scene->object_count == 0) prog.enabled = 0;

  for (int oi = 0; oi < scene->object_count; oi++) {
    const scene_object_t *obj = &scene->objects[oi];
    char buf[VOX_WHERE_MAX];
    const char *where = vox_object_where(scene, oi, buf);
    mesh_tris_t *mesh = &meshes->mesh[oi];
    float lo[3], hi[3];
    rc = vox_to_index_space(mesh, obj, where, d, lo, hi, err);
    if (rc) goto error;
    vox_region_t r;
    if (!vox_region_around(lo, hi, band, d, &r)) {
      bk_warn("%s: %s lies entirely outside grid.bounds; ignored", where, obj->mesh);
      mesh_io_free(mesh);
      continue;
    }
    rc = vox_scratch_fit(&scratch, r.count, err);
    if (rc) goto error;
    snprintf(label, sizeof label, "voxelize %d/%d", oi + 1, scene->object_count);
    prog.label = scene->object_count > 1 ? label : "voxelize";
    rc = vox_object_passes(obj, mesh, &r, band, smoothing, &scratch, &prog, out, err);
    if (rc) goto error;
    mesh_io_free(mesh); /* each as soon as it is in the volume */
  }
  bk_progress_end(&prog);
  double t_sum = bk_now_ms();
  vox_summarise(out);
  bk_log(2, "voxelize: summary %.0f ms", bk_now_ms() - t_sum);

  if (scene->object_count > 0)
    bk_timings_add(timings, "mesh load", load_ms, "%d mesh%s, %lld tris", scene->object_count,
                   scene->object_count == 1 ? "" : "es", total_tris);
  double vox_ms = bk_now_ms() - t_start + meshes->check_ms;
  bk_timings_add(timings, "voxelize", vox_ms,
                 "%d object%s, %lld tris, %dx%dx%d, n in [%g, %g], %.0f M voxels/s%s",
                 scene->object_count, scene->object_count == 1 ? "" : "s", total_tris, d->nx,
                 d->ny, d->nz, out->n_min, out->n_max, (double)count / (vox_ms * 1e3 + 1e-9),
                 out->grey && out->sigma_code ? ", sigma coded to fit in memory" : "");
  vox_meshes_free(meshes);
  free(scratch.dist2);
  free(scratch.vote);
  return BK_OK;

error:
  vox_meshes_free(meshes);
  free(scratch.dist2);
  free(scratch.vote);
  vox_free(out);
  return rc;
}

void vox_free(volume_t *v) {
  if (!v) return;
  free(v->ior);
  free(v->sigma_s);
  free(v->sigma_t);
  free(v->sigma_code);
  free(v->density);
  free(v->g);
  free(v->ior_rb);
  v->ior = v->sigma_s = v->sigma_t = v->sigma_code = v->density = v->g = v->ior_rb = NULL;
}
