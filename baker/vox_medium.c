/* vox_medium.c: the medium under the objects, and the summary of the volume
 * once they are composited (see vox_medium.h). */
#include "vox_medium.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "vdbio.h"
#include "vox_code.h"

/* The uniform medium over voxels [lo, hi): the grid's first touch, hundreds
 * of MiB at 256^3, so spread over the cores. */
typedef struct medium_fill {
  const scene_t *scene;
  volume_t *out;
} medium_fill_t;

static void fill_ior_range(void *ctx, size_t lo, size_t hi) {
  const medium_fill_t *f = ctx;
  for (size_t v = lo; v < hi; v++) f->out->ior[v] = f->scene->medium_ior;
}

/* σs and σa: sigma_t holds σa until vox_summarise makes it σs + σa */
static void fill_sigma_range(void *ctx, size_t lo, size_t hi) {
  const medium_fill_t *f = ctx;
  const float *ms = f->scene->medium_sigma_s, *ma = f->scene->medium_sigma_a;
  float *s = f->out->sigma_s, *a = f->out->sigma_t;
  const int C = f->out->sigma_channels;
  for (size_t v = lo; v < hi; v++)
    for (int ch = 0; ch < C; ch++) {
      s[(size_t)C * v + ch] = ms[ch];
      a[(size_t)C * v + ch] = ma[ch];
    }
}

/* density_vdb's values into σs and σa (sigma_t holds σa, as above) in
 * chunks side by side: a negative density counts and becomes 0; each chunk
 * notes its first non-finite one (SIZE_MAX: none), the earliest is reported. */
#define DENSITY_CHUNKS 64
typedef struct density_fill {
  const scene_t *scene;
  volume_t *out;
  const float *density;
  size_t clamped[DENSITY_CHUNKS], bad[DENSITY_CHUNKS];
} density_fill_t;

static void fill_density_chunk(void *ctx, size_t k, size_t lo, size_t hi) {
  density_fill_t *f = ctx;
  const float *ms = f->scene->medium_sigma_s, *ma = f->scene->medium_sigma_a;
  volume_t *out = f->out;
  size_t clamped = 0;
  f->bad[k] = SIZE_MAX;
  for (size_t v = lo; v < hi; v++) {
    float rho = f->density[v];
    if (!isfinite(rho)) {
      f->bad[k] = v;
      break;
    }
    if (rho < 0.0f) rho = 0.0f, clamped++;
    for (int ch = 0; ch < out->sigma_channels; ch++) {
      out->sigma_s[vox_sigma_index(out, v, ch)] = ms[ch] * rho;
      out->sigma_t[vox_sigma_index(out, v, ch)] = ma[ch] * rho;
    }
  }
  f->clamped[k] = clamped;
}

/* n from the scene's ior_vdb, resampled onto the grid; n < 1 (e.g. a zero
 * background outside the active voxels) is raised to 1, with a warning. */
static int medium_ior_from_vdb(const scene_t *scene, volume_t *out, bk_error_t *err) {
  const scene_vdb_ref_t *ref = &scene->ior_vdb;
  const size_t count = grid_count(&out->dims);
  int rc = vdbio_resample_float(ref->file, ref->grid, &out->dims, out->ior, ref->where, err);
  if (rc) return rc;
  size_t clamped = 0;
  float lowest = 1.0f;
  for (size_t v = 0; v < count; v++) {
    if (!isfinite(out->ior[v]))
      return bk_fail(err, BK_ERR_INPUT, "%s: %s: grid \"%s\" gives a non-finite n at voxel %zu",
                     ref->where, ref->file, ref->grid, v);
    if (out->ior[v] < 1.0f) {
      lowest = fminf(lowest, out->ior[v]);
      out->ior[v] = 1.0f;
      clamped++;
    }
  }
  if (clamped)
    bk_warn("%s: %s: grid \"%s\": %zu voxels had n < 1 (lowest %g), raised to 1", ref->where,
            ref->file, ref->grid, clamped, lowest);
  return BK_OK;
}

/* σs and σa from the scene's density_vdb (density_fill_t); the density is
 * kept in out->density until vox_summarise codes σ by it. */
