/* bake.c: the `baker bake` command and the per-frame pipeline. */
#define _POSIX_C_SOURCE 200809L
#include "bake.h"

#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "adaptive.h"
#include "clhost.h"
#include "common.h"
#include "frames.h"
#include "grid.h"
#include "march.h"
#include "voxelize.h"

static int expand_scene_paths(scene_t *s, int frame, bk_error_t *err);

static void bake_usage(FILE *out) {
  fprintf(out,
          "usage: baker bake SCENE.json -o OUT.vdb [options]\n"
          "\n"
          "Voxelizes the scene's meshes into index-of-refraction and medium grids, traces\n"
          "photons along curved paths on OpenCL and writes the grids radiance, ior,\n"
          "extinction, scattering and density to OUT.vdb (DESIGN.md §5).\n"
          "\n"
          "options:\n"
          "  -o, --output PATH        output .vdb (required); may hold a frame pattern\n"
          "  --frames A[-B[xS]]       bake frames A..B step S; `####` (4 digits) or `$F4`\n"
          "                           in SCENE and PATH become the frame number. Frames\n"
          "                           whose output exists are skipped (restartable); one\n"
          "                           frame per task: --frames $SLURM_ARRAY_TASK_ID\n"
          "  --force                  re-bake frames whose output already exists\n"
          "  --mode reference|adaptive   photon pipeline (scene photons.mode)\n"
          "  --photons N              photon count (scene photons.count)\n"
          "  --no-filter              adaptive: skip the reconstruction filter (the raw,\n"
          "                           unbiased estimate)\n"
          "  --write-filter-radius    adaptive: also write the filter_radius grid (debug)\n"
          "  --integrator euler|rk4   ray-equation integrator (scene photons.integrator)\n"
          "  --step VOXELS            march step in refractive regions (scene photons.step)\n"
          "  --seed N                 sampling seed (scene photons.seed)\n"
          "  --resolution N           voxels along the longest side (scene grid.resolution)\n"
          "  --compression zip|blosc|none   VDB compression (default blosc: about half\n"
          "                           the write time of zip and smaller here; Houdini's\n"
          "                           and Blender's OpenVDB read both)\n"
          "  --half                   store float grids as 16-bit half\n"
          "  --device SPEC            OpenCL device: `P:D` indices or a name substring;\n"
          "                           default PoCL (CPU). `baker devices` lists them\n"
          "  --host                   march on the host in plain C instead of OpenCL\n"
          "  --progress               show progress even when stderr is not a terminal\n"
          "  -q, --quiet              errors only (no timing table)\n"
          "  -v, --verbose            more detail (OpenCL build logs, cache use)\n"
          "  -h, --help               this text\n"
          "\n"
          "Exit status: 0 success, 2 bad input or usage, 1 runtime failure.\n");
}

/* Parses a whole-string number; 0 on junk. */
static int parse_ll(const char *s, long long *out) {
  char *end;
  errno = 0;
  long long v = strtoll(s, &end, 10);
  if (errno || end == s || *end) return 0;
  *out = v;
  return 1;
}
static int parse_float(const char *s, float *out) {
  char *end;
  errno = 0;
  float v = strtof(s, &end);
  if (errno || end == s || *end) return 0;
  *out = v;
  return 1;
}

static void apply_overrides(const bake_options_t *opt, scene_t *s) {
  if (opt->mode >= 0) s->mode = (photon_mode_t)opt->mode;
  if (opt->photons > 0) s->photon_count = opt->photons;
  if (opt->integrator >= 0) s->integrator = (integrator_t)opt->integrator;
  if (opt->step > 0) s->step = opt->step;
  if (opt->resolution > 0) s->resolution = opt->resolution;
  if (opt->seed >= 0) s->seed = (unsigned)opt->seed;
}

/* An existing output counts as complete when it opens as a VDB written by
 * baker: files are renamed into place only once fully written, so a partial
 * file can only come from another program. */
static int output_complete(const char *path) {
  if (access(path, F_OK) != 0) return 0;
  char creator[256];
  bk_error_t err;
  if (vdbio_read_meta(path, "creator", creator, sizeof creator, &err) != BK_OK) return 0;
  return strncmp(creator, "baker", 5) == 0;
}

/* sigma_t = sigma_s + sigma_a per channel, the grey density (mean of the
 * channels), and whether the coefficients are grey. */
