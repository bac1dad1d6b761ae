/* march.c: photon marching on OpenCL or on the host (see march.h). */
#define _DEFAULT_SOURCE /* M_PI from math.h */
#include "march.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "field.h"
#include "integrators.h"
#include "kernels/scatter_march.h"

double pm_fixed_scale(double power_max, double path_bound) {
  if (!(power_max > 0.0) || !(path_bound > 0.0)) return 1.0;
  double s = ldexp(1.0, 62) / (power_max * path_bound);
  /* the deposit is computed in float: keep S and Φ·ℓ·S finite */
  return s < 1e30 ? s : 1e30;
}

bk_grid pm_kernel_grid(const grid_dims_t *d) {
  bk_grid g;
  g.nx = d->nx, g.ny = d->ny, g.nz = d->nz, g.pad0 = 0;
  g.origin_x = (float)d->origin[0], g.origin_y = (float)d->origin[1], g.origin_z = (float)d->origin[2];
  g.voxel_size = (float)d->voxel_size;
  return g;
}

/* The fixed-point scale and the conversion to radiance for the setup's
 * lights, when no photon carries more than w_max times its light's power per
 * photon (the weighted march, march.h): the bound of march.h's scale rule
 * grows by w_max. */
static void set_scale(pm_setup_t *s, double w_max) {
  pm_params *P = &s->params;
  const grid_dims_t *d = &s->dims;
  const double h = d->voxel_size;
  double diag = sqrt((double)d->nx * d->nx + (double)d->ny * d->ny + (double)d->nz * d->nz);
  double pmax = 0.0;
  if (P->dispersion) w_max *= 3.0; /* a photon carries 3x its channel's power (pm_disperse) */
  if (s->channels == 1) pmax = s->lights.power[0] + s->lights.power[1] + s->lights.power[2];
  else
    for (int c = 0; c < 3; c++) pmax = s->lights.power[c] > pmax ? s->lights.power[c] : pmax;
  /* multiple scattering: the path cap bounds a chain's physical path, and a
   * leg's deposit is Φ0 times its expected path (scatter.h), not its
   * marched length: the bound holds for the mean, so 4x headroom on it */
  double bound = (P->path_cap + diag) * (s->ms.params.max_bounces ? 4.0 : 1.0);
  P->fixed_scale = (float)pm_fixed_scale(pmax * w_max, bound);
  P->photon_total = (bk_uint)s->lights.photons;
  P->light_count = (bk_uint)s->lights.count;
  /* quanta -> W·voxel -> W·m / (4π V) */
  for (int c = 0; c < 3; c++)
    s->to_radiance[c] = (s->channels == 1 ? s->lights.chroma[c] : 1.0) /
                        ((double)P->fixed_scale * 4.0 * M_PI * h * h);
}

void pm_scale_batches(pm_setup_t *s, double batch_cap) { set_scale(s, batch_cap); }

static int check_inputs(const scene_t *scene, const grid_dims_t *d, size_t voxels, bk_error_t *err) {
  if (voxels == 0 || !(d->voxel_size > 0.0))
    return bk_fail(err, BK_ERR_INPUT, "%s: march: empty grid %dx%dx%d", scene->path, d->nx, d->ny,
                   d->nz);
  if (!(scene->step > 0.0f) || !isfinite(scene->step))
    return bk_fail(err, BK_ERR_INPUT, "%s: photons.step: expected a positive number of voxels, got %g",
                   scene->path, (double)scene->step);
  if (scene->photon_count < 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: photons.count: expected a count >= 0, got %lld",
                   scene->path, scene->photon_count);
  return BK_OK;
}

/* The volume's σ as the kernels read it: plain arrays, or the code. */
static void set_sigma(const volume_t *vol, pm_setup_t *s) {
  const size_t C = vol->sigma_channels == 1 ? 1 : 3;
  if (vol->sigma_code) {
    s->sigma_t = s->sigma_s = vol->sigma_code;
    s->sigma_floats = vol->sigma_code_floats;
    s->params.sigma_stride |= PM_SIGMA_CODED_FLAG;
  } else {
    s->sigma_t = vol->sigma_t, s->sigma_s = vol->sigma_s;
    s->sigma_floats = vol->homogeneous ? C : C * grid_count(&vol->dims);
  }
}