static int medium_sigma_from_density(const scene_t *scene, volume_t *out, bk_error_t *err) {
  const scene_vdb_ref_t *ref = &scene->density_vdb;
  const size_t count = grid_count(&out->dims);
  float *density = bk_calloc(count, sizeof *density, "voxelize: density_vdb", err);
  if (!density) return BK_ERR_RUNTIME;
  int rc = vdbio_resample_float(ref->file, ref->grid, &out->dims, density, ref->where, err);
  if (rc) {
    free(density);
    return rc;
  }
  density_fill_t f = {scene, out, density, {0}, {0}};
  bk_parallel_chunks(count, DENSITY_CHUNKS, fill_density_chunk, &f);
  size_t clamped = 0, bad = SIZE_MAX;
  for (int k = 0; k < DENSITY_CHUNKS; k++) {
    clamped += f.clamped[k];
    bad = f.bad[k] < bad ? f.bad[k] : bad;
  }
  if (bad != SIZE_MAX) {
    free(density);
    return bk_fail(err, BK_ERR_INPUT, "%s: %s: grid \"%s\" gives a non-finite density at voxel %zu",
                   ref->where, ref->file, ref->grid, bad);
  }
  if (clamped)
    bk_warn("%s: %s: grid \"%s\": %zu voxels had a negative density, set to 0", ref->where,
            ref->file, ref->grid, clamped);
  out->density = density;
  return BK_OK;
}

int vox_medium(const scene_t *scene, volume_t *out, bk_error_t *err) {
  const size_t count = grid_count(&out->dims);
  medium_fill_t f = {scene, out};
  int rc = BK_OK;
  if (scene->ior_vdb.present) rc = medium_ior_from_vdb(scene, out, err);
  else bk_parallel(count, BK_GRAIN, fill_ior_range, &f);
  if (rc) return rc;
  if (scene->density_vdb.present) rc = medium_sigma_from_density(scene, out, err);
  else bk_parallel(count, BK_GRAIN, fill_sigma_range, &f);
  if (rc) return rc;
  for (int c = 0; c < 3; c++) {
    out->medium_s[c] = scene->medium_sigma_s[c];
    out->medium_a[c] = scene->medium_sigma_a[c];
  }
  if (scene_has_dispersion(scene)) { /* the medium's n in every channel */
    if (!(out->ior_rb = bk_calloc(count, 2 * sizeof(float), "voxelize: ior per channel", err)))
      return BK_ERR_RUNTIME;
    memcpy(out->ior_rb, out->ior, count * sizeof(float));
    memcpy(out->ior_rb + count, out->ior, count * sizeof(float));
  }
  return BK_OK;
}

void vox_blend_dispersion(const scene_object_t *obj, float w, size_t gv, size_t plane, float *rb) {
  for (int p = 0; p < 2; p++) {
    float n = scene_object_n(obj, 2 * p), *x = rb + p * plane + gv;
    *x = w >= 1.0f ? n : *x + w * (n - *x);
  }
}

/* --- the summary --------------------------------------------------------------- */

/* Pieces of the parallel summary (more than cores, few enough to combine). */
#define VOX_SUMMARY_CHUNKS 64

/* A grey medium's coefficients once per voxel (vox_sigma_index), the RGB
 * arrays shrunk in place: the volume lives through every phase. */
static void vox_store_grey(volume_t *v) {
  const size_t n = grid_count(&v->dims);
  for (size_t i = 0; i < n; i++) {
    v->sigma_s[i] = v->sigma_s[3 * i];
    v->sigma_t[i] = v->sigma_t[3 * i];
  }
  float *s = realloc(v->sigma_s, n * sizeof(float)), *a = realloc(v->sigma_t, n * sizeof(float));
  if (s) v->sigma_s = s; /* a failed shrink keeps the larger block: still valid */
  if (a) v->sigma_t = a;
  v->sigma_channels = 1;
}

/* A homogeneous medium's coefficients once (voxel 0's, vox_sigma_index):
 * no σ grids for it (4-12 bytes per voxel each). */
static void vox_store_uniform(volume_t *v) {
  const size_t C = v->sigma_channels == 1 ? 1 : 3;
  float *s = realloc(v->sigma_s, C * sizeof(float)), *a = realloc(v->sigma_t, C * sizeof(float));
  if (s) v->sigma_s = s; /* a failed shrink keeps the larger block: still valid */
  if (a) v->sigma_t = a;
  v->homogeneous = 1;
}

