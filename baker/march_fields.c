/* march_fields.c: the march's per-volume fields (march.h: pm_fields_scan,
 * pm_fields_build), built, or taken from the frame before when its volume
 * had the same key (baker/frame_reuse.h). */
#include <stdlib.h>
#include <string.h>

#include "base/common.h"
#include "base/parallel.h"
#include "field.h"
#include "march.h"
#include "vox_medium.h"

/* What the march specialises on: n varies (or differs between channels:
 * dispersion), σt the same everywhere, σt grey. The volume's own scan when
 * it has one (vox_summarise), else one made here. */
static void scan_volume(const volume_t *vol, int *has_refraction, int *homogeneous, int *grey) {
  vox_scan_t own;
  const vox_scan_t *f = vox_scan_of(vol, &own);
  *has_refraction = vol->ior_rb != NULL || f->n_max > f->n_min;
  *homogeneous = !f->t_varies;
  *grey = !f->t_coloured;
}

/* The cache holds this volume's scan (its fields, channels > 0, may still
 * differ in channels or be absent). */
static int holds_volume(const pm_field_cache_t *c, const volume_t *vol) {
  return c && vol->key != 0 && c->key == vol->key;
}

static void free_fields(pm_field_cache_t *c) {
  free(c->ng);
  oct_free(&c->pyramid);
  c->ng = NULL;
  c->channels = 0;
}

/* The scan as found, before pm_prepare narrows grey for the scattering. */
void pm_fields_scan(const volume_t *vol, pm_field_cache_t *kept, int frame, pm_setup_t *s) {
  if (holds_volume(kept, vol)) {
    s->has_refraction = kept->has_refraction;
    s->homogeneous = kept->homogeneous;
    s->grey = kept->grey;
    return;
  }
  pm_field_cache_free(kept); /* another volume: its fields go before new ones are built */
  double t0 = bk_now_ms();
  scan_volume(vol, &s->has_refraction, &s->homogeneous, &s->grey);
  bk_log(2, "octree: volume scan %.0f ms", bk_now_ms() - t0);
  if (!kept || vol->key == 0) return;
  kept->key = vol->key;
  kept->frame = frame;
  kept->has_refraction = s->has_refraction;
  kept->homogeneous = s->homogeneous;
  kept->grey = s->grey;
}

void pm_field_cache_free(pm_field_cache_t *c) {
  if (!c) return;
  free_fields(c);
  memset(c, 0, sizeof *c);
}

void pm_fields_decide(const scene_t *scene, const volume_t *vol, pm_field_cache_t *kept,
                      ms_setup_t *ms, int *grey_scatter) {
  const int holds = holds_volume(kept, vol);
  if (holds && kept->decided && kept->bounces == scene->bounces) {
    *ms = kept->ms;
    *grey_scatter = kept->grey_scatter;
    return;
  }
  ms_decide(scene, vol, ms, grey_scatter);
  if (!holds) return;
  kept->decided = 1;
  kept->bounces = scene->bounces;
  kept->ms = *ms;
  kept->grey_scatter = *grey_scatter;
}

/* The pyramid and the {∇n, n} field, only where n varies (σ is read from
 * the volume). */
static int build_fields(const volume_t *vol, pm_setup_t *s, bk_error_t *err) {
  const grid_dims_t *d = &s->dims;
  const double h = d->voxel_size;
  if (s->has_refraction) {
    double t0 = bk_now_ms();
    /* dispersion: constant where every channel's n is, a field per channel */
    const size_t count = s->voxels;
    const oct_source_t rgb[3] = {{vol->ior_rb, 1, 1, 0}, {vol->ior, 1, 1, 0},
                                 {vol->ior_rb ? vol->ior_rb + count : NULL, 1, 1, 0}};
    const oct_source_t *src = vol->ior_rb ? rgb : rgb + 1; /* R, G, B or n alone */
    const int nsrc = vol->ior_rb ? 3 : 1;
    int rc = oct_build_fields(d->nx, d->ny, d->nz, src, nsrc, OCT_HALO, &s->pyramid, err);
    double tc = bk_now_ms();
    if (rc == BK_OK) rc = oct_add_cells(d->nx, d->ny, d->nz, src, nsrc, &s->pyramid, err);
    if (rc != BK_OK) return rc;
    double t1 = bk_now_ms();
    s->ng = vol->ior_rb ? fld_build_rgb(d->nx, d->ny, d->nz, h, vol->ior, vol->ior_rb, err)
                        : fld_build(d->nx, d->ny, d->nz, h, vol->ior, err);
    if (!s->ng) return BK_ERR_RUNTIME;
    bk_log(2, "octree: pyramid %.0f ms (constant cells %.0f), {grad n, n} field %.0f ms (%.1f MiB sparse)",
           t1 - t0, t1 - tc, bk_now_ms() - t1,
           (double)fld_floats(d->nx, d->ny, d->nz, s->ng, vol->ior_rb ? 3 : 1) * 4.0 / 1048576.0);
  }
  return BK_OK;
}

int pm_fields_build(const volume_t *vol, pm_field_cache_t *kept, pm_setup_t *s,
                    bk_error_t *err) {
  const int holds = holds_volume(kept, vol);
  if (holds && kept->channels == s->channels) {
    s->ng = kept->ng;
    s->pyramid = kept->pyramid;
    s->fields_kept = 2;
    s->fields_frame = kept->frame;
    s->octree_enabled = s->has_refraction;
    return BK_OK;
  }
  if (holds) free_fields(kept); /* the channel count changed */
  int rc = build_fields(vol, s, err);
  s->octree_enabled = s->has_refraction;
  if (rc != BK_OK || !holds_volume(kept, vol)) return rc;
  kept->channels = s->channels;
  kept->ng = s->ng;
  kept->pyramid = s->pyramid;
  s->fields_kept = 1;
  s->fields_frame = kept->frame;
  return BK_OK;
}
