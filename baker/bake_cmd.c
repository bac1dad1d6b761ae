/* bake_cmd.c: the `baker bake` command: parses the options (getopt_long, so
 * `--photons=N` and `--photons N` alike) and hands them to the pipeline
 * (bake_run in bake.c). */
#include <errno.h>
#include <math.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "bake.h"
#include "budget.h"
#include "cmdline.h"
#include "shard.h"
#include "vdbio.h"
#include "base/common.h"

static void bake_usage(FILE *out) {
  fprintf(out,
          "usage: baker bake SCENE.json -o OUT.vdb [options]\n"
          "\n"
          "Voxelizes the scene's meshes into index-of-refraction and medium grids, traces\n"
          "photons along curved paths on OpenCL and writes the grids radiance, ior,\n"
          "extinction, scattering and density to OUT.vdb (DESIGN.md §5).\n"
          "\n"
          "SCENE `-` reads the scene from standard input (relative paths against the\n"
          "working directory).\n"
          "\n"
          "options:\n"
          "  -o, --output PATH        output .vdb (required; not `-`, not a directory);\n"
          "                           may hold a frame pattern\n"
          "  --frames LIST            frames to bake, in this order, each once: A, A-B,\n"
          "                           A-BxS or A-B:S, comma-separated (1-3,7,10-20x2);\n"
          "                           `####` (4 digits) or `$F4` in SCENE and PATH become\n"
          "                           the frame number. `--frames task`: the array task's\n"
          "                           frame ($SLURM_ARRAY_TASK_ID, $SGE_TASK_ID,\n"
          "                           $PBS_ARRAYID, $PBS_ARRAY_INDEX), also the default\n"
          "                           for a patterned PATH without --frames\n"
          "  --keep-going             bake the other frames after a failure; end with a\n"
          "                           per-frame summary (exit 1 if any failed at run\n"
          "                           time, 2 if only for bad input)\n"
          "  --force                  re-bake frames whose output is up to date (an output\n"
          "                           is skipped only when complete and baked from the\n"
          "                           same scene hash and settings; else re-baked)\n"
          "  --set KEY=VALUE          override a scene key before validation, by its path:\n"
          "                           medium.sigma_s=0.3, lights[0].intensity=[5,5,5],\n"
          "                           photons.integrator=rk4 (VALUE is JSON, else a string);\n"
          "                           repeatable\n"
          "  --mode reference|adaptive   photon pipeline (scene photons.mode)\n"
          "  --photons N              photon count (scene photons.count)\n"
          "  --no-filter              adaptive: skip the reconstruction filter (the raw,\n"
          "                           unbiased estimate)\n"
          "  --write-filter-radius    adaptive: also write the filter_radius grid (debug)\n"
          "  --integrator euler|rk4   ray-equation integrator (scene photons.integrator)\n"
          "  --step VOXELS            march step in refractive regions, at least 1/1024\n"
          "                           (scene photons.step)\n"
          "  --seed N                 sampling seed (scene photons.seed)\n"
          "  --batches N              trace the photons in N independent batches, whose\n"
          "                           spread measures the noise (scene photons.batches,\n"
          "                           default 4, 8 with a target or budget; 1 = one\n"
          "                           Hammersley set, no noise estimate)\n"
          "  --target-error E         add batches until the estimated error (relative RMS\n"
          "                           over lit voxels, docs/error.md) is at most E, in\n"
          "                           (0, 1] (scene photons.target_error)\n"
          "  --time-budget S          stop adding batches when the next would end the\n"
          "                           photon march past S seconds (photons.time_budget_s)\n"
          "  --error-grid             also write the float grid radiance_error: each\n"
          "                           voxel's standard error of the luminance of radiance\n"
          "  --stats PATH.json        write each frame's stage times, photon counts, peak\n"
          "                           memory and error terms as JSON (may hold a frame\n"
          "                           pattern; without one each frame overwrites it)\n"
          "  --resolution N           voxels along the longest side (scene grid.resolution)\n"
          "  --compression zip|blosc|none   VDB compression (default blosc: about half\n"
          "                           the write time of zip and smaller here; Houdini's\n"
          "                           and Blender's OpenVDB read both)\n"
          "  --half                   store float grids as 16-bit half\n"
          "  --device SPEC            OpenCL device: `P:D` indices or a name substring;\n"
          "                           default PoCL (CPU). `baker devices` lists them\n"
          "  --host                   march on the host in plain C instead of OpenCL\n"
          "  --shard I/N              trace only the I-th of N slices of the photons and\n"
          "                           write their raw sums (a shard); `baker merge` adds\n"
          "                           the N shards into the bake, bit for bit\n"
          "  --max-memory SIZE        refuse a bake whose estimated peak memory exceeds\n"
          "                           SIZE (e.g. 8G, 500M) instead of the memory this\n"
          "                           machine has available\n"
          "  --progress[=json]        show progress even when stderr is not a terminal;\n"
          "                           =json: one JSON object per line on stderr\n"
          "                           {\"stage\",\"fraction\",\"eta_s\",\"frame\"}\n"
          "  --threads N              at most N host threads and PoCL CPU threads\n"
          "  --log FILE               append every message to FILE as well\n"
          "  -q, --quiet              errors only (no timing table)\n"
          "  -v, --verbose            more detail (OpenCL build logs, cache use)\n"
          "  -h, --help               this text\n"
          "\n"
          "Exit status: 0 success, 2 bad input or usage, 1 runtime failure.\n");
}

