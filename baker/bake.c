/* bake.c: the per-frame bake pipeline and the batch of frames `baker bake`
 * runs (the command's parsing is bake_cmd.c). A frame is four stages:
 * load the scene and voxelize it, trace photons (reference march or
 * adaptive), derive the output grids, write the VDB. */
#define _POSIX_C_SOURCE 200809L
#include "bake.h"

#include <inttypes.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "adaptive.h"
#include "batches.h"
#include "brick_grid.h"
#include "base/common.h"
#include "base/frames.h"
#include "base/grid.h"
#include "base/parallel.h"
#include "budget.h"
#include "clhost.h"
#include "frame_reuse.h"
#include "march.h"
#include "shard.h"
#include "stats_json.h"
#include "vox_code.h"
#include "voxelize.h"

/* One frame's state, from the scene to the grids written. */
typedef struct bake_job {
  scene_t scene;
  int scene_loaded;
  bake_reuse_t *reuse;  /* owns the volume and the OpenCL context (frame_reuse.h) */
  const volume_t *vol;  /* &reuse->volume once built */
  bk_timings_t timings;
  clh_context_t *cl;    /* &reuse->cl once started, else no_cl */
  clh_context_t no_cl;
  pm_stats_t stats;
  ad_stats_t astats;
  bt_result_t error;
  float *radiance, *photon_count, *photon_weight, *filter_radius;
  og_source_t derived; /* what the grids made at the write read (out_grids.h) */
  shard_state_t shard;  /* --shard: the raw sums written instead of radiance */
  brick_grid_t ior_bricks; /* the volume's n once the march no longer reads it */
  /* a coded volume's σt decoded for the write's extinction and density
   * grids (12 B per voxel beside the code and radiance: less than the
   * voxelize phase held); NULL: none, or no memory for it */
  float *sigma_t_dense;
} bake_job_t;

static int expand_scene_paths(scene_t *s, int frame, bk_error_t *err);

void bake_options_defaults(bake_options_t *opt) {
  memset(opt, 0, sizeof *opt);
  opt->mode = opt->integrator = -1;
  opt->photons = opt->seed = -1;
  opt->batches = -1;
  opt->target_error = opt->time_budget_s = -1.0;
  opt->step = -1.0f;
  opt->resolution = -1;
  opt->write.compression = VDBIO_COMPRESS_BLOSC;
}

static void apply_overrides(const bake_options_t *opt, scene_t *s) {
  if (opt->mode >= 0) s->mode = (photon_mode_t)opt->mode;
  if (opt->photons > 0) s->photon_count = opt->photons;
  if (opt->integrator >= 0) s->integrator = (integrator_t)opt->integrator;
  if (opt->step > 0) s->step = opt->step;
  if (opt->resolution > 0) s->resolution = opt->resolution;
  if (opt->seed >= 0) s->seed = (unsigned)opt->seed;
  if (opt->batches > 0) s->batches = opt->batches;
  if (opt->target_error > 0) s->target_error = (float)opt->target_error;
  if (opt->time_budget_s > 0) s->time_budget_s = (float)opt->time_budget_s;
}

int bake_load_scene(const bake_options_t *opt, const char *scene_path, int frame, scene_t *s,
                    bk_error_t *err) {
  int rc = scene_load_frame(scene_path, opt->sets, opt->set_count, frame, s, err);
  if (!rc) apply_overrides(opt, s);
  return rc;
}

static const char *compression_name(vdbio_compression_t c) {
  return c == VDBIO_COMPRESS_ZIP ? "zip" : c == VDBIO_COMPRESS_NONE ? "none" : "blosc";
}