/* PM_CAMERA (kernels/march_deposit.h): the flux is kept (some g != 0), the
 * scene has a camera, and one g holds everywhere or photons scatter (the
 * march of multiple scattering reads g per voxel; single scattering's does
 * not, and its lobes are exact for one light). */
static int wants_camera(const scene_t *scene, const ms_setup_t *ms) {
  return ms->hg && scene->camera.present && scene->camera.bake_phase &&
         (!ms->g_grid || ms->params.max_bounces > 0);
}

/* The camera in voxel coordinates, its g and the phase's scale 1/P_max. */
static void set_camera(const scene_t *scene, const volume_t *vol, pm_setup_t *s) {
  pm_params *P = &s->params;
  const grid_dims_t *d = &s->dims;
  if (!wants_camera(scene, &s->ms)) return;
  for (int a = 0; a < 3; a++)
    P->cam[a] = (float)(((double)scene->camera.position[a] - d->origin[a]) / d->voxel_size);
  const double g = vol->g ? vol->g[0] : scene->medium_g;
  double ag = fabs(g);
  P->cam_g = (float)g;
  P->cam_g_grid = (bk_uint)s->ms.g_grid;
  for (size_t i = 0; P->cam_g_grid && i < s->voxels; i++) ag = fmax(ag, fabs((double)vol->g[i]));
  P->cam_scale = (float)((1.0 - ag) * (1.0 - ag) / (1.0 + ag));
  P->camera = 1;
}

/* The march's parameters (kernels/photon_march.h) in reference mode. */
static int set_params(const scene_t *scene, const volume_t *vol, pm_setup_t *s, bk_error_t *err) {
  const grid_dims_t *d = &s->dims;
  const double h = d->voxel_size;
  pm_params *P = &s->params;
  memset(P, 0, sizeof *P);
  P->grid = pm_kernel_grid(d);
  if (s->homogeneous)
    for (int c = 0; c < 3; c++) P->sigma_t[c] = (float)(vol_sigma_t(vol, 0, c) * h);
  for (int c = 0; c < 3; c++)
    if (!(P->sigma_t[c] >= 0.0f))
      return bk_fail(err, BK_ERR_INPUT, "%s: medium: extinction must be >= 0, got %g per unit",
                     scene->path, (double)P->sigma_t[c] / h);
  double diag = sqrt((double)d->nx * d->nx + (double)d->ny * d->ny + (double)d->nz * d->nz);
  P->step = scene->step;
  P->path_cap = (float)(PM_MAX_PATH_DIAGONALS * diag);
  P->absorb_fraction = PM_ABSORB_FRACTION;
  P->channels = (bk_uint)s->channels;
  P->has_refraction = (bk_uint)s->has_refraction;
  P->homogeneous = (bk_uint)s->homogeneous;
  P->integrator = integrator_kind(scene->integrator)->device;
  P->dispersion = vol->ior_rb != NULL;
  P->mode = PM_MODE_REFERENCE;
  P->flux = (bk_uint)s->ms.hg; /* the view's anisotropic phase needs the flux */
  set_camera(scene, vol, s);
  P->sigma_stride = vol->sigma_channels == 1 ? 1u : 3u;
  P->h = d->voxel_size;
  set_sigma(vol, s);
  s->g = vol->g;
  set_scale(s, 1.0);
  return BK_OK;
}

static void report_prepare(const pm_setup_t *s, bk_timings_t *timings, double ms_octree,
                           double ms_generate) {
  if (s->fields_kept == 2) {
    bk_timings_add(timings, "octree", ms_octree, "reused from frame %d (volume unchanged)",
                   s->fields_frame);
    bk_timings_mark_reused(timings, s->fields_frame);
  } else if (s->has_refraction) {
    const uint64_t *v = s->pyramid.voxels_at_level;
    double tot = (double)s->voxels;
    char note[96];
    int at = snprintf(note, sizeof note, "constant:");
    for (int l = OCT_LEVELS; l >= 1 && at < (int)sizeof note; l--)
      at += snprintf(note + at, sizeof note - at, " %.0f%% in %d^3", 100.0 * v[l] / tot,
                     2 << (2 * (l - 1)));
    bk_timings_add(timings, "octree", ms_octree, "%s, %.0f M voxels/s", note,
                   (double)s->voxels / (ms_octree * 1e3 + 1e-9));
  } else {
    bk_timings_add(timings, "octree", ms_octree, "n constant: one straight DDA per photon");
  }
  bk_timings_add(timings, "photon generation", ms_generate, "%d light(s), in-kernel Hammersley, %s",
                 s->lights.count, s->channels == 1 ? "1 channel (one colour)" : "RGB");
}