/* values of the long-only options */
enum {
  OPT_FRAMES = CMD_FIRST_OWN, OPT_FORCE, OPT_MODE, OPT_PHOTONS, OPT_INTEGRATOR, OPT_STEP,
  OPT_SEED, OPT_RESOLUTION, OPT_COMPRESSION, OPT_NO_FILTER, OPT_WRITE_FILTER_RADIUS, OPT_HALF,
  OPT_DEVICE, OPT_HOST, OPT_KEEP_GOING, OPT_SET, OPT_MAX_MEMORY, OPT_SHARD,
  OPT_BATCHES, OPT_TARGET_ERROR,
  OPT_TIME_BUDGET, OPT_ERROR_GRID, OPT_STATS
};

static const struct option bake_longopts[] = {
    {"output", required_argument, NULL, 'o'},
    {"frames", required_argument, NULL, OPT_FRAMES},
    {"force", no_argument, NULL, OPT_FORCE},
    {"mode", required_argument, NULL, OPT_MODE},
    {"photons", required_argument, NULL, OPT_PHOTONS},
    {"integrator", required_argument, NULL, OPT_INTEGRATOR},
    {"step", required_argument, NULL, OPT_STEP},
    {"seed", required_argument, NULL, OPT_SEED},
    {"resolution", required_argument, NULL, OPT_RESOLUTION},
    {"compression", required_argument, NULL, OPT_COMPRESSION},
    {"no-filter", no_argument, NULL, OPT_NO_FILTER},
    {"write-filter-radius", no_argument, NULL, OPT_WRITE_FILTER_RADIUS},
    {"half", no_argument, NULL, OPT_HALF},
    {"device", required_argument, NULL, OPT_DEVICE},
    {"host", no_argument, NULL, OPT_HOST},
    {"keep-going", no_argument, NULL, OPT_KEEP_GOING},
    {"set", required_argument, NULL, OPT_SET},
    {"max-memory", required_argument, NULL, OPT_MAX_MEMORY},
    {"shard", required_argument, NULL, OPT_SHARD},
    {"batches", required_argument, NULL, OPT_BATCHES},
    {"target-error", required_argument, NULL, OPT_TARGET_ERROR},
    {"time-budget", required_argument, NULL, OPT_TIME_BUDGET},
    {"error-grid", no_argument, NULL, OPT_ERROR_GRID},
    {"stats", required_argument, NULL, OPT_STATS},
    CMD_COMMON_LONGOPTS,
    {NULL, 0, NULL, 0}};