void bake_settings(const bake_options_t *opt, const scene_t *s, char *out, size_t len) {
  snprintf(out, len,
           "scene=%016" PRIx64 " mode=%s photons=%lld integrator=%s step=%.9g seed=%u "
           "resolution=%d compression=%s half=%d filter=%s batches=%d target_error=%g "
           "time_budget_s=%g error_grid=%d",
           s->hash, scene_mode_name(s->mode), s->photon_count,
           scene_integrator_name(s->integrator), (double)s->step, s->seed, s->resolution,
           compression_name(opt->write.compression), opt->write.half_float ? 1 : 0,
           s->mode != MODE_ADAPTIVE ? "n/a" : opt->no_filter ? "off" : "on", scene_batches(s, bt_per_voxel(opt->error_grid, opt->shard_count)),
           (double)s->target_error, (double)s->time_budget_s, opt->error_grid);
  size_t at = strlen(out);
  if (opt->shard_count && at < len)
    snprintf(out + at, len - at, " shard=%d/%d", opt->shard_index, opt->shard_count);
}

/* The march runs on OpenCL: the scene has lights to trace and the host
 * path was not asked for. */
static int bake_wants_cl(const bake_job_t *j, const bake_options_t *opt) {
  return j->scene.light_count > 0 && !opt->host_only;
}

/* Stage 1: the scene (with the command's overrides, the frame's keyframed
 * values and paths) and its voxels, kept from the frame before when they
 * were made from the same inputs. */
static int bake_load(bake_job_t *j, const bake_options_t *opt, const char *scene_path,
                     const char *out_path, int frame, bk_error_t *err) {
  double t0 = bk_now_ms();
  int rc = BK_OK;
  if (!j->scene_loaded && (rc = bake_load_scene(opt, scene_path, frame, &j->scene, err)))
    return rc;
  j->scene_loaded = 1;
  if ((rc = expand_scene_paths(&j->scene, frame, err))) return rc;
  bk_timings_add(&j->timings, "scene load", bk_now_ms() - t0, "%d objects, %d lights",
                 j->scene.object_count, j->scene.light_count);
  j->reuse->extra_bytes = (opt->shard_count ? budget_shard_bytes(&j->scene) : 0.0) +
                          budget_output_bytes(&j->scene, out_path);
  /* the march will want OpenCL: its driver loads while the voxels are made */
  const char *cl_device = bake_wants_cl(j, opt) ? (opt->device ? opt->device : "") : NULL;
  if ((rc = fr_volume(j->reuse, &j->scene, opt->max_memory, cl_device, &j->timings, err)))
    return rc;
  j->vol = &j->reuse->volume;
  return BK_OK;
}

static int bake_adaptive(bake_job_t *j, const bake_options_t *opt, bk_error_t *err) {
  size_t n = grid_count(&j->vol->dims);
  ad_bake_opts_t ao;
  ad_bake_defaults(&ao);
  ao.filter = !opt->no_filter;
  ao.fields = j->reuse->keep_fields ? &j->reuse->fields : NULL;
  ao.error_grid = opt->error_grid;
  ao.retable = j->scene.retable;
  ao.t_start = bk_now_ms(); /* a time budget counts the pilot and the distribution */
  if (j->scene.medium_g != 0.0f || j->vol->g)
    bk_warn("%s: adaptive mode writes no radiance_flux: `baker view` shows the anisotropic "
            "medium's in-scattering as isotropic (photons.mode \"reference\" keeps it)",
            j->scene.path);
  j->photon_count = bk_calloc(n, sizeof(float), "photon_count grid", err);
  j->photon_weight = bk_calloc(n, sizeof(float), "photon_weight grid", err);
  if (opt->write_filter_radius)
    j->filter_radius = bk_calloc(n, sizeof(float), "filter_radius grid", err);
  if (!j->photon_count || !j->photon_weight || (opt->write_filter_radius && !j->filter_radius))
    return err->code;
  int rc = ad_bake(opt->host_only ? NULL : j->cl, &j->scene, j->vol, &ao, j->radiance,
                   j->photon_count, j->photon_weight, j->filter_radius, &j->astats, &j->timings,
                   err);
  j->stats = j->astats.march;
  j->error = j->astats.error; /* the error grid moves to j->error */
  j->astats.error.error_grid = NULL;
  return rc;
}

/* No later frame of this run takes the volume (a batch of several frames
 * keeps it): the bake may then free its arrays as it is done with them. */
static int bake_volume_ends_here(const bake_job_t *j) { return !j->reuse->several_frames; }