/* n changes across a band of ior_smoothing voxels around each surface; a
 * step longer than the band can land on both sides of it and never sample
 * the gradient, so refraction silently disappears (at 20+ voxels almost all
 * of it). Warned about, not refused or clamped: a coarse step is a
 * legitimate quick preview, and clamping would change a bake the user asked
 * for. */
static void warn_coarse_step(const scene_t *scene, int has_refraction) {
  if (!has_refraction || !(scene->step > scene->ior_smoothing)) return;
  bk_warn("%s: photons.step is %g voxels, longer than the refractive objects' smoothing band "
          "(grid.ior_smoothing = %g voxels): photons step over the surfaces and lose most of "
          "their refraction; use a step of at most %g voxels (0.5 is the default)",
          scene->path, (double)scene->step, (double)scene->ior_smoothing,
          (double)scene->ior_smoothing / 2.0);
}

int pm_prepare(const scene_t *scene, const volume_t *vol, pm_setup_t *s, bk_timings_t *timings,
               pm_stats_t *stats, bk_error_t *err) {
  return pm_prepare_kept(scene, vol, NULL, s, timings, stats, err);
}

int pm_prepare_kept(const scene_t *scene, const volume_t *vol, pm_field_cache_t *kept,
                    pm_setup_t *s, bk_timings_t *timings, pm_stats_t *stats, bk_error_t *err) {
  memset(s, 0, sizeof *s);
  s->dims = vol->dims;
  s->voxels = grid_count(&vol->dims);
  const grid_dims_t *d = &s->dims;
  int rc = check_inputs(scene, d, s->voxels, err);
  if (rc != BK_OK) return rc;

  /* what the volume allows the kernel to skip: part of the octree stage */
  double t0 = bk_now_ms();
  pm_fields_scan(vol, kept, scene->frame, s);
  int grey_scatter;
  pm_fields_decide(scene, vol, kept, &s->ms, &grey_scatter);
  /* one channel carries every colour only when the albedo is grey too */
  if (s->ms.params.max_bounces && !grey_scatter) s->grey = 0;
  warn_coarse_step(scene, s->has_refraction);
  double ms_scan = bk_now_ms() - t0;
  t0 = bk_now_ms();
  rc = ph_prepare(scene, d, (uint64_t)scene->photon_count, scene->seed, &s->lights, err);
  if (rc != BK_OK) return rc;
  s->channels = (s->grey && s->lights.one_colour && !vol->ior_rb) ? 1 : 3;
  if (s->channels == 1) ph_make_grey(&s->lights);
  s->seed = scene->seed;
  pm_set_range(s, 0, s->lights.photons);
  /* what the march holds per voxel beside the volume: the pyramid, the
   * counters (σ is read from the volume). The sparse {∇n, n} field is
   * not counted here: its worst case (FLD_WORST_BYTES_PER_VOXEL, every
   * brick stored) would refuse large mesh scenes whose field is well under
   * a byte per voxel; it is sized from the bricks it stores before they
   * are allocated (field.c), and the bake's budget counted the whole. */
  size_t per_voxel = (s->has_refraction ? 1 : 0) + s->channels * sizeof(uint64_t) +
                     3 * sizeof(float) +
                     (s->ms.hg ? PM_FLUX_SLOTS * (sizeof(uint64_t) + sizeof(float)) + 4 : 0) +
                     (wants_camera(scene, &s->ms) ? sizeof(uint64_t) + sizeof(float) : 0);
  rc = grid_check_memory(d, per_voxel, scene->path, err);
  if (rc != BK_OK) return rc;
  double ms_generate = bk_now_ms() - t0;

  t0 = bk_now_ms();
  if ((rc = pm_fields_build(vol, kept, s, err)) != BK_OK) goto error;
  double ms_octree = bk_now_ms() - t0 + ms_scan;
  t0 = bk_now_ms();
  if ((rc = set_params(scene, vol, s, err)) != BK_OK) goto error;
  if (s->ms.params.max_bounces) ms_build(scene, vol, &s->ms);
  ms_generate += bk_now_ms() - t0;
  if (timings) report_prepare(s, timings, ms_octree, ms_generate);
  if (stats) {
    stats->ms_octree = ms_octree;
    stats->ms_generate = ms_generate;
  }
  return BK_OK;
error:
  pm_setup_free(s);
  return rc;
}

