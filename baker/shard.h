/* shard.h: photon shards, `baker bake --shard I/N` and what `baker merge`
 * (merge_cmd.c) reads back.
 *
 * A shard traces the I-th of N contiguous, disjoint slices [first, last) of
 * the photon indices of every batch (reference mode, baker/batches.h: share
 * I of each batch's photons, pm_share_range; the march keeps every index's
 * place among the batch's photons, pm_set_range; adaptive mode: of the
 * weighted march's photons; the metadata's range is shard_range of
 * photons.count), and writes its raw 64-bit
 * fixed-point sums instead of radiance. The sums of all N shards added as
 * integers are the single bake's sums bit for bit (integer addition does not
 * care about order), so the merge's radiance equals the single bake's.
 * Adaptive mode: every shard runs the pilot and the PDF itself (they are
 * deterministic: the same tables in every shard) and shards only the
 * weighted march; the merge applies the unpacking and the filter
 * (ad_finish).
 *
 * The shard file: the medium grids as a bake writes them (ior, extinction,
 * scattering, density; never half floats), and per counter slot s of the
 * march's accumulator a Vec3f grid `shard_sum_S` holding the 64-bit sum as
 * three floats of 22, 22 and 20 bits (whole numbers below 2^22: exact in a
 * float, never -0 or NaN, so the writer's sparse grids and checksums keep
 * them bit for bit). Its metadata (shard_meta; the keys are listed in
 * README.md, "One frame on many machines") records the shard, the photon
 * range, a key that hashes the scene and the settings that change the
 * result, and the scales that turn sums into radiance. */
#ifndef BAKER_SHARD_H
#define BAKER_SHARD_H

#include <stdint.h>

#include "adaptive.h"
#include "bake.h"
#include "march.h"

#define SHARD_META_MAX 20 /* entries shard_meta adds, at most */
#define SHARD_MAX_STRIDE 4 /* counters per voxel: 3 channels + packed count/weight */
/* and the flux's (shard_flux_A), the camera's last */
#define SHARD_MAX_SLOTS (SHARD_MAX_STRIDE + PM_FLUX_SLOTS_WITH(1))
#define SHARD_MAX_COUNT 100000

/* One counter per voxel of the sums, as the write's fill reads it. */
typedef struct shard_slot {
  const uint64_t *acc; /* voxel v's counter at acc[stride * v + slot] */
  int stride, slot;
} shard_slot_t;

/* One shard's state between the march and the write. */
typedef struct shard_state {
  pm_sums_t sums;
  uint64_t first, last, photons; /* the range of photons.count traced */
  shard_slot_t slots[SHARD_MAX_SLOTS]; /* shard_sum_S, then shard_flux_A */
  char key[24], scales[160], names[SHARD_MAX_SLOTS][16], filter[160], ior_bg[40], grid[160];
  char camera[40], camera_at[96]; /* shard_sum_camera, radiance_camera_position */
  float alpha;                   /* adaptive.alpha, for the merge's filter */
} shard_state_t;

/* "I/N" -> index and count (1 <= I <= N <= SHARD_MAX_COUNT). */
int shard_parse(const char *text, int *index, int *count, bk_error_t *err);
/* Photons [*first, *last) of `photons` for shard index (1-based) of count:
 * floor(photons (index-1) / count) .. floor(photons index / count). */
void shard_range(uint64_t photons, int index, int count, uint64_t *first, uint64_t *last);
/* The shard's key: FNV-1a of the bake settings without the shard part. */
void shard_key(const bake_options_t *opt, const scene_t *s, char out[24]);

/* The march of the shard opt asks for (reference or adaptive), its sums
 * into sh. */
int shard_march(clh_context_t *cl, const scene_t *scene, const volume_t *vol,
                const bake_options_t *opt, shard_state_t *sh, pm_stats_t *stats,
                ad_stats_t *astats, bk_timings_t *timings, bk_error_t *err);
/* Appends the shard_sum_S grids to grids (*count of max in use), made from
 * the sums by a fill as the write needs them. */
int shard_grids(shard_state_t *sh, const grid_dims_t *dims, vdbio_grid_t *grids, int *count,
                int max, bk_error_t *err);
/* Writes the shard's metadata entries at meta (room for SHARD_META_MAX);
 * returns how many. Strings point into sh. */
int shard_meta(shard_state_t *sh, const bake_options_t *opt, const scene_t *s,
               const grid_dims_t *dims, vdbio_meta_t *meta);
void shard_free(shard_state_t *sh);

/* Splitting and joining a 64-bit sum (3 floats per value): slot `slot` of
 * each voxel's `stride` counters. shard_decode_add returns 0 (having added
 * part) when a value is not a whole number of its field's width. */
void shard_encode(const uint64_t *acc, size_t voxels, int stride, int slot, float *out);
int shard_decode_add(const float *in, size_t voxels, int stride, int slot, uint64_t *acc);

#endif