/* Once the march has its {∇n, n} field, n is read again only by the
 * write's ior grid: it waits there as bricks, most of them one value
 * (brick_grid.h: 0.4 B per voxel for the sphere scene instead of 4). Out of
 * memory for the bricks, n stays as it is. */
static void bake_pack_ior(void *ctx) {
  bake_job_t *j = ctx;
  volume_t *v = &j->reuse->volume;
  bk_error_t err;
  const double t0 = bk_now_ms();
  if (!v->ior || bg_build(&v->dims, v->ior, &j->ior_bricks, &err) != BK_OK) return;
  bk_log(2, "march: n packed into bricks, %.1f MiB, %.0f ms",
         (double)bg_bytes(&j->ior_bricks) / 1048576.0, bk_now_ms() - t0);
  free(v->ior);
  v->ior = NULL;
  j->reuse->has_volume = 0; /* not whole now */
}

/* Stage 2: the radiance grid, by the reference march or the adaptive
 * pipeline; a scene without lights still gets an (empty) radiance grid. */
static int bake_photons(bake_job_t *j, const bake_options_t *opt, bk_error_t *err) {
  size_t n = grid_count(&j->vol->dims);
  if (opt->shard_count && j->scene.light_count == 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: --shard: the scene has no lights, so no photons to "
                   "split; bake it whole", j->scene.path);
  /* the reference march allocates it itself, after its fields are freed */
  const int march_allocates = !opt->shard_count && j->scene.light_count > 0 &&
                              j->scene.mode != MODE_ADAPTIVE;
  if (!opt->shard_count && !march_allocates &&
      !(j->radiance = bk_calloc(n * 3, sizeof(float), "radiance grid", err)))
    return err->code;
  if (j->scene.light_count == 0) return BK_OK;
  if (bake_wants_cl(j, opt)) {
    int rc = fr_opencl(j->reuse, opt->device, j->scene.frame, &j->timings, err);
    if (rc) return rc;
    j->cl = &j->reuse->cl;
  }
  if (opt->shard_count)
    return shard_march(opt->host_only ? NULL : j->cl, &j->scene, j->vol, opt, &j->shard,
                       &j->stats, &j->astats, &j->timings, err);
  if (j->scene.mode == MODE_ADAPTIVE) return bake_adaptive(j, opt, err);
  bt_options_t bo = {0};
  bo.error_grid = opt->error_grid;
  bo.fields = j->reuse->keep_fields ? &j->reuse->fields : NULL;
  bo.radiance_out = &j->radiance;
  if (bake_volume_ends_here(j) && !j->vol->ior_rb) {
    bo.fields_built = bake_pack_ior;
    bo.fields_built_ctx = j;
  }
  return bt_bake(opt->host_only ? NULL : j->cl, &j->scene, j->vol, &bo, j->radiance, &j->error,
                 &j->stats, &j->timings, err);
}

/* A grid of the list, dense or made at the write. */
static vdbio_grid_t made_grid(const char *name, vdbio_type_t type, og_values_t v, int inv,
                              float background) {
  return (vdbio_grid_t){name, type, v.data, inv, background, v.fill, v.ctx, v.grey};
}

/* Each background is the value outside the grid: the medium's n for `ior`,
 * 0 for the rest (the bake holds no light or matter outside its box). */