/* The scan in VOX_SUMMARY_CHUNKS chunks of the grid, each with its own
 * slot. Combining min, max and OR is exact in any order. With t_out
 * (vox_summarise) the sigma_t array still holds σa and each chunk turns it
 * into σs + σa as it goes; voxel 0's values, which every chunk compares
 * with, are taken before any chunk writes. */
typedef struct vox_chunks {
  const volume_t *v;
  float *t_out;       /* v->sigma_t, to be written; else NULL */
  float s0[3], t0[3]; /* voxel 0 per channel */
  vox_scan_t slot[VOX_SUMMARY_CHUNKS];
} vox_chunks_t;

/* σt at index at: the stored value, or with t_out σs + σa, stored. */
static inline float scan_t(const vox_chunks_t *S, const float *ss, const float *st, size_t at) {
  if (!S->t_out) return st[at];
  const float t = ss[at] + st[at];
  S->t_out[at] = t;
  return t;
}

/* scan_chunk for a volume grey from the start (one value per voxel stands
 * for every channel): the channel sums are then 3·σs and 3·σt, which double
 * holds exactly, so they keep their bits without per-channel adds; nothing
 * is coloured. */
static void scan_chunk_grey(vox_chunks_t *S, size_t k, size_t lo, size_t hi) {
  const volume_t *v = S->v;
  const float *ss = v->sigma_s, *st = v->sigma_t, s0 = S->s0[0], t0 = S->t0[0];
  float n_min = v->ior[lo], n_max = v->ior[lo];
  int t_varies = 0, s_varies = 0, g_varies = 0, g_set = 0;
  vox_scan_t p = S->slot[k]; /* zero sums */
  for (size_t i = lo; i < hi; i++) {
    const float n = v->ior[i], t = scan_t(S, ss, st, i);
    n_min = n < n_min ? n : n_min;
    n_max = n > n_max ? n : n_max;
    const double s3 = 3.0 * (double)ss[i], t3 = 3.0 * (double)t;
    p.ss += s3;
    p.st += t3;
    if (s3 > 0.0) p.st_scattering += t3, p.scattering++;
    s_varies |= ss[i] != s0;
    t_varies |= t != t0;
    if (v->g) g_varies |= v->g[i] != v->g[0], g_set |= v->g[i] != 0.0f;
  }
  p.n_min = n_min, p.n_max = n_max;
  p.varies = s_varies | t_varies, p.t_varies = t_varies, p.s_varies = s_varies;
  p.coloured = p.t_coloured = p.s_coloured = 0;
  p.g_varies = g_varies, p.g_set = g_set;
  S->slot[k] = p;
}

/* Three channels per voxel: the channel sums in bounces.c's former order
 * (the channels, then the voxels). */
static void scan_chunk(void *ctx, size_t k, size_t lo, size_t hi) {
  vox_chunks_t *S = ctx;
  const volume_t *v = S->v;
  if (lo >= hi) return;
  if (v->sigma_channels == 1) { /* grey from the start */
    scan_chunk_grey(S, k, lo, hi);
    return;
  }
  const float *s0 = S->s0, *t0 = S->t0;
  float n_min = v->ior[lo], n_max = v->ior[lo];
  /* branch-free accumulation: this runs over every voxel of the grid */
  int s_varies = 0, s_coloured = 0, t_varies = 0, t_coloured = 0, g_varies = 0, g_set = 0;
  vox_scan_t p = S->slot[k]; /* zero sums */
  for (size_t i = lo; i < hi; i++) {
    float n = v->ior[i];
    n_min = n < n_min ? n : n_min;
    n_max = n > n_max ? n : n_max;
    const float *s = v->sigma_s + 3 * i;
    const float t[3] = {scan_t(S, v->sigma_s, v->sigma_t, 3 * i),
                        scan_t(S, v->sigma_s, v->sigma_t, 3 * i + 1),
                        scan_t(S, v->sigma_s, v->sigma_t, 3 * i + 2)};
    const double sum_s = ((double)s[0] + s[1]) + s[2], sum_t = ((double)t[0] + t[1]) + t[2];
    p.ss += sum_s;
    p.st += sum_t;
    if (sum_s > 0.0) p.st_scattering += sum_t, p.scattering++;
    s_varies |= (s[0] != s0[0]) | (s[1] != s0[1]) | (s[2] != s0[2]);
    s_coloured |= (s[0] != s[1]) | (s[0] != s[2]);
    t_varies |= (t[0] != t0[0]) | (t[1] != t0[1]) | (t[2] != t0[2]);
    t_coloured |= (t[0] != t[1]) | (t[1] != t[2]);
    if (v->g) g_varies |= v->g[i] != v->g[0], g_set |= v->g[i] != 0.0f;
  }
  p.n_min = n_min, p.n_max = n_max;
  p.varies = s_varies | t_varies, p.coloured = s_coloured | t_coloured;
  p.t_varies = t_varies, p.t_coloured = t_coloured;
  p.s_varies = s_varies, p.s_coloured = s_coloured;
  p.g_varies = g_varies, p.g_set = g_set;
  S->slot[k] = p;
}

