/* shard.c: `baker bake --shard I/N`: the photon range of a shard, its march,
 * and its raw sums and metadata in the output file (see shard.h). */
#include "shard.h"

#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "base/common.h"
#include "base/grid.h"
#include "base/parallel.h"
#include "batches.h"
#include "cmdline.h"

int shard_parse(const char *text, int *index, int *count, bk_error_t *err) {
  const char *slash = text ? strchr(text, '/') : NULL;
  long long i = 0, n = 0;
  char head[32];
  if (slash && (size_t)(slash - text) < sizeof head) {
    memcpy(head, text, (size_t)(slash - text));
    head[slash - text] = 0;
    if (!cmd_parse_ll(head, &i) || !cmd_parse_ll(slash + 1, &n)) n = 0;
  }
  if (n < 1 || n > SHARD_MAX_COUNT || i < 1 || i > n)
    return bk_fail(err, BK_ERR_INPUT,
                   "--shard: expected I/N with 1 <= I <= N <= %d (shard I of N), got '%s'",
                   SHARD_MAX_COUNT, text ? text : "");
  *index = (int)i;
  *count = (int)n;
  return BK_OK;
}

void shard_range(uint64_t photons, int index, int count, uint64_t *first, uint64_t *last) {
  pm_share_range(photons, index, count, first, last);
}

void shard_key(const bake_options_t *opt, const scene_t *s, char out[24]) {
  bake_options_t whole = *opt;
  char settings[512];
  whole.shard_index = whole.shard_count = 0;
  bake_settings(&whole, s, settings, sizeof settings);
  snprintf(out, 24, "%016" PRIx64, bk_hash64(settings, strlen(settings), BK_HASH_SEED));
}

int shard_march(clh_context_t *cl, const scene_t *scene, const volume_t *vol,
                const bake_options_t *opt, shard_state_t *sh, pm_stats_t *stats,
                ad_stats_t *astats, bk_timings_t *timings, bk_error_t *err) {
  sh->photons = scene->photon_count > 0 ? (uint64_t)scene->photon_count : 0;
  shard_range(sh->photons, opt->shard_index, opt->shard_count, &sh->first, &sh->last);
  sh->alpha = scene->alpha;
  if (scene->mode != MODE_ADAPTIVE) { /* the same share of every batch (batches.h) */
    bt_options_t bo = {0};
    bo.shard_index = opt->shard_index, bo.shard_count = opt->shard_count, bo.sums = &sh->sums;
    bt_result_t res;
    return bt_bake(cl, scene, vol, &bo, NULL, &res, stats, timings, err);
  }
  if (scene->retable)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: --shard: adaptive.tables \"measured\" rebuilds the tables from every "
                   "batch's spread, which a shard does not see; use \"pilot\" to shard",
                   scene->path);
  ad_bake_opts_t ao;
  ad_bake_defaults(&ao);
  ao.filter = !opt->no_filter;
  ao.sums = &sh->sums;
  ao.shard_index = opt->shard_index;
  ao.shard_count = opt->shard_count;
  snprintf(sh->filter, sizeof sh->filter,
           "filter=%d max_radius=%a noise_k=%a alpha=%a radius_grid=%d",
           ao.filter, (double)ao.max_radius, (double)ao.noise_k, (double)scene->alpha,
           opt->write_filter_radius ? 1 : 0);
  int rc = ad_bake(cl, scene, vol, &ao, NULL, NULL, NULL, NULL, astats, timings, err);
  *stats = astats->march;
  return rc;
}

/* --- the sums as float grids ----------------------------------------------- */

#define SHARD_BITS 22 /* per float: whole numbers below 2^22 are exact */

void shard_encode(const uint64_t *acc, size_t voxels, int stride, int slot, float *out) {
  const uint64_t m = (1ull << SHARD_BITS) - 1ull;
  for (size_t v = 0; v < voxels; v++) {
    uint64_t q = acc[(size_t)stride * v + (size_t)slot];
    out[3 * v] = (float)(q & m);
    out[3 * v + 1] = (float)((q >> SHARD_BITS) & m);
    out[3 * v + 2] = (float)(q >> (2 * SHARD_BITS));
  }
}

/* A vdbio fill: voxels [lo, hi) of one slot, encoded as the write needs
 * them (made where each part of the file is made, never whole). */
static void shard_fill(const void *ctx, size_t lo, size_t hi, float *out) {
  const shard_slot_t *s = ctx;
  shard_encode(s->acc + (size_t)s->stride * lo, hi - lo, s->stride, s->slot, out);
}

int shard_decode_add(const float *in, size_t voxels, int stride, int slot, uint64_t *acc) {
  const float lim[3] = {0x1p22f, 0x1p22f, 0x1p20f}; /* 22, 22 and 20 bits */
  for (size_t v = 0; v < voxels; v++) {
    uint64_t q = 0;
    for (int p = 2; p >= 0; p--) {
      float f = in[3 * v + p];
      if (!(f >= 0.0f && f < lim[p]) || f != (float)(uint32_t)f) return 0;
      q = q << SHARD_BITS | (uint64_t)(uint32_t)f;
    }
    acc[(size_t)stride * v + (size_t)slot] += q;
  }
  return 1;
}

