/* bounces.c: multiple scattering's host side (see bounces.h). */
#include "bounces.h"

#include "base/parallel.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One pass over the volume for the rule and the scatter grid's need, in
 * MS_SCAN_CHUNKS chunks side by side whose sums are added in chunk order
 * (the same bits on every run and thread count). */
#define MS_SCAN_CHUNKS 64
typedef struct ms_scan {
  double ss, st, st_scattering; /* Σ σs, Σ σt, Σ σt where σs > 0 (channels summed) */
  size_t scattering;            /* voxels with σs > 0 */
  int sigma_varies, colour;     /* σs differs between voxels; between channels */
  int g_varies, g_set;          /* g differs between voxels; g != 0 somewhere */
} ms_scan_t;

typedef struct ms_scan_ctx {
  const volume_t *vol;
  ms_scan_t part[MS_SCAN_CHUNKS];
} ms_scan_ctx_t;

static void scan_voxels(const volume_t *vol, size_t a, size_t b, ms_scan_t *p) {
  const float *sg = vol->sigma_s;
  float s0[3];
  for (int c = 0; c < 3; c++) s0[c] = sg[vox_sigma_index(vol, 0, c)];
  for (size_t i = a; i < b; i++) {
    double s = 0.0, t = 0.0;
    float sc[3];
    for (int c = 0; c < 3; c++) {
      const size_t at = vox_sigma_index(vol, i, c);
      sc[c] = sg[at];
      s += sg[at];
      t += sg[at] + vol->sigma_a[at];
    }
    p->ss += s;
    p->st += t;
    if (s > 0.0) p->st_scattering += t, p->scattering++;
    if (sc[0] != s0[0] || sc[1] != s0[1] || sc[2] != s0[2]) p->sigma_varies = 1;
    if (sc[0] != sc[1] || sc[0] != sc[2]) p->colour = 1;
    if (vol->g && vol->g[i] != vol->g[0]) p->g_varies = 1;
    if (vol->g && vol->g[i] != 0.0f) p->g_set = 1;
  }
}

static void scan_chunk(void *arg, size_t k, size_t a, size_t b) {
  ms_scan_ctx_t *x = arg;
  scan_voxels(x->vol, a, b, &x->part[k]);
}

static void scan_volume(const volume_t *vol, ms_scan_t *out) {
  ms_scan_ctx_t x;
  memset(&x, 0, sizeof x);
  memset(out, 0, sizeof *out);
  x.vol = vol;
  bk_parallel_chunks(grid_count(&vol->dims), MS_SCAN_CHUNKS, scan_chunk, &x);
  for (int k = 0; k < MS_SCAN_CHUNKS; k++) {
    const ms_scan_t *p = &x.part[k];
    out->ss += p->ss, out->st += p->st, out->st_scattering += p->st_scattering;
    out->scattering += p->scattering;
    out->sigma_varies |= p->sigma_varies, out->colour |= p->colour;
    out->g_varies |= p->g_varies, out->g_set |= p->g_set;
  }
}

/* The rule's r from the scan. */
static double order_ratio(const volume_t *vol, const ms_scan_t *m) {
  const grid_dims_t *d = &vol->dims;
  if (!(m->ss > 0.0) || !(m->st > 0.0)) return 0.0;
  double h = d->voxel_size, lx = d->nx * h, ly = d->ny * h, lz = d->nz * h;
  double chord = 4.0 * lx * ly * lz / (2.0 * (lx * ly + ly * lz + lz * lx));
  double tau = m->st_scattering / (3.0 * (double)m->scattering) * chord;
  return m->ss / m->st * (1.0 - exp(-tau));
}

double ms_order_ratio(const volume_t *vol) {
  ms_scan_t m;
  scan_volume(vol, &m);
  return order_ratio(vol, &m);
}

int ms_auto_bounces(double r) {
  if (!(r >= MS_AUTO_THIN)) return 0;
  if (r >= 1.0) return MS_AUTO_MAX;
  double n = ceil(log(MS_AUTO_REMAINDER) / log(r) - 1.0);
  if (n < 1.0) n = 1.0;
  return n > MS_AUTO_MAX ? MS_AUTO_MAX : (int)n;
}

void ms_decide(const scene_t *scene, const volume_t *vol, ms_setup_t *ms, int *grey_scatter) {
  memset(ms, 0, sizeof *ms);
  ms_scan_t m;
  scan_volume(vol, &m);
  ms->ratio = order_ratio(vol, &m);
  ms->auto_chosen = scene->bounces == SCENE_BOUNCES_AUTO;
  int n = ms->auto_chosen ? ms_auto_bounces(ms->ratio) : scene->bounces;
  /* no scattering anywhere: nothing to bounce */
  ms->params.max_bounces = ms->ratio > 0.0 ? (bk_uint)n : 0u;
  ms->sigma_grid = m.sigma_varies;
  *grey_scatter = !m.colour;
  ms->g_grid = m.g_varies;
  ms->hg = scene->medium_g != 0.0f || m.g_set;
}

typedef struct scat_ctx {
  const volume_t *vol;
  ms_setup_t *ms;
  int channels;
  double h;
} scat_ctx_t;

/* The scatter grid of voxels [lo, hi): σs per voxel length, then g. */
static void scat_range(void *arg, size_t lo, size_t hi) {
  const scat_ctx_t *x = arg;
  const volume_t *vol = x->vol;
  for (size_t i = lo; i < hi; i++) {
    float *o = x->ms->scat + x->ms->stride * i;
    for (int c = 0; c < x->channels; c++)
      o[c] = (float)(vol->sigma_s[vox_sigma_index(vol, i, c)] * x->h);
    if (x->ms->g_grid) o[x->channels] = vol->g[i];
  }
}

int ms_build(const scene_t *scene, const volume_t *vol, int channels, ms_setup_t *ms,
             bk_error_t *err) {
  ms_params *M = &ms->params;
  const double h = vol->dims.voxel_size;
  const size_t count = grid_count(&vol->dims);
  M->seed = scene->seed;
  M->g = vol->g ? vol->g[0] : scene->medium_g;
  M->grid = (bk_uint)ms->sigma_grid;
  M->g_grid = (bk_uint)ms->g_grid;
  /* one channel carries the sum of RGB, and σs is grey: any channel's */
  for (int c = 0; c < 3; c++) M->sigma_s[c] = (float)(vol->sigma_s[vox_sigma_index(vol, 0, c)] * h);
  ms->stride = channels + (ms->g_grid ? 1 : 0);
  if (!ms->sigma_grid && !ms->g_grid) return BK_OK;
  ms->scat = bk_calloc(count, ms->stride * sizeof(float), "march: scatter grid", err);
  if (!ms->scat) return BK_ERR_RUNTIME;
  scat_ctx_t x = {vol, ms, channels, h};
  bk_parallel(count, BK_GRAIN, scat_range, &x);
  return BK_OK;
}

void ms_free(ms_setup_t *ms) {
  if (!ms) return;
  free(ms->scat);
  ms->scat = NULL;
}

void ms_kernel_defines(const ms_setup_t *ms, char *buf, size_t len) {
  if (!ms->params.max_bounces) {
    if (len) buf[0] = '\0';
    return;
  }
  snprintf(buf, len, "-DMULTIPLE_SCATTERING=1 -DMS_SIGMA_GRID=%d -DMS_G_GRID=%d -DMS_HG=%d",
           ms->sigma_grid, ms->g_grid, ms->hg);
}