void pm_setup_free_fields(pm_setup_t *s) {
  if (!s->fields_kept) { /* kept fields belong to their pm_field_cache_t */
    free(s->ng);
    oct_free(&s->pyramid);
  }
  s->ng = NULL;
}

void pm_setup_free(pm_setup_t *s) {
  if (!s) return;
  pm_setup_free_fields(s);
}

void pm_disable_octree(pm_setup_t *s) {
  if (s->pyramid.level)
    memset(s->pyramid.level, 0, oct_bytes(&s->pyramid));
  s->octree_enabled = 0;
}

int pm_derive(const pm_setup_t *base, const scene_t *scene, uint64_t photons, pm_setup_t *out,
              bk_error_t *err) {
  *out = *base;
  out->masks = NULL;
  out->cell_work = NULL;
  out->tables = NULL;
  out->params.mode = PM_MODE_REFERENCE;
  int rc = ph_prepare(scene, &base->dims, photons, base->seed, &out->lights, err);
  if (rc != BK_OK) return rc;
  if (out->channels == 1) ph_make_grey(&out->lights);
  pm_set_range(out, 0, out->lights.photons);
  set_scale(out, 1.0);
  return BK_OK;
}

/* photons * k / count without overflow (count < 2^17) */
static uint64_t share(uint64_t photons, uint64_t k, uint64_t count) {
  return photons / count * k + photons % count * k / count;
}

void pm_share_range(uint64_t photons, int index, int count, uint64_t *first, uint64_t *last) {
  *first = share(photons, (uint64_t)index - 1, (uint64_t)count);
  *last = share(photons, (uint64_t)index, (uint64_t)count);
}

void pm_set_range(pm_setup_t *s, uint64_t first, uint64_t last) {
  s->last = last < s->lights.photons ? last : s->lights.photons;
  s->first = first < s->last ? first : s->last;
}

void pm_record_origins(pm_setup_t *s, int coarse_shift, uint64_t *masks) {
  pm_params *P = &s->params;
  const int m = (1 << coarse_shift) - 1;
  P->mode = PM_MODE_ORIGINS;
  P->coarse_shift = coarse_shift;
  P->cnx = (s->dims.nx + m) >> coarse_shift;
  P->cny = (s->dims.ny + m) >> coarse_shift;
  P->cnz = (s->dims.nz + m) >> coarse_shift;
  s->masks = masks;
}

void pm_deposit_lattice(pm_setup_t *s) {
  pm_params *P = &s->params;
  P->lattice = 1;
  P->cnx = (s->dims.nx + 1) >> 1;
  P->cny = (s->dims.ny + 1) >> 1;
  P->cnz = (s->dims.nz + 1) >> 1;
  P->flux = P->camera = 0; /* no sums beside radiance's */
}

int pm_sample_tables(pm_setup_t *s, const float *tables, double w_max, uint64_t total,
                     bk_error_t *err) {
  pm_params *P = &s->params;
  if (total < s->lights.photons) total = s->lights.photons;
  /* count bits: the photons, with room for 4 passages per photon on average
   * (curved paths may re-enter a voxel); the weight sum takes the rest, with
   * the same room, in quanta of 2^-24 to 2^-8 */
  int count_bits = 2;
  while (count_bits < 64 && (total >> (count_bits - 2)) != 0) count_bits++;
  int shift = 64 - count_bits;
  /* quanta per unit weight: a power of 2 with N w_max of them below 2^shift */
  double room = ldexp(1.0, shift) / (4.0 * (double)(total ? total : 1) *
                                     (w_max > 1.0 ? w_max : 1.0) * 1.001);
  if (room < 256.0)
    return bk_fail(err, BK_ERR_INPUT,
                   "adaptive: %llu photons are too many for the per-voxel photon count and "
                   "weight sums (%d bits); use at most about 4e7 photons, or photons.mode "
                   "\"reference\"",
                   (unsigned long long)total, count_bits);
  P->mode = PM_MODE_TABLES;
  P->flux = 0; /* the adaptive pipeline makes no radiance_flux (yet) */
  P->count_shift = (bk_uint)shift;
  P->weight_scale = (float)ldexp(1.0, (int)floor(log2(room)) > 24 ? 24 : (int)floor(log2(room)));
  s->tables = tables;
  set_scale(s, w_max);
  return BK_OK;
}