static int derive_medium_grids(const volume_t *v, float **extinction, float **density,
                               bk_error_t *err) {
  size_t n = grid_count(&v->dims);
  *extinction = bk_calloc(n * 3, sizeof(float), "extinction grid", err);
  *density = bk_calloc(n, sizeof(float), "density grid", err);
  if (!*extinction || !*density) return err->code;
  for (size_t i = 0; i < n; i++) {
    float sum = 0.0f;
    for (int c = 0; c < 3; c++) {
      float t = v->sigma_s[3 * i + c] + v->sigma_a[3 * i + c];
      (*extinction)[3 * i + c] = t;
      sum += t;
    }
    (*density)[i] = sum / 3.0f;
  }
  return BK_OK;
}

/* For grey media the Vec3 grids collapse to floats (DESIGN §5 allows it, and
 * renderers read a float `extinction` more widely). */
static float *first_channel(const float *rgb, size_t n, bk_error_t *err) {
  float *out = bk_calloc(n, sizeof(float), "grey grid", err);
  if (out)
    for (size_t i = 0; i < n; i++) out[i] = rgb[3 * i];
  return out;
}

int bake_frame(const bake_options_t *opt, const char *scene_path, const char *out_path, int frame,
               bk_error_t *err) {
  scene_t scene;
  volume_t vol;
  bk_timings_t timings;
  clh_context_t cl;
  pm_stats_t stats;
  float *extinction = NULL, *density = NULL, *ext_grey = NULL, *sca_grey = NULL;
  float *radiance = NULL, *photon_count = NULL, *photon_weight = NULL, *filter_radius = NULL;
  ad_stats_t astats;
  memset(&astats, 0, sizeof astats);
  memset(&vol, 0, sizeof vol);
  memset(&cl, 0, sizeof cl);
  memset(&stats, 0, sizeof stats);
  memset(&timings, 0, sizeof timings);
  int rc = bk_check_output_dir(out_path, err);
  if (rc) return rc;

  double t0 = bk_now_ms();
  rc = scene_load(scene_path, &scene, err);
  if (rc) return rc;
  apply_overrides(opt, &scene);
  if ((rc = expand_scene_paths(&scene, frame, err))) goto done;
  bk_timings_add(&timings, "scene load", bk_now_ms() - t0, "%d objects, %d lights",
                 scene.object_count, scene.light_count);

  rc = vox_build(&scene, &vol, &timings, err);
  if (rc) goto done;
  size_t n = grid_count(&vol.dims);

  /* photons: a scene without lights still gets an (empty) radiance grid */
  radiance = bk_calloc(n * 3, sizeof(float), "radiance grid", err);
  if (!radiance) {
    rc = err->code;
    goto done;
  }
  if (scene.light_count > 0) {
    if (!opt->host_only) {
      t0 = bk_now_ms();
      rc = clh_init(&cl, opt->device, err);
      if (rc) goto done;
      bk_timings_add(&timings, "OpenCL init", bk_now_ms() - t0, "%s", cl.device_name);
    }
    if (scene.mode == MODE_ADAPTIVE) {
      ad_bake_opts_t ao;
      ad_bake_defaults(&ao);
      ao.filter = !opt->no_filter;
      photon_count = bk_calloc(n, sizeof(float), "photon_count grid", err);
      photon_weight = bk_calloc(n, sizeof(float), "photon_weight grid", err);
      if (opt->write_filter_radius)
        filter_radius = bk_calloc(n, sizeof(float), "filter_radius grid", err);
      if (!photon_count || !photon_weight || (opt->write_filter_radius && !filter_radius)) {
        rc = err->code;
        goto done;
      }
      rc = ad_bake(opt->host_only ? NULL : &cl, &scene, &vol, &ao, radiance, photon_count,
                   photon_weight, filter_radius, &astats, &timings, err);
      stats = astats.march;
    } else {
      rc = pm_bake(opt->host_only ? NULL : &cl, &scene, &vol, radiance, &stats, &timings, err);
    }
    if (rc) goto done;
  }

  t0 = bk_now_ms();
  rc = derive_medium_grids(&vol, &extinction, &density, err);
  if (rc) goto done;
  vdbio_grid_t grids[11];
  int g = 0;
  grids[g++] = (vdbio_grid_t){"ior", VDBIO_FLOAT, vol.ior, 0};
  if (vol.grey) {
    ext_grey = first_channel(extinction, n, err);
    sca_grey = first_channel(vol.sigma_s, n, err);
    if (!ext_grey || !sca_grey) {
      rc = err->code;
      goto done;
    }
    grids[g++] = (vdbio_grid_t){"extinction", VDBIO_FLOAT, ext_grey, 0};
    grids[g++] = (vdbio_grid_t){"scattering", VDBIO_FLOAT, sca_grey, 0};
  } else {
    grids[g++] = (vdbio_grid_t){"extinction", VDBIO_VEC3, extinction, 1};
    grids[g++] = (vdbio_grid_t){"scattering", VDBIO_VEC3, vol.sigma_s, 1};
  }
  grids[g++] = (vdbio_grid_t){"density", VDBIO_FLOAT, density, 0};
  grids[g++] = (vdbio_grid_t){"radiance", VDBIO_VEC3, radiance, 1};
  if (photon_count) grids[g++] = (vdbio_grid_t){"photon_count", VDBIO_FLOAT, photon_count, 0};
  if (photon_weight) grids[g++] = (vdbio_grid_t){"photon_weight", VDBIO_FLOAT, photon_weight, 0};
  if (filter_radius) grids[g++] = (vdbio_grid_t){"filter_radius", VDBIO_FLOAT, filter_radius, 0};

  char hash[32], bounds[160];
  snprintf(hash, sizeof hash, "%016" PRIx64, scene.hash);
  snprintf(bounds, sizeof bounds, "[[%g,%g,%g],[%g,%g,%g]]", scene.bounds_min[0],
           scene.bounds_min[1], scene.bounds_min[2], scene.bounds_max[0], scene.bounds_max[1],
           scene.bounds_max[2]);
  vdbio_meta_t meta[] = {
      {"mode", VDBIO_META_STRING, scene_mode_name(scene.mode), 0, 0},
      {"scene_file", VDBIO_META_STRING, scene_path, 0, 0},
      {"scene_hash", VDBIO_META_STRING, hash, 0, 0},
      {"frame", VDBIO_META_INT, NULL, frame, 0},
      {"grid_bounds", VDBIO_META_STRING, bounds, 0, 0},
      {"grid_resolution", VDBIO_META_INT, NULL, scene.resolution, 0},
      {"ior_smoothing_voxels", VDBIO_META_FLOAT, NULL, 0, scene.ior_smoothing},
      {"photon_count", VDBIO_META_INT, NULL, (long long)stats.photons, 0},
      {"photon_integrator", VDBIO_META_STRING, scene_integrator_name(scene.integrator), 0, 0},
      {"photon_step_voxels", VDBIO_META_FLOAT, NULL, 0, scene.step},
      {"photon_seed", VDBIO_META_INT, NULL, scene.seed, 0},
      {"photons_missed_grid", VDBIO_META_INT, NULL, (long long)stats.missed_grid, 0},
      {"photons_left_grid", VDBIO_META_INT, NULL, (long long)stats.left_grid, 0},
      {"photons_absorbed", VDBIO_META_INT, NULL, (long long)stats.absorbed, 0},
      {"photons_step_limit", VDBIO_META_INT, NULL, (long long)stats.step_limit, 0},
      {"photon_steps", VDBIO_META_INT, NULL, (long long)stats.steps, 0},
      {"opencl_device", VDBIO_META_STRING, opt->host_only ? "host C" : cl.device_name, 0, 0},
      /* adaptive only (the count below leaves them out otherwise) */
      {"adaptive_pilot_photons", VDBIO_META_INT, NULL, (long long)astats.pilot.photons, 0},
      {"adaptive_gradient_threshold", VDBIO_META_FLOAT, NULL, 0,
       astats.select.gradient_threshold},
      {"adaptive_gradient_threshold_rule", VDBIO_META_STRING,
       scene.gradient_threshold < 0.0f ? "auto" : "given", 0, 0},
      {"adaptive_luminance_threshold", VDBIO_META_FLOAT, NULL, 0,
       astats.select.luminance_threshold},
      {"adaptive_luminance_threshold_rule", VDBIO_META_STRING,
       scene.luminance_threshold < 0.0f ? "auto" : "given", 0, 0},
      {"adaptive_alpha", VDBIO_META_FLOAT, NULL, 0, scene.alpha},
      {"adaptive_filter", VDBIO_META_STRING, astats.filtered ? "on" : "off", 0, 0},
  };
  int meta_count = (int)(sizeof meta / sizeof meta[0]);
  if (scene.mode != MODE_ADAPTIVE) meta_count -= 7;
  rc = vdbio_write(out_path, &vol.dims, grids, g, meta, meta_count, &opt->write, err);
  if (rc) goto done;
  bk_timings_add(&timings, "write", bk_now_ms() - t0, "%s", out_path);

  if (bk_verbosity >= 1) {
    printf("baked %s -> %s (%dx%dx%d voxels of %g m)\n", scene_path, out_path, vol.dims.nx,
           vol.dims.ny, vol.dims.nz, vol.dims.voxel_size);
    if (stats.photons)
      printf("photons: %llu traced, %llu missed the grid, %llu left it, %llu absorbed, "
             "%llu stopped at the step limit\n",
             (unsigned long long)stats.photons, (unsigned long long)stats.missed_grid,
             (unsigned long long)stats.left_grid, (unsigned long long)stats.absorbed,
             (unsigned long long)stats.step_limit);
    bk_timings_print(&timings, stdout);
    fflush(stdout);
  }
done:
  free(extinction);
  free(density);
  free(ext_grey);
  free(sca_grey);
  free(radiance);
  free(photon_count);
  free(photon_weight);
  free(filter_radius);
  clh_release(&cl);
  vox_free(&vol);
  scene_free(&scene);
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

/* Which frames to bake: --frames, else $SLURM_ARRAY_TASK_ID when the output
 * holds a frame pattern (one frame per array task), else the single frame 0
 * for a plain output path. */
static int choose_frames(const bake_options_t *opt, frames_range_t *range, bk_error_t *err) {
  const char *slurm = getenv("SLURM_ARRAY_TASK_ID");
  int patterned = frames_has_pattern(opt->out_path);
  if (opt->frames) {
    int rc = frames_parse(opt->frames, "--frames", range, err);
    if (rc) return rc;
  } else if (patterned && slurm && *slurm) {
    int rc = frames_parse(slurm, "$SLURM_ARRAY_TASK_ID", range, err);
    if (rc) return rc;
  } else if (patterned) {
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: the output holds a frame pattern but no frame was given "
                   "(--frames A-B, or run as a Slurm array task)", opt->out_path);
  } else {
    *range = (frames_range_t){0, 0, 1};
  }
  if (frames_count(range) > 1 && !patterned)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: %d frames would all write this one file; put #### or $F4 in the "
                   "output path", opt->out_path, frames_count(range));
  return BK_OK;
}