int bake_grid_list(const bake_arrays_t *a, vdbio_grid_t grids[BAKE_MAX_GRIDS]) {
  int g = 0;
  const vdbio_type_t medium = a->sca_channels == 3 ? VDBIO_VEC3 : VDBIO_FLOAT;
  const int inv = a->sca_channels == 3;
  grids[g++] = made_grid("ior", VDBIO_FLOAT, a->ior, 0, a->medium_ior);
  grids[g++] = made_grid("extinction", medium, a->extinction, inv, 0.0f);
  grids[g++] = made_grid("scattering", medium, a->scattering, inv, 0.0f);
  grids[g++] = made_grid("density", VDBIO_FLOAT, a->density, 0, 0.0f);
  if (og_present(a->ior_rgb))
    grids[g++] = made_grid("ior_rgb", VDBIO_VEC3, a->ior_rgb, 0, a->medium_ior);
  if (og_present(a->radiance)) grids[g++] = made_grid("radiance", VDBIO_VEC3, a->radiance, 1, 0.0f);
  if (og_present(a->emission))
    grids[g++] = made_grid("emission", VDBIO_VEC3, a->emission, 1, 0.0f);
  if (a->radiance_flux)
    grids[g++] = made_grid("radiance_flux", VDBIO_VEC3, og_dense(a->radiance_flux), 0, 0.0f);
  if (a->radiance_uncollided)
    grids[g++] =
        made_grid("radiance_uncollided", VDBIO_FLOAT, og_dense(a->radiance_uncollided), 0, 0.0f);
  if (a->radiance_flux_uncollided)
    grids[g++] = made_grid("radiance_flux_uncollided", VDBIO_VEC3,
                           og_dense(a->radiance_flux_uncollided), 0, 0.0f);
  if (a->radiance_camera)
    grids[g++] = made_grid("radiance_camera", VDBIO_FLOAT, og_dense(a->radiance_camera), 0, 0.0f);
  if (og_present(a->phase_g)) grids[g++] = made_grid("phase_g", VDBIO_FLOAT, a->phase_g, 0, 0.0f);
  if (a->photon_count)
    grids[g++] = made_grid("photon_count", VDBIO_FLOAT, og_dense(a->photon_count), 0, 0.0f);
  if (a->photon_weight)
    grids[g++] = made_grid("photon_weight", VDBIO_FLOAT, og_dense(a->photon_weight), 0, 0.0f);
  if (a->filter_radius)
    grids[g++] = made_grid("filter_radius", VDBIO_FLOAT, og_dense(a->filter_radius), 0, 0.0f);
  return g;
}

/* Stage 3: the grids of DESIGN.md §5 in file order (bake_grid_list), for a
 * shard the medium grids and the raw sums (shard.h); *count of them. The
 * derived ones (density, emission, ...) are made by the writer
 * a few slices at a time (out_grids.h), never whole. For grey media the Vec3
 * grids collapse to floats (DESIGN §5 allows it, and renderers read a float
 * `extinction` more widely). */