size_t pm_acc_count(const pm_setup_t *s) {
  const pm_params *P = &s->params;
  if (P->mode == PM_MODE_ORIGINS) return (size_t)P->cnx * P->cny * P->cnz * (size_t)s->channels;
  if (P->lattice) return (size_t)P->cnx * P->cny * P->cnz * (size_t)s->channels;
  return s->voxels * pm_sum_slots((int)P->mode, s->channels, (int)P->flux, (int)P->camera);
}

size_t pm_sum_slots(int mode, int channels, int flux, int camera) {
  return (size_t)pm_acc_stride(mode, channels) + (flux ? PM_FLUX_SLOTS_WITH(camera) : 0);
}

size_t pm_mask_count(const pm_setup_t *s) {
  const pm_params *P = &s->params;
  if (P->mode != PM_MODE_ORIGINS) return 0;
  return (size_t)P->cnx * P->cny * P->cnz * (size_t)s->lights.count;
}

int pm_run_host(const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats, bk_error_t *err) {
  bk_progress_t prog;
  if (stats) stats->bounces = (int)s->ms.params.max_bounces;
  bk_progress_begin(&prog, "photon marching", s->last - s->first);
  for (uint64_t i = s->first; i < s->last; i++) {
    /* slot i traces the photon the devices' slot i traces, so a shard holds
     * the same photons whichever path bakes it */
    const bk_uint photon = ph_photon_of_slot(s->lights.lights, s->params.light_count, (bk_uint)i);
    pm_result r;
    if (s->ms.params.max_bounces) {
      ms_tally t;
      const ms_medium med = {s->sigma_s, s->g};
      pm_march_scattered(&s->params, &s->ms.params, s->lights.lights, s->ng, s->pyramid.level,
                         s->sigma_t, med, acc, s->masks, s->tables, photon, &r, &t, NULL);
      if (stats) pm_stats_add_tally(stats, &t);
    } else {
      pm_march_photon(&s->params, s->lights.lights, s->ng, s->pyramid.level, s->sigma_t, acc,
                      s->masks, s->tables, photon, &r, NULL);
    }
    if (stats) pm_stats_add(stats, &r);
    pm_count_cell_work(s, i, &r);
    if (((i - s->first) & 4095) == 4095) bk_progress_update(&prog, i - s->first + 1);
  }
  bk_progress_end(&prog);
  return BK_OK;
}

static int run_host_batches(const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
                            pm_batch_fn next, void *ctx, bk_error_t *err) {
  pm_setup_t run = *s;
  for (int done = 0;; done++) {
    int go = next(ctx, done, acc, &run, err);
    if (go <= 0) return go < 0 ? err->code : BK_OK;
    if (go == PM_BATCH_GO_ZERO) memset(acc, 0, pm_acc_count(s) * sizeof *acc);
    int rc = pm_run_host(&run, acc, stats, err);
    if (rc != BK_OK) return rc;
  }
}

int pm_run_batches(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
                   pm_batch_fn next, void *ctx, bk_error_t *err) {
  return cl ? pm_run_cl_batches(cl, s, acc, stats, next, ctx, err)
            : run_host_batches(s, acc, stats, next, ctx, err);
}

typedef struct pm_unpack_ctx {
  const pm_setup_t *s;
  const uint64_t *acc;
  float *radiance, *count, *mean_weight;
  int channels; /* of radiance */
} pm_unpack_ctx_t;

int pm_radiance_channels(const pm_setup_t *s) {
  const double *k = s->to_radiance;
  return s->channels == 1 && k[0] == k[1] && k[1] == k[2] ? 1 : 3;
}