int shard_grids(shard_state_t *sh, const grid_dims_t *dims, vdbio_grid_t *grids, int *count,
                int max, bk_error_t *err) {
  const pm_sums_t *k = &sh->sums;
  const int fslots = PM_FLUX_SLOTS_WITH(k->camera), slots = k->stride + (k->flux ? fslots : 0);
  if (k->stride < 1 || k->stride > SHARD_MAX_STRIDE || *count + slots > max)
    return bk_fail(err, BK_ERR_RUNTIME, "shard: %d counters per voxel do not fit the file",
                   slots);
  size_t n = grid_count(dims);
  for (int s = 0; s < slots; s++) {
    const int f = s - k->stride; /* >= 0: a flux counter, after the voxels' */
    sh->slots[s] = f < 0 ? (shard_slot_t){k->acc, k->stride, s}
                         : (shard_slot_t){k->acc + n * (size_t)k->stride, fslots, f};
    snprintf(sh->names[s], sizeof sh->names[s], f < 0 ? "shard_sum_%d" : "shard_flux_%d",
             f < 0 ? s : f);
    grids[(*count)++] =
        (vdbio_grid_t){sh->names[s], VDBIO_VEC3, NULL, 0, 0.0f, shard_fill, &sh->slots[s], 0};
  }
  return BK_OK;
}

int shard_meta(shard_state_t *sh, const bake_options_t *opt, const scene_t *s,
               const grid_dims_t *dims, vdbio_meta_t *meta) {
  const pm_sums_t *k = &sh->sums;
  int m = 0;
  shard_key(opt, s, sh->key);
  snprintf(sh->scales, sizeof sh->scales, "%a %a %a %u %a", k->to_radiance[0], k->to_radiance[1],
           k->to_radiance[2], k->count_shift, (double)k->weight_scale);
  meta[m++] = (vdbio_meta_t){"shard_index", VDBIO_META_INT, NULL, opt->shard_index, 0};
  meta[m++] = (vdbio_meta_t){"shard_count", VDBIO_META_INT, NULL, opt->shard_count, 0};
  meta[m++] = (vdbio_meta_t){"shard_photon_first", VDBIO_META_INT, NULL, (long long)sh->first, 0};
  meta[m++] = (vdbio_meta_t){"shard_photon_last", VDBIO_META_INT, NULL, (long long)sh->last, 0};
  meta[m++] = (vdbio_meta_t){"shard_photons", VDBIO_META_INT, NULL, (long long)sh->photons, 0};
  meta[m++] = (vdbio_meta_t){"shard_key", VDBIO_META_STRING, sh->key, 0, 0};
  /* the photons a slot range holds depend on the launch order */
  meta[m++] = (vdbio_meta_t){"shard_photon_order", VDBIO_META_INT, NULL, PH_LAUNCH_ORDER, 0};
  meta[m++] = (vdbio_meta_t){"shard_sum_stride", VDBIO_META_INT, NULL, k->stride, 0};
  meta[m++] = (vdbio_meta_t){"shard_sum_channels", VDBIO_META_INT, NULL, k->channels, 0};
  meta[m++] = (vdbio_meta_t){"shard_sum_mode", VDBIO_META_INT, NULL, k->mode, 0};
  if (k->flux) meta[m++] = (vdbio_meta_t){"shard_sum_flux", VDBIO_META_INT, NULL, 1, 0};
  if (k->flux && k->camera) { /* its scale, and the point the merged file names */
    snprintf(sh->camera, sizeof sh->camera, "%a", (double)k->cam_scale);
    meta[m++] = (vdbio_meta_t){"shard_sum_camera", VDBIO_META_STRING, sh->camera, 0, 0};
    bake_camera_meta(s->camera.position, sh->camera_at, sizeof sh->camera_at, &meta[m++]);
  }
  meta[m++] = (vdbio_meta_t){"shard_sum_scales", VDBIO_META_STRING, sh->scales, 0, 0};
  snprintf(sh->ior_bg, sizeof sh->ior_bg, "%a", (double)s->medium_ior);
  snprintf(sh->grid, sizeof sh->grid, "%d %d %d %a %a %a %a", dims->nx, dims->ny, dims->nz,
           (double)dims->voxel_size, (double)dims->origin[0], (double)dims->origin[1],
           (double)dims->origin[2]);
  meta[m++] = (vdbio_meta_t){"shard_grid", VDBIO_META_STRING, sh->grid, 0, 0};
  meta[m++] = (vdbio_meta_t){"shard_ior_background", VDBIO_META_STRING, sh->ior_bg, 0, 0};
  if (sh->filter[0])
    meta[m++] = (vdbio_meta_t){"shard_filter", VDBIO_META_STRING, sh->filter, 0, 0};
  return m;
}

void shard_free(shard_state_t *sh) {
  pm_sums_free(&sh->sums);
}