static int bake_output_grids(bake_job_t *j, vdbio_grid_t grids[BAKE_MAX_GRIDS], int *count,
                             bk_error_t *err) {
  const volume_t *vol = j->vol;
  size_t n = grid_count(&vol->dims);
  og_source_t *src = &j->derived;
  /* grey light: one radiance value per voxel, the RGB grid made at the write */
  const int rad_channels = j->error.radiance_channels == 1 ? 1 : 3;
  *src = (og_source_t){.vol = vol,
                       .radiance = j->radiance,
                       .radiance_channels = rad_channels,
                       .ior = vol->ior,
                       .ior_rb = vol->ior_rb,
                       .voxels = n,
                       .g = vol->g,
                       .medium_g = j->scene.medium_g};
  /* n packed into bricks after the march's fields were built (bake_pack_ior);
   * the scattering and extinction grids are the volume's σs and σt: plain
   * arrays as they stand, else decoded (a coded volume, voxelize.h) or
   * repeated (a homogeneous one's one voxel) at the write; Vec3, or floats
   * when the volume is grey (vox_summarise) */
  const og_values_t ior = j->ior_bricks.slot ? (og_values_t){NULL, bg_fill, &j->ior_bricks, 0}
                                             : og_dense(vol->ior);
  const int plain = vol->sigma_s && !vol->homogeneous;
  /* a coded volume's σt decoded once: the writer reads a grid several times
   * (tree, leaves, checksum); without memory for it, decoded as it goes */
  if (vol->sigma_code) src->sigma_t = j->sigma_t_dense = vox_code_decode(vol, 1);
  bake_arrays_t a = {ior, og_dense(j->radiance),
                     plain              ? og_dense(vol->sigma_t)
                     : src->sigma_t     ? og_dense(src->sigma_t)
                                        : og_made(og_extinction, src),
                     plain ? og_dense(vol->sigma_s) : og_made(og_scattering, src),
                     og_made(og_density, src), og_dense(NULL),
                     j->photon_count, j->photon_weight, j->filter_radius, 3,
                     j->scene.medium_ior, og_dense(NULL), j->error.flux, j->error.uncollided,
                     og_dense(NULL), NULL, NULL};
  /* grey light: radiance and (in a grey medium) emission written as RGB
   * from one float per voxel (vdbio_grid_t.grey) */
  const int grey_emission = rad_channels == 1 && vol->sigma_channels == 1;
  if (j->radiance)
    a.emission = grey_emission ? og_grey(og_made(og_emission_grey, src))
                               : og_made(og_emission, src);
  if (j->radiance && rad_channels == 1) a.radiance = og_grey(og_dense(j->radiance));
  if (j->error.uncollided) a.radiance_flux_uncollided = pm_flux_uncollided(j->error.uncollided, n);
  if (j->error.camera) a.radiance_camera = pm_radiance_camera(j->error.uncollided, n);
  if (vol->ior_rb) a.ior_rgb = og_made(og_ior_rgb, src);
  if (j->error.flux || j->shard.sums.flux) /* a shard's flux is in its sums */
    a.phase_g = og_made(og_phase_g, src);
  if (vol->grey) a.sca_channels = 1; /* σs and σt hold one value per voxel */
  *count = bake_grid_list(&a, grids);
  if (j->error.error_grid)
    grids[(*count)++] =
        made_grid("radiance_error", VDBIO_FLOAT, og_dense(j->error.error_grid), 0, 0.0f);
  if (j->shard.sums.acc)
    return shard_grids(&j->shard, &vol->dims, grids, count, BAKE_MAX_GRIDS, err);
  return BK_OK;
}

/* What the error metadata covers, in words. */
static const char *error_note(const scene_t *s, const bake_options_t *opt, const ee_terms_t *e) {
  if (opt->shard_count)
    return "not measured for photon shards and their merge (the spread needs every shard's "
           "batches; error_* are -1)";
  if (e->noise < 0.0) return "noise not measured: one batch (photons.batches >= 2 measures it)";
  if (s->mode == MODE_ADAPTIVE && e->filter > 0.0)
    return "relative RMS luminance error over lit voxels vs RK4 1/8-voxel truth: noise of the "
           "filtered estimate, the filter's bias (error_filter) and the step (docs/error.md)";
  return "relative RMS luminance error over lit voxels vs RK4 1/8-voxel truth (docs/error.md)";
}

/* What the write may free as it goes when no later frame takes this
 * volume: n and σt (plain arrays) or the coded σ once the last grid that
 * reads each is in the file (docs/memory.md). */
typedef struct bake_release {
  bake_reuse_t *reuse;
  int last_ior, last_sigma_t; /* grid indices; -1: none reads it */
} bake_release_t;

static void bake_grid_done(void *ctx, int g) {
  bake_release_t *r = ctx;
  volume_t *v = &r->reuse->volume;
  if (g == r->last_ior) free(v->ior), v->ior = NULL;
  if (g == r->last_sigma_t && v->sigma_code) free(v->sigma_code), v->sigma_code = NULL;
  else if (g == r->last_sigma_t) free(v->sigma_t), v->sigma_t = NULL;
  if (g == r->last_ior || g == r->last_sigma_t) r->reuse->has_volume = 0; /* not whole now */
}

/* The release plan for `grids`: which grid reads n and σt last (with coded
 * σ, σs too: the same buffer). */
static bake_release_t bake_release_plan(bake_reuse_t *reuse, const vdbio_grid_t *grids,
                                        int count) {
  bake_release_t r = {reuse, -1, -1};
  const int coded = reuse->volume.sigma_code != NULL;
  for (int g = 0; g < count; g++) {
    const char *n = grids[g].name;
    if (!strcmp(n, "ior") || !strcmp(n, "ior_rgb")) r.last_ior = g;
    if (!strcmp(n, "extinction") || !strcmp(n, "density") ||
        (coded && (!strcmp(n, "scattering") || !strcmp(n, "emission") || !strcmp(n, "phase_g"))))
      r.last_sigma_t = g;
  }
  return r;
}

