/* bounces.c: multiple scattering's host side (see bounces.h). */
#include "bounces.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

double ms_order_ratio(const volume_t *vol) {
  const grid_dims_t *d = &vol->dims;
  const size_t count = grid_count(d);
  double ss = 0.0, st = 0.0, st_scattering = 0.0;
  size_t scattering = 0;
  for (size_t i = 0; i < count; i++) {
    double s = 0.0, t = 0.0;
    for (int c = 0; c < 3; c++) {
      const size_t at = vox_sigma_index(vol, i, c);
      s += vol->sigma_s[at];
      t += vol->sigma_s[at] + vol->sigma_a[at];
    }
    ss += s;
    st += t;
    if (s > 0.0) {
      st_scattering += t;
      scattering++;
    }
  }
  if (!(ss > 0.0) || !(st > 0.0)) return 0.0;
  double h = d->voxel_size, lx = d->nx * h, ly = d->ny * h, lz = d->nz * h;
  double chord = 4.0 * lx * ly * lz / (2.0 * (lx * ly + ly * lz + lz * lx));
  double tau = st_scattering / (3.0 * (double)scattering) * chord;
  return ss / st * (1.0 - exp(-tau));
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
  const size_t count = grid_count(&vol->dims);
  ms->ratio = ms_order_ratio(vol);
  ms->auto_chosen = scene->bounces == SCENE_BOUNCES_AUTO;
  int n = ms->auto_chosen ? ms_auto_bounces(ms->ratio) : scene->bounces;
  /* no scattering anywhere: nothing to bounce */
  ms->params.max_bounces = ms->ratio > 0.0 ? (bk_uint)n : 0u;
  const float *sg = vol->sigma_s;
  *grey_scatter = 1;
  for (size_t i = 0; i < count; i++) {
    float s[3], s0[3];
    for (int c = 0; c < 3; c++) {
      s[c] = sg[vox_sigma_index(vol, i, c)];
      s0[c] = sg[vox_sigma_index(vol, 0, c)];
    }
    if (s[0] != s0[0] || s[1] != s0[1] || s[2] != s0[2]) ms->sigma_grid = 1;
    if (s[0] != s[1] || s[0] != s[2]) *grey_scatter = 0;
  }
  ms->g_grid = 0;
  ms->hg = scene->medium_g != 0.0f;
  if (vol->g)
    for (size_t i = 0; i < count; i++) {
      if (vol->g[i] != vol->g[0]) ms->g_grid = 1;
      if (vol->g[i] != 0.0f) ms->hg = 1;
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
  for (size_t i = 0; i < count; i++) {
    float *o = ms->scat + ms->stride * i;
    for (int c = 0; c < channels; c++) o[c] = (float)(vol->sigma_s[vox_sigma_index(vol, i, c)] * h);
    if (ms->g_grid) o[channels] = vol->g[i];
  }
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