static void to_radiance_range(void *arg, size_t lo, size_t hi) {
  const pm_unpack_ctx_t *u = arg;
  const int ch = u->s->channels, stride = pm_acc_stride((int)u->s->params.mode, ch);
  const int out = u->channels; /* 1: every channel the same value */
  const double *k = u->s->to_radiance;
  for (size_t i = lo; i < hi; i++)
    for (int c = 0; c < out; c++)
      u->radiance[out * i + c] = (float)((double)u->acc[stride * i + (ch == 1 ? 0 : c)] * k[c]);
}

void pm_to_radiance(const pm_setup_t *s, const uint64_t *acc, float *radiance, int channels) {
  pm_unpack_ctx_t u = {s, acc, radiance, NULL, NULL, channels};
  bk_parallel(s->voxels, BK_GRAIN, to_radiance_range, &u);
}

float *pm_to_radiance_in_place(const pm_setup_t *s, uint64_t *acc, int channels) {
  const size_t stride = (size_t)pm_acc_stride((int)s->params.mode, s->channels);
  const size_t out = (size_t)channels, block = (size_t)1 << 20; /* voxels per step */
  if (out * sizeof(float) > stride * sizeof(uint64_t)) return NULL;
  float *tmp = malloc(block * out * sizeof(float));
  if (!tmp) return NULL;
  /* a block's floats go where its counters began or earlier, never over
   * the counters of the blocks after it; made aside first, since they
   * overlap the block's own counters */
  for (size_t a = 0; a < s->voxels; a += block) {
    const size_t n = s->voxels - a < block ? s->voxels - a : block;
    pm_unpack_ctx_t u = {s, acc + stride * a, tmp, NULL, NULL, channels};
    bk_parallel(n, BK_GRAIN, to_radiance_range, &u);
    memcpy((char *)acc + out * sizeof(float) * a, tmp, n * out * sizeof(float));
  }
  free(tmp);
  float *radiance = realloc(acc, s->voxels * out * sizeof(float));
  return radiance ? radiance : (float *)acc; /* a failed shrink keeps the larger block */
}

static void unpack_weights_range(void *arg, size_t lo, size_t hi) {
  const pm_unpack_ctx_t *u = arg;
  const pm_setup_t *s = u->s;
  const int ch = s->channels, stride = pm_acc_stride((int)s->params.mode, ch);
  const unsigned shift = s->params.count_shift;
  const uint64_t low = (1ull << shift) - 1ull;
  const float inv_scale = 1.0f / s->params.weight_scale; /* a power of 2: exact */
  for (size_t i = lo; i < hi; i++) {
    uint64_t q = u->acc[stride * i + ch];
    float n = (float)(q >> shift);
    if (u->count) u->count[i] = n;
    if (u->mean_weight) u->mean_weight[i] = n > 0.0f ? (float)(q & low) * inv_scale / n : 0.0f;
  }
}

/* quanta of the flux counters -> W m^-2 sr^-1 of luminance: one channel is
 * coloured by to_radiance, three are weighted in the kernel (all three
 * to_radiance equal then), so either way Σ lum_c to_radiance[c] */
double pm_flux_scale(const pm_setup_t *s) {
  static const double lum[3] = {0.2126, 0.7152, 0.0722}; /* pm_flux_weight's */
  return lum[0] * s->to_radiance[0] + lum[1] * s->to_radiance[1] + lum[2] * s->to_radiance[2];
}

static void to_flux_range(void *arg, size_t lo, size_t hi) {
  const pm_unpack_ctx_t *u = arg;
  const int stride = pm_acc_stride((int)u->s->params.mode, u->s->channels);
  const uint64_t *f = u->acc + u->s->voxels * (size_t)stride;
  const double k = pm_flux_scale(u->s);
  const int camera = (int)u->s->params.camera, slots = PM_FLUX_SLOTS_WITH(camera);
  const double kc = camera ? k / (double)u->s->params.cam_scale : 0.0;
  float *cam = pm_radiance_camera(u->count, u->s->voxels);
  for (size_t i = lo; i < hi; i++) {
    const uint64_t *q = f + slots * i;
    if (camera) cam[i] = (float)((double)q[PM_CAMERA_SLOT] * kc);
    float *f0 = pm_flux_uncollided(u->count, u->s->voxels) + 3 * i;
    for (int a = 0; a < 3; a++) { /* F: the scattered light's sum + the uncollided one's */
      u->radiance[3 * i + a] = (float)((double)(int64_t)(q[a] + q[4 + a]) * k);
      f0[a] = (float)((double)(int64_t)q[4 + a] * k);
    }
    u->count[i] = (float)((double)q[3] * k);
  }
}