/* A vacuum's crop (vox_crop.h): which voxels of the scene's grid the
 * file's grids are, for a reader that wants the scene's index space. */
static vdbio_meta_t bake_crop_meta(const volume_t *v, char *buf, size_t size) {
  snprintf(buf, size, "voxels [%d, %d, %d] to [%d, %d, %d] of the %dx%dx%d grid (vacuum elsewhere)",
           v->crop_off[0], v->crop_off[1], v->crop_off[2], v->crop_off[0] + v->dims.nx - 1,
           v->crop_off[1] + v->dims.ny - 1, v->crop_off[2] + v->dims.nz - 1, v->whole.nx,
           v->whole.ny, v->whole.nz);
  vdbio_meta_t m = {"grid_crop", VDBIO_META_STRING, buf, 0, 0};
  return m;
}

void bake_camera_meta(const float position[3], char *buf, size_t size, vdbio_meta_t *out) {
  snprintf(buf, size, "[%.9g, %.9g, %.9g]", (double)position[0], (double)position[1],
           (double)position[2]);
  *out = (vdbio_meta_t){"radiance_camera_position", VDBIO_META_STRING, buf, 0, 0};
}

/* Stage 4: the grids and the metadata that says how they were made. */
static int bake_write(bake_job_t *j, const bake_options_t *opt, const char *scene_path,
                      const char *out_path, int frame, const vdbio_grid_t *grids, int count,
                      bk_error_t *err) {
  const scene_t *s = &j->scene;
  const pm_stats_t *st = &j->stats;
  const ad_stats_t *as = &j->astats;
  const ee_terms_t *e = &j->error.terms;
  /* what marched: target mode chooses its own integrator and step */
  const int chosen = j->error.step > 0.0f;
  const integrator_t integ = chosen ? j->error.integrator : s->integrator;
  const float step = chosen ? j->error.step : s->step;
  char hash[32], bounds[160], settings[512];
  bake_settings(opt, s, settings, sizeof settings);
  snprintf(hash, sizeof hash, "%016" PRIx64, s->hash);
  snprintf(bounds, sizeof bounds, "[[%g,%g,%g],[%g,%g,%g]]", s->bounds_min[0], s->bounds_min[1],
           s->bounds_min[2], s->bounds_max[0], s->bounds_max[1], s->bounds_max[2]);
  vdbio_meta_t meta[] = {
      {"mode", VDBIO_META_STRING, scene_mode_name(s->mode), 0, 0},
      {"scene_file", VDBIO_META_STRING, scene_path, 0, 0},
      {"scene_hash", VDBIO_META_STRING, hash, 0, 0},
      {"frame", VDBIO_META_INT, NULL, frame, 0},
      {"grid_bounds", VDBIO_META_STRING, bounds, 0, 0},
      {"grid_resolution", VDBIO_META_INT, NULL, s->resolution, 0},
      {"ior_smoothing_voxels", VDBIO_META_FLOAT, NULL, 0, s->ior_smoothing},
      {"photon_count", VDBIO_META_INT, NULL, (long long)st->photons, 0},
      {"photon_integrator", VDBIO_META_STRING, scene_integrator_name(integ), 0, 0},
      {"photon_step_voxels", VDBIO_META_FLOAT, NULL, 0, step},
      {"photon_seed", VDBIO_META_INT, NULL, s->seed, 0},
      {"photons_missed_grid", VDBIO_META_INT, NULL, (long long)st->missed_grid, 0},
      {"photons_left_grid", VDBIO_META_INT, NULL, (long long)st->left_grid, 0},
      {"photons_absorbed", VDBIO_META_INT, NULL, (long long)st->absorbed, 0},
      {"photons_step_limit", VDBIO_META_INT, NULL, (long long)st->step_limit, 0},
      {"photon_steps", VDBIO_META_INT, NULL, (long long)st->steps, 0},
      /* multiple scattering (baker/bounces.h): the events allowed per photon
       * (0: single scattering) and the share of the deposit after the first */
      {"photon_bounces", VDBIO_META_INT, NULL, st->bounces, 0},
      {"scattered_share", VDBIO_META_FLOAT, NULL, 0, (float)pm_scattered_share(st)},
      {"opencl_device", VDBIO_META_STRING, opt->host_only ? "host C" : j->cl->device_name, 0, 0},
      {"bake_settings", VDBIO_META_STRING, settings, 0, 0},
      /* docs/error.md; -1: not measured */
      {"error_estimate", VDBIO_META_FLOAT, NULL, 0, (float)e->estimate},
      {"error_noise", VDBIO_META_FLOAT, NULL, 0, (float)e->noise},
      {"error_step", VDBIO_META_FLOAT, NULL, 0, (float)e->step},
      /* adaptive with its filter: the filter's bias (0: no filter) */
      {"error_filter", VDBIO_META_FLOAT, NULL, 0, e->noise >= 0.0 ? (float)e->filter : -1.0f},
      {"error_batches", VDBIO_META_INT, NULL, e->batches, 0},
      {"error_note", VDBIO_META_STRING, error_note(s, opt, e), 0, 0},
      /* adaptive only (the count below leaves them out otherwise) */
      {"adaptive_pilot_photons", VDBIO_META_INT, NULL, (long long)as->pilot.photons, 0},
      {"adaptive_gradient_threshold", VDBIO_META_FLOAT, NULL, 0, as->select.gradient_threshold},
      {"adaptive_gradient_threshold_rule", VDBIO_META_STRING,
       s->gradient_threshold < 0.0f ? "auto" : "given", 0, 0},
      {"adaptive_luminance_threshold", VDBIO_META_FLOAT, NULL, 0,
       as->select.luminance_threshold},
      {"adaptive_luminance_threshold_rule", VDBIO_META_STRING,
       s->luminance_threshold < 0.0f ? "auto" : "given", 0, 0},
      {"adaptive_alpha", VDBIO_META_FLOAT, NULL, 0, s->alpha},
      {"adaptive_filter", VDBIO_META_STRING, as->filtered ? "on" : "off", 0, 0},
  };
  int meta_count = (int)(sizeof meta / sizeof meta[0]);
  if (s->mode != MODE_ADAPTIVE) meta_count -= 7;
  vdbio_meta_t all[sizeof meta / sizeof meta[0] + 2 + SHARD_META_MAX];
  memcpy(all, meta, sizeof meta);
  char crop[160], camera[96];
  if (j->vol->cropped) all[meta_count++] = bake_crop_meta(j->vol, crop, sizeof crop);
  if (j->error.camera)
    bake_camera_meta(s->camera.position, camera, sizeof camera, &all[meta_count++]);
  if (j->shard.sums.acc)
    meta_count += shard_meta(&j->shard, opt, s, &j->vol->dims, all + meta_count);
  vdbio_write_opts_t wo = opt->write;
  if (j->shard.sums.acc) wo.half_float = 0; /* sums and medium go to the merge exactly */
  bake_release_t release = bake_release_plan(j->reuse, grids, count);
  if (bake_volume_ends_here(j)) {
    wo.grid_done = bake_grid_done;
    wo.grid_done_ctx = &release;
  }
  return vdbio_write(out_path, &j->vol->dims, grids, count, all, meta_count, &wo, err);
}