/* vox_scan; with t_out (v->sigma_t, holding σa) σs + σa written there on
 * the way. */
static void scan_volume(const volume_t *v, float *t_out, vox_scan_t *out) {
  vox_chunks_t S;
  S.v = v;
  S.t_out = t_out;
  for (int c = 0; c < 3; c++) {
    const size_t at = vox_sigma_index(v, 0, c);
    S.s0[c] = v->sigma_s[at];
    S.t0[c] = t_out ? v->sigma_s[at] + v->sigma_t[at] : v->sigma_t[at];
  }
  /* an empty chunk (a grid of fewer voxels) reads as the first voxel */
  vox_scan_t first;
  memset(&first, 0, sizeof first);
  first.n_min = first.n_max = v->ior[0];
  for (int k = 0; k < VOX_SUMMARY_CHUNKS; k++) S.slot[k] = first;
  bk_parallel_chunks(grid_count(&v->dims), VOX_SUMMARY_CHUNKS, scan_chunk, &S);
  *out = first;
  for (int k = 0; k < VOX_SUMMARY_CHUNKS; k++) {
    const vox_scan_t *c = &S.slot[k];
    out->n_min = c->n_min < out->n_min ? c->n_min : out->n_min;
    out->n_max = c->n_max > out->n_max ? c->n_max : out->n_max;
    out->varies |= c->varies;
    out->coloured |= c->coloured;
    out->t_varies |= c->t_varies;
    out->t_coloured |= c->t_coloured;
    out->ss += c->ss, out->st += c->st, out->st_scattering += c->st_scattering;
    out->scattering += c->scattering;
    out->s_varies |= c->s_varies, out->s_coloured |= c->s_coloured;
    out->g_varies |= c->g_varies, out->g_set |= c->g_set;
  }
}

/* A homogeneous volume keeps one voxel's coefficients (vox_store_uniform):
 * its summary scan stands. */
void vox_scan(const volume_t *v, vox_scan_t *out) {
  if (v->homogeneous && v->scanned) *out = v->scan;
  else scan_volume(v, NULL, out);
}

const vox_scan_t *vox_scan_of(const volume_t *v, vox_scan_t *own) {
  if (v->scanned) return &v->scan;
  vox_scan(v, own);
  return own;
}

void vox_summarise(volume_t *v) {
  scan_volume(v, v->sigma_t, &v->scan);
  v->scanned = 1;
  v->n_min = v->scan.n_min;
  v->n_max = v->scan.n_max;
  v->has_refraction = (v->n_max - v->n_min) > 1e-6f;
  v->grey = !v->scan.coloured;
  if (v->grey && v->sigma_channels == 3) vox_store_grey(v);
  if (!v->scan.varies) vox_store_uniform(v);
  /* RGB σ coded: 24 bytes per voxel become about 4, for a march some 15%
   * slower. A grey volume keeps its 8 bytes, unless the bake fits in memory
   * only with 4: coding costs its voxelize some 4 ns per voxel and its
   * march about 3% (docs/memory.md) */
  if (!v->homogeneous && (!v->grey || v->code_grey)) vox_code(v);
  free(v->density);
  v->density = NULL;
}