static int run_frames(const bake_options_t *opt, bk_error_t *err) {
  frames_range_t range;
  int rc = choose_frames(opt, &range, err);
  if (rc) return rc;
  int count = frames_count(&range), baked = 0, skipped = 0;
  for (int i = 0; i < count; i++) {
    int frame = frames_at(&range, i);
    char scene_path[SCENE_PATH_MAX], out_path[SCENE_PATH_MAX];
    if ((rc = frames_expand(opt->scene_path, frame, scene_path, sizeof scene_path, err)) ||
        (rc = frames_expand(opt->out_path, frame, out_path, sizeof out_path, err)))
      return rc;
    if (!opt->force && output_complete(out_path)) {
      bk_log(1, "%s exists and is complete: skipped (--force re-bakes it)", out_path);
      skipped++;
      continue;
    }
    if (count > 1) bk_log(1, "frame %d (%d of %d)", frame, i + 1, count);
    if ((rc = bake_frame(opt, scene_path, out_path, frame, err))) {
      if (count > 1) {
        char msg[sizeof err->msg];
        snprintf(msg, sizeof msg, "frame %d: %s", frame, err->msg);
        snprintf(err->msg, sizeof err->msg, "%s", msg);
      }
      return rc;
    }
    baked++;
  }
  if (count > 1) bk_log(1, "%d frames baked, %d skipped as already complete", baked, skipped);
  return BK_OK;
}