static void bake_report(const bake_job_t *j, const char *scene_path, const char *out_path) {
  const volume_t *vol = j->vol;
  const pm_stats_t *st = &j->stats;
  printf("baked %s -> %s (%dx%dx%d voxels of %g m)\n", scene_path, out_path, vol->dims.nx,
         vol->dims.ny, vol->dims.nz, vol->dims.voxel_size);
  if (st->photons)
    printf("photons: %llu traced, %llu missed the grid, %llu left it, %llu absorbed, "
           "%llu stopped at the step limit\n",
           (unsigned long long)st->photons, (unsigned long long)st->missed_grid,
           (unsigned long long)st->left_grid, (unsigned long long)st->absorbed,
           (unsigned long long)st->step_limit);
  bk_timings_print(&j->timings, stdout);
  fflush(stdout);
}

/* --stats: the frame's JSON, at the frame's expansion of the path. */
static int bake_stats(const bake_job_t *j, const bake_options_t *opt, const char *scene_path,
                      const char *out_path, int frame, bk_error_t *err) {
  char path[SCENE_PATH_MAX];
  int rc = frames_expand(opt->stats_path, frame, path, sizeof path, err);
  if (rc) return rc;
  sj_frame_t f = {scene_path, out_path, frame, &j->scene, &j->timings, &j->stats,
                  &j->error};
  return sj_write(path, &f, err);
}