/* Applies option c with value val; BK_OK or BK_ERR_INPUT with the message in err. */
static int bake_option(bake_options_t *opt, const char **sets, int c, const char *name,
                       const char *val, bk_error_t *err) {
  long long ll;
  float f;
  const char *want = NULL;
  switch (c) {
  case 'o': opt->out_path = val; break;
  case OPT_FRAMES: opt->frames = val; break;
  case OPT_FORCE: opt->force = 1; break;
  case OPT_MODE:
    if (!strcmp(val, "reference")) opt->mode = MODE_REFERENCE;
    else if (!strcmp(val, "adaptive")) opt->mode = MODE_ADAPTIVE;
    else want = "reference or adaptive";
    break;
  case OPT_PHOTONS:
    if (!cmd_parse_ll(val, &ll) || ll < 1) want = "a positive photon count";
    else opt->photons = ll;
    break;
  case OPT_INTEGRATOR:
    if (!strcmp(val, "euler")) opt->integrator = INTEGRATOR_EULER;
    else if (!strcmp(val, "rk4")) opt->integrator = INTEGRATOR_RK4;
    else want = "euler or rk4";
    break;
  case OPT_STEP:
    if (!cmd_parse_float(val, &opt->step) || !(opt->step >= SCENE_MIN_STEP))
      want = "a step in voxels of at least 1/1024 (0.0009765625)";
    break;
  case OPT_SEED:
    if (!cmd_parse_ll(val, &ll) || ll < 0 || ll > UINT_MAX) want = "a seed in 0..4294967295";
    else opt->seed = ll;
    break;
  case OPT_RESOLUTION:
    if (!cmd_parse_ll(val, &ll) || ll < 1 || ll > INT_MAX) want = "a positive voxel count";
    else opt->resolution = (int)ll;
    break;
  case OPT_COMPRESSION:
    if (!strcmp(val, "zip")) opt->write.compression = VDBIO_COMPRESS_ZIP;
    else if (!strcmp(val, "blosc")) opt->write.compression = VDBIO_COMPRESS_BLOSC;
    else if (!strcmp(val, "none")) opt->write.compression = VDBIO_COMPRESS_NONE;
    else want = "zip, blosc or none";
    break;
  case OPT_NO_FILTER: opt->no_filter = 1; break;
  case OPT_WRITE_FILTER_RADIUS: opt->write_filter_radius = 1; break;
  case OPT_HALF: opt->write.half_float = 1; break;
  case OPT_DEVICE: opt->device = val; break;
  case OPT_HOST: opt->host_only = 1; break;
  case OPT_KEEP_GOING: opt->keep_going = 1; break;
  case OPT_MAX_MEMORY:
    if (!budget_parse_size(val, &opt->max_memory)) want = "a size such as 8G or 500M";
    break;
  case OPT_SHARD: return shard_parse(val, &opt->shard_index, &opt->shard_count, err);
  case OPT_BATCHES:
    if (!cmd_parse_ll(val, &ll) || ll < 1 || ll > 65536) want = "a batch count in 1..65536";
    else opt->batches = (int)ll;
    break;
  case OPT_TARGET_ERROR:
    if (!cmd_parse_float(val, &f) || !isfinite(f) || !(f > 0.0f) || f > 1.0f)
      want = "a relative error in (0, 1], e.g. 0.05";
    else opt->target_error = f;
    break;
  case OPT_TIME_BUDGET:
    if (!cmd_parse_float(val, &f) || !isfinite(f) || !(f > 0.0f))
      want = "a positive number of seconds";
    else opt->time_budget_s = f;
    break;
  case OPT_ERROR_GRID: opt->error_grid = 1; break;
  case OPT_STATS: opt->stats_path = val; break;
  case OPT_SET:
    if (!strchr(val, '=') || val[0] == '=') want = "KEY=VALUE (e.g. medium.sigma_s=0.3)";
    else sets[opt->set_count++] = val;
    break;
  }
  if (want) return bk_fail(err, BK_ERR_INPUT, "%s: expected %s, got '%s'", name, want, val);
  return BK_OK;
}

/* Returns CMD_HELP or CMD_VERSION for those (exit 0), else an exit status. */
static int bake_parse(int argc, char **argv, bake_options_t *opt, const char **sets,
                      bk_error_t *err) {
  cmd_parser_t p;
  int c;
  bake_options_defaults(opt);
  opt->sets = sets;
  cmd_begin(&p, argc, argv, "bake", "o:" CMD_COMMON_SHORTOPTS, bake_longopts);
  while ((c = cmd_next(&p, err)) != CMD_END) {
    if (c == CMD_ERROR) return err->code;
    if (c == CMD_HELP || c == CMD_VERSION) return c;
    if (c != CMD_POSITIONAL) {
      if (bake_option(opt, sets, c, p.opt, p.arg, err)) return err->code;
    } else if (!opt->scene_path) {
      opt->scene_path = p.arg;
    } else {
      return bk_fail(err, BK_ERR_INPUT, "unexpected argument '%s' (one scene per command)",
                     p.arg);
    }
  }
  return BK_OK;
}

/* Parses, then bakes; `sets` holds room for every --set of argv. */
static int bake_command(int argc, char **argv, const char **sets) {
  bake_options_t opt;
  bk_error_t err = {0, ""};
  int rc = bake_parse(argc, argv, &opt, sets, &err);
  if (rc == CMD_HELP) bake_usage(stdout);
  else if (rc == CMD_VERSION) cmd_print_version();
  if (rc == CMD_HELP || rc == CMD_VERSION) return BK_OK;
  if (rc) {
    bk_report("bake", err.msg);
    return rc;
  }
  if (!opt.scene_path || !opt.out_path) {
    fprintf(stderr, "baker bake: %s\n\n",
            !opt.scene_path ? "no scene file given" : "no output given (-o OUT.vdb)");
    bake_usage(stderr);
    return BK_ERR_INPUT;
  }
  if (opt.shard_count && vdbio_is_nano_path(opt.out_path)) {
    bk_report("bake", "--shard: a shard is written as .vdb (its metadata goes to the merge; "
                      "NanoVDB files carry none)");
    return BK_ERR_INPUT;
  }
  rc = bake_run(&opt, &err);
  if (rc) bk_report("bake", err.msg);
  return rc;
}

int bake_main(int argc, char **argv) {
  const char **sets = calloc((size_t)argc + 1, sizeof *sets); /* --set texts, in order */
  if (!sets) return BK_ERR_RUNTIME;
  int rc = bake_command(argc, argv, sets);
  free(sets);
  return rc;
}