int bake_main(int argc, char **argv) {
  bake_options_t opt;
  memset(&opt, 0, sizeof opt);
  opt.mode = opt.integrator = -1;
  opt.photons = opt.seed = -1;
  opt.step = -1.0f;
  opt.resolution = -1;
  opt.write.compression = VDBIO_COMPRESS_BLOSC;

  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    const char *val = (i + 1 < argc) ? argv[i + 1] : NULL;
#define NEED_VALUE()                                                            \
  do {                                                                          \
    if (!val) {                                                                 \
      fprintf(stderr, "baker bake: %s needs a value (see baker bake --help)\n", a); \
      return BK_ERR_INPUT;                                                      \
    }                                                                           \
    i++;                                                                        \
  } while (0)
#define BAD_VALUE(what)                                                              \
  do {                                                                               \
    fprintf(stderr, "baker bake: %s: expected %s, got '%s'\n", a, what, val);        \
    return BK_ERR_INPUT;                                                             \
  } while (0)
    long long ll;
    if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
      bake_usage(stdout);
      return BK_OK;
    } else if (!strcmp(a, "-o") || !strcmp(a, "--output")) {
      NEED_VALUE();
      opt.out_path = val;
    } else if (!strcmp(a, "--frames")) {
      NEED_VALUE();
      opt.frames = val;
    } else if (!strcmp(a, "--force")) {
      opt.force = 1;
    } else if (!strcmp(a, "--mode")) {
      NEED_VALUE();
      if (!strcmp(val, "reference")) opt.mode = MODE_REFERENCE;
      else if (!strcmp(val, "adaptive")) opt.mode = MODE_ADAPTIVE;
      else BAD_VALUE("reference or adaptive");
    } else if (!strcmp(a, "--photons")) {
      NEED_VALUE();
      if (!parse_ll(val, &ll) || ll < 1) BAD_VALUE("a positive photon count");
      opt.photons = ll;
    } else if (!strcmp(a, "--integrator")) {
      NEED_VALUE();
      if (!strcmp(val, "euler")) opt.integrator = INTEGRATOR_EULER;
      else if (!strcmp(val, "rk4")) opt.integrator = INTEGRATOR_RK4;
      else BAD_VALUE("euler or rk4");
    } else if (!strcmp(a, "--step")) {
      NEED_VALUE();
      if (!parse_float(val, &opt.step) || !(opt.step > 0.0f)) BAD_VALUE("a positive step in voxels");
    } else if (!strcmp(a, "--seed")) {
      NEED_VALUE();
      if (!parse_ll(val, &ll) || ll < 0 || ll > UINT_MAX) BAD_VALUE("a seed in 0..4294967295");
      opt.seed = ll;
    } else if (!strcmp(a, "--resolution")) {
      NEED_VALUE();
      if (!parse_ll(val, &ll) || ll < 1 || ll > INT_MAX) BAD_VALUE("a positive voxel count");
      opt.resolution = (int)ll;
    } else if (!strcmp(a, "--compression")) {
      NEED_VALUE();
      if (!strcmp(val, "zip")) opt.write.compression = VDBIO_COMPRESS_ZIP;
      else if (!strcmp(val, "blosc")) opt.write.compression = VDBIO_COMPRESS_BLOSC;
      else if (!strcmp(val, "none")) opt.write.compression = VDBIO_COMPRESS_NONE;
      else BAD_VALUE("zip, blosc or none");
    } else if (!strcmp(a, "--no-filter")) {
      opt.no_filter = 1;
    } else if (!strcmp(a, "--write-filter-radius")) {
      opt.write_filter_radius = 1;
    } else if (!strcmp(a, "--half")) {
      opt.write.half_float = 1;
    } else if (!strcmp(a, "--device")) {
      NEED_VALUE();
      opt.device = val;
    } else if (!strcmp(a, "--host")) {
      opt.host_only = 1;
    } else if (bk_common_option(a)) {
    } else if (a[0] == '-' && a[1]) {
      fprintf(stderr, "baker bake: unknown option '%s' (see baker bake --help)\n", a);
      return BK_ERR_INPUT;
    } else if (!opt.scene_path) {
      opt.scene_path = a;
    } else {
      fprintf(stderr, "baker bake: unexpected argument '%s' (one scene per command)\n", a);
      return BK_ERR_INPUT;
    }
#undef NEED_VALUE
#undef BAD_VALUE
  }
  if (!opt.scene_path || !opt.out_path) {
    fprintf(stderr, "baker bake: %s\n\n", !opt.scene_path ? "no scene file given" : "no output given (-o OUT.vdb)");
    bake_usage(stderr);
    return BK_ERR_INPUT;
  }

  bk_error_t err = {0, ""};
  int rc = run_frames(&opt, &err);
  if (rc) fprintf(stderr, "baker bake: %s\n", err.msg);
  return rc;
}