static void bake_job_free(bake_job_t *j) {
  bg_free(&j->ior_bricks);
  free(j->radiance);
  free(j->sigma_t_dense);
  free(j->photon_count);
  free(j->photon_weight);
  free(j->filter_radius);
  shard_free(&j->shard);
  free(j->error.error_grid);
  free(j->error.flux);
  free(j->error.uncollided);
  if (j->scene_loaded) scene_free(&j->scene);
}

int bake_frame(const bake_options_t *opt, const char *scene_path, const char *out_path, int frame,
               scene_t *loaded, bake_reuse_t *reuse, bk_error_t *err) {
  bake_job_t job, *j = &job;
  bake_reuse_t alone;
  memset(j, 0, sizeof *j);
  memset(&alone, 0, sizeof alone);
  j->reuse = reuse ? reuse : &alone;
  j->cl = &j->no_cl;
  if (loaded) j->scene = *loaded, j->scene_loaded = 1; /* the job frees it from here */
  vdbio_grid_t grids[BAKE_MAX_GRIDS];
  int count = 0;
  int rc = bk_check_output_dir(out_path, err);
  if (!rc && opt->stats_path) rc = bk_check_output_dir(opt->stats_path, err);
  if (!rc) rc = bake_load(j, opt, scene_path, out_path, frame, err);
  if (!rc) rc = bake_photons(j, opt, err);
  double t0 = bk_now_ms();
  if (!rc) rc = bake_output_grids(j, grids, &count, err);
  if (!rc) rc = bake_write(j, opt, scene_path, out_path, frame, grids, count, err);
  if (!rc) {
    double ms = bk_now_ms() - t0;
    bk_timings_add(&j->timings, "write", ms, "%s, %.0f M voxels/s", out_path,
                   (double)grid_count(&j->vol->dims) / (ms * 1e3 + 1e-9));
    pm_warn_step_limit(&j->scene, &j->stats);
    if (bk_verbosity >= 1) bake_report(j, scene_path, out_path);
    if (opt->stats_path) rc = bake_stats(j, opt, scene_path, out_path, frame, err);
  }
  bake_job_free(j);
  fr_opencl_settle(j->reuse); /* a frame that failed before the march left it opening */
  if (rc == BK_ERR_RUNTIME) fr_drop_opencl(j->reuse); /* it may be what failed */
  fr_free(&alone);
  return rc;
}

/* Frame patterns also work inside the scene: a mesh sequence or a Houdini
 * smoke cache (density_vdb "smoke.$F4.vdb") follows the frame. */
static int expand_scene_paths(scene_t *s, int frame, bk_error_t *err) {
  char buf[SCENE_PATH_MAX];
  int rc = BK_OK;
  for (int i = 0; i < s->object_count && !rc; i++)
    if (!(rc = frames_expand(s->objects[i].mesh, frame, buf, sizeof buf, err)))
      memcpy(s->objects[i].mesh, buf, sizeof buf);
  scene_vdb_ref_t *refs[2] = {&s->density_vdb, &s->ior_vdb};
  for (int i = 0; i < 2 && !rc; i++)
    if (refs[i]->present && !(rc = frames_expand(refs[i]->file, frame, buf, sizeof buf, err)))
      memcpy(refs[i]->file, buf, sizeof buf);
  return rc;
}