void pm_to_flux(const pm_setup_t *s, const uint64_t *acc, float *flux, float *uncollided) {
  pm_unpack_ctx_t u = {s, acc, flux, uncollided, NULL, 0};
  bk_parallel(s->voxels, BK_GRAIN, to_flux_range, &u);
}

void pm_unpack_weights(const pm_setup_t *s, const uint64_t *acc, float *count,
                       float *mean_weight) {
  pm_unpack_ctx_t u = {s, acc, NULL, count, mean_weight, 0};
  bk_parallel(s->voxels, BK_GRAIN, unpack_weights_range, &u);
}

void pm_sums_keep(const pm_setup_t *s, uint64_t *acc, pm_sums_t *out) {
  memset(out, 0, sizeof *out);
  out->acc = acc;
  out->voxels = s->voxels;
  out->channels = s->channels;
  out->mode = (int)s->params.mode;
  out->stride = pm_acc_stride(out->mode, s->channels);
  out->flux = (int)s->params.flux;
  out->camera = (int)s->params.camera;
  out->cam_scale = s->params.cam_scale;
  memcpy(out->to_radiance, s->to_radiance, sizeof out->to_radiance);
  out->count_shift = s->params.count_shift;
  out->weight_scale = s->params.weight_scale;
}

void pm_sums_setup(const pm_sums_t *k, pm_setup_t *out) {
  memset(out, 0, sizeof *out);
  out->voxels = k->voxels;
  out->channels = k->channels;
  out->params.mode = (bk_uint)k->mode;
  out->params.channels = (bk_uint)k->channels;
  out->params.count_shift = k->count_shift;
  out->params.weight_scale = k->weight_scale;
  out->params.flux = (bk_uint)k->flux;
  out->params.camera = (bk_uint)k->camera;
  out->params.cam_scale = k->cam_scale;
  memcpy(out->to_radiance, k->to_radiance, sizeof out->to_radiance);
}

void pm_sums_free(pm_sums_t *k) {
  free(k->acc);
  k->acc = NULL;
}

int pm_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol, float *radiance,
            pm_stats_t *stats, bk_timings_t *timings, bk_error_t *err) {
  return pm_bake_range(cl, scene, vol, 0, UINT64_MAX, radiance, NULL, stats, timings, err);
}

int pm_bake_range(clh_context_t *cl, const scene_t *scene, const volume_t *vol, uint64_t first,
                  uint64_t last, float *radiance, pm_sums_t *sums, pm_stats_t *stats,
                  bk_timings_t *timings, bk_error_t *err) {
  pm_setup_t s;
  pm_stats_t local;
  uint64_t *acc = NULL;
  if (!stats) stats = &local;
  memset(stats, 0, sizeof *stats);
  int rc = pm_prepare(scene, vol, &s, timings, stats, err);
  if (rc != BK_OK) return rc;
  pm_set_range(&s, first, last);
  rc = BK_ERR_RUNTIME;
  acc = bk_calloc(pm_acc_count(&s), sizeof(uint64_t), "march: radiance accumulator", err);
  if (!acc) goto error;
  double t0 = bk_now_ms();
  rc = cl ? pm_run_cl(cl, &s, acc, stats, err) : pm_run_host(&s, acc, stats, err);
  if (rc != BK_OK) goto error;
  if (sums) {
    pm_sums_keep(&s, acc, sums);
    acc = NULL;
  } else {
    pm_to_radiance(&s, acc, radiance, 3);
  }
  stats->ms_march = bk_now_ms() - t0;
  if (timings) {
    double sec = stats->ms_march > 0.0 ? stats->ms_march / 1000.0 : 1e-9;
    /* Euler-equivalent: path / Δs per second, what stepping everywhere needs */
    bk_timings_add(timings, "photon marching", stats->ms_march,
                   "%.1f M photon-steps/s (%.0f M Euler-equivalent), %.0f M voxels/s%s",
                   stats->steps / sec * 1e-6, stats->path_voxels / scene->step / sec * 1e-6,
                   stats->voxels / sec * 1e-6, cl ? "" : ", host C");
  }
  bk_log(2,
         "march: %llu photons: %llu missed the grid, %llu left it, %llu absorbed, %llu at the "
         "step limit; %llu steps, %llu voxel crossings",
         (unsigned long long)stats->photons, (unsigned long long)stats->missed_grid,
         (unsigned long long)stats->left_grid, (unsigned long long)stats->absorbed,
         (unsigned long long)stats->step_limit, (unsigned long long)stats->steps,
         (unsigned long long)stats->voxels);
  pm_report_scattering(&s, stats, timings);
  if (stats->step_limit)
    bk_log(1, "march: %llu photon(s) stopped at the step limit (trapped by total internal "
              "reflection?%s)", (unsigned long long)stats->step_limit,
           s.ms.params.max_bounces ? " or a random walk longer than 16 grid diagonals" : "");
  rc = BK_OK;
error:
  free(acc);
  pm_setup_free(&s);
  return rc;
}

