/* bounces.c: multiple scattering's host side (see bounces.h). */
#include "bounces.h"

#include "base/parallel.h"
#include "vox_medium.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The rule's r from the scan. */
static double order_ratio(const volume_t *vol, const vox_scan_t *m) {
  const grid_dims_t *d = &vol->dims;
  if (!(m->ss > 0.0) || !(m->st > 0.0)) return 0.0;
  double h = d->voxel_size, lx = d->nx * h, ly = d->ny * h, lz = d->nz * h;
  double chord = 4.0 * lx * ly * lz / (2.0 * (lx * ly + ly * lz + lz * lx));
  double tau = m->st_scattering / (3.0 * (double)m->scattering) * chord;
  return m->ss / m->st * (1.0 - exp(-tau));
}

double ms_order_ratio(const volume_t *vol) {
  vox_scan_t own;
  return order_ratio(vol, vox_scan_of(vol, &own));
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
  vox_scan_t own;
  const vox_scan_t *m = vox_scan_of(vol, &own);
  ms->ratio = order_ratio(vol, m);
  ms->auto_chosen = scene->bounces == SCENE_BOUNCES_AUTO;
  int n = ms->auto_chosen ? ms_auto_bounces(ms->ratio) : scene->bounces;
  /* no scattering anywhere: nothing to bounce */
  ms->params.max_bounces = ms->ratio > 0.0 ? (bk_uint)n : 0u;
  ms->sigma_grid = m->s_varies;
  *grey_scatter = !m->s_coloured;
  ms->g_grid = m->g_varies;
  ms->hg = scene->medium_g != 0.0f || m->g_set;
}

void ms_build(const scene_t *scene, const volume_t *vol, ms_setup_t *ms) {
  ms_params *M = &ms->params;
  const double h = vol->dims.voxel_size;
  M->seed = scene->seed;
  M->g = vol->g ? vol->g[0] : scene->medium_g;
  M->grid = (bk_uint)ms->sigma_grid;
  M->g_grid = (bk_uint)ms->g_grid;
  /* one channel carries the sum of RGB, and σs is grey: any channel's */
  for (int c = 0; c < 3; c++) M->sigma_s[c] = (float)(vol_sigma_s(vol, 0, c) * h);
}

void ms_kernel_defines(const ms_setup_t *ms, char *buf, size_t len) {
  if (!ms->params.max_bounces) {
    if (len) buf[0] = '\0';
    return;
  }
  snprintf(buf, len, "-DMULTIPLE_SCATTERING=1 -DMS_SIGMA_GRID=%d -DMS_G_GRID=%d -DMS_HG=%d",
           ms->sigma_grid, ms->g_grid, ms->hg);
}