/* Marches one photon with a path recorder, on a scratch accumulator. */
static int trace(const pm_setup_t *s, const pm_params *P, const ph_light *lights, uint32_t index,
                 float *points, int max_points, int *count, pm_result *res, bk_error_t *err) {
  uint64_t *scratch = bk_calloc(pm_acc_count(s), sizeof(uint64_t), "march: trace scratch", err);
  if (!scratch) return BK_ERR_RUNTIME;
  pm_path_rec rec = {points, max_points, 0};
  pm_result r;
  pm_march_photon(P, lights, s->ng, s->pyramid.level, s->sigma_t, scratch, NULL, NULL, index, &r,
                  &rec);
  free(scratch);
  const grid_dims_t *d = &s->dims;
  int stored = rec.count < max_points ? rec.count : max_points;
  for (int i = 0; i < stored; i++)
    for (int a = 0; a < 3; a++) points[3 * i + a] = d->origin[a] + points[3 * i + a] * d->voxel_size;
  *count = rec.count;
  if (res) *res = r;
  return BK_OK;
}

int pm_trace_photon(const pm_setup_t *s, uint32_t index, float *points, int max_points,
                    int *count, pm_result *res, bk_error_t *err) {
  if (index >= s->lights.photons)
    return bk_fail(err, BK_ERR_INPUT, "pm_trace_photon: photon %u of %llu", index,
                   (unsigned long long)s->lights.photons);
  return trace(s, &s->params, s->lights.lights, index, points, max_points, count, res, err);
}

int pm_trace_ray(const pm_setup_t *s, const float origin[3], const float dir[3], float *points,
                 int max_points, int *count, pm_result *res, bk_error_t *err) {
  /* a one-photon directional light whose rectangle is a point */
  pm_params P = s->params;
  ph_light L;
  memset(&L, 0, sizeof L);
  const grid_dims_t *d = &s->dims;
  double l = sqrt((double)dir[0] * dir[0] + (double)dir[1] * dir[1] + (double)dir[2] * dir[2]);
  if (!(l > 0.0)) return bk_fail(err, BK_ERR_INPUT, "pm_trace_ray: zero direction");
  L.type = PH_DIRECTIONAL;
  L.px = (origin[0] - d->origin[0]) / d->voxel_size;
  L.py = (origin[1] - d->origin[1]) / d->voxel_size;
  L.pz = (origin[2] - d->origin[2]) / d->voxel_size;
  L.dx = (float)(dir[0] / l), L.dy = (float)(dir[1] / l), L.dz = (float)(dir[2] / l);
  L.power[0] = L.power[1] = L.power[2] = 1.0f;
  L.count = 1;
  P.light_count = 1;
  P.photon_total = 1;
  return trace(s, &P, &L, 0, points, max_points, count, res, err);
}

uint64_t pm_deposit_repeat_host(float value, uint64_t n) {
  volatile uint64_t acc = 0; /* volatile: the loop must really add n times */
  uint64_t a;
  for (uint64_t i = 0; i < n; i++) {
    a = acc;
    pm_deposit(&a, value);
    acc = a;
  }
  return acc;
}
