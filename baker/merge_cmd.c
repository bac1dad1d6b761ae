/* merge_cmd.c: `baker merge SHARD.vdb... -o OUT.vdb`: adds the raw sums of
 * photon shards (shard.h) as integers and finishes them as the bake does
 * after its march (normalisation; adaptive: unpacking and the filter), then
 * writes the frame's normal grids and metadata. Every shard must come from
 * the same scene and settings (shard_key, the medium grids' checksums, the
 * sums' scales), each index 1..N exactly once; otherwise nothing is written
 * and the exit status is 2. */
#define _POSIX_C_SOURCE 200809L
#include "merge.h"

#include <sys/stat.h>

#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "adaptive.h"
#include "bake.h"
#include "base/common.h"
#include "base/grid.h"
#include "cmdline.h"
#include "shard.h"
#include "vdbio.h"

static void merge_usage(FILE *out) {
  fprintf(out,
          "usage: baker merge SHARD.vdb [SHARD.vdb ...] -o OUT.vdb [options]\n"
          "\n"
          "Adds the photon sums of the shards of one frame (`baker bake --shard I/N`),\n"
          "exactly, and writes the grids the single bake would write: the same radiance,\n"
          "bit for bit, in reference mode. All N shards of the same scene and settings\n"
          "must be given, each once, in any order.\n"
          "\n"
          "options:\n"
          "  -o, --output PATH   the merged .vdb (required; not one of the shards)\n"
          "  --threads N         at most N host threads\n"
          "  --log FILE          append every message to FILE as well\n"
          "  -q, --quiet         errors only\n"
          "  -v, --verbose       more detail\n"
          "  -h, --help          this text\n"
          "\n"
          "Exit status: 0 success, 2 bad input (shards that do not belong together,\n"
          "a missing or repeated shard, a file that is not a shard), 1 runtime failure.\n");
}

/* One shard file: its metadata and the fields the merge checks. */
typedef struct merge_shard {
  const char *path;
  vdbio_meta_entry_t *meta;
  int meta_count;
  long long index, count, first, last, photons, stride, channels, mode;
} merge_shard_t;

static const char *meta_get(const merge_shard_t *s, const char *key) {
  for (int i = 0; i < s->meta_count; i++)
    if (!strcmp(s->meta[i].key, key)) return s->meta[i].value;
  return NULL;
}

/* Reads the shard's metadata and its integer fields. */
static int read_shard(merge_shard_t *s, bk_error_t *err) {
  int rc = vdbio_read_meta_all(s->path, &s->meta, &s->meta_count, err);
  if (rc) return rc;
  struct { const char *key; long long *v; } ints[] = {
      {"shard_index", &s->index},       {"shard_count", &s->count},
      {"shard_photon_first", &s->first}, {"shard_photon_last", &s->last},
      {"shard_photons", &s->photons},   {"shard_sum_stride", &s->stride},
      {"shard_sum_channels", &s->channels}, {"shard_sum_mode", &s->mode}};
  const char *need[] = {"shard_key", "shard_sum_scales", "shard_grid", "shard_ior_background",
                        "bake_settings"};
  for (size_t i = 0; i < sizeof need / sizeof need[0]; i++)
    if (!meta_get(s, need[i]))
      return bk_fail(err, BK_ERR_INPUT, "%s: not a photon shard (no %s metadata; make shards "
                     "with `baker bake --shard I/N`)", s->path, need[i]);
  for (size_t i = 0; i < sizeof ints / sizeof ints[0]; i++) {
    const char *v = meta_get(s, ints[i].key);
    if (!v || !cmd_parse_ll(v, ints[i].v))
      return bk_fail(err, BK_ERR_INPUT, "%s: not a photon shard (%s missing or not a number)",
                     s->path, ints[i].key);
  }
  if (s->count < 1 || s->count > SHARD_MAX_COUNT || s->photons < 0 || s->first < 0 ||
      s->last < s->first)
    return bk_fail(err, BK_ERR_INPUT, "%s: shard %lld/%lld of photons [%lld, %lld) of %lld: "
                   "not a shard this baker writes", s->path, s->index, s->count, s->first,
                   s->last, s->photons);
  if (s->stride < 1 || s->stride > SHARD_MAX_STRIDE || (s->channels != 1 && s->channels != 3))
    return bk_fail(err, BK_ERR_INPUT, "%s: shard_sum_stride %lld / shard_sum_channels %lld: "
                   "not a layout this baker writes", s->path, s->stride, s->channels);
  return BK_OK;
}

/* What must be equal in every shard: the scene and settings, the medium the
 * photons crossed (its grids' checksums: a mesh or VDB changed between two
 * shards), and the sums' layout and scales. */
static const char *const SAME_KEYS[] = {
    "shard_key", "shard_photon_order", "shard_count", "shard_photons", "shard_sum_stride", "shard_sum_channels",
    "shard_sum_mode", "shard_sum_flux", "shard_sum_scales", "shard_grid", "shard_ior_background", "shard_filter",
    "shard_sum_camera", "radiance_camera_position",
    "checksum_v2_ior", "checksum_v2_extinction", "checksum_v2_scattering", "checksum_v2_density"};

static int check_together(const merge_shard_t *sh, int n, bk_error_t *err) {
  for (int i = 1; i < n; i++)
    for (size_t k = 0; k < sizeof SAME_KEYS / sizeof SAME_KEYS[0]; k++) {
      const char *a = meta_get(&sh[0], SAME_KEYS[k]), *b = meta_get(&sh[i], SAME_KEYS[k]);
      if ((a == NULL) != (b == NULL) || (a && strcmp(a, b)))
        return bk_fail(err, BK_ERR_INPUT,
                       "%s and %s are not shards of one bake: %s differs (%s vs %s); shards "
                       "must come from the same scene, settings and meshes",
                       sh[0].path, sh[i].path, SAME_KEYS[k], a ? a : "absent", b ? b : "absent");
    }
  return BK_OK;
}

/* Each index 1..N once, with the photon range it must have. */
static int check_complete(const merge_shard_t *sh, int n, bk_error_t *err) {
  const long long N = sh[0].count;
  for (int i = 0; i < n; i++) {
    uint64_t f, l;
    if (sh[i].index < 1 || sh[i].index > N)
      return bk_fail(err, BK_ERR_INPUT, "%s: shard %lld of %lld is out of range", sh[i].path,
                     sh[i].index, N);
    shard_range((uint64_t)sh[i].photons, (int)sh[i].index, (int)N, &f, &l);
    if ((uint64_t)sh[i].first != f || (uint64_t)sh[i].last != l)
      return bk_fail(err, BK_ERR_INPUT, "%s: shard %lld/%lld covers photons [%lld, %lld), "
                     "expected [%" PRIu64 ", %" PRIu64 ")", sh[i].path, sh[i].index, N,
                     sh[i].first, sh[i].last, f, l);
    for (int j = 0; j < i; j++)
      if (sh[j].index == sh[i].index)
        return bk_fail(err, BK_ERR_INPUT, "%s and %s are both shard %lld/%lld: each shard "
                       "must be given once", sh[j].path, sh[i].path, sh[i].index, N);
  }
  if (n != N) {
    char missing[256] = "";
    size_t at = 0;
    for (long long k = 1; k <= N && at + 24 < sizeof missing; k++) {
      int seen = 0;
      for (int i = 0; i < n; i++) seen |= sh[i].index == k;
      if (!seen)
        at += (size_t)snprintf(missing + at, sizeof missing - at, "%s%lld", at ? ", " : "", k);
    }
    return bk_fail(err, BK_ERR_INPUT, "%d of %lld shards given: missing shard(s) %s of %lld "
                   "(from %s)", n, N, missing, N, sh[0].path);
  }
  return BK_OK;
}

/* The grid the shards were baked on (exact: hex floats). */
static int shard_dims(const merge_shard_t *s, grid_dims_t *d, bk_error_t *err) {
  double vs, o[3];
  memset(d, 0, sizeof *d);
  if (sscanf(meta_get(s, "shard_grid"), "%d %d %d %la %la %la %la", &d->nx, &d->ny, &d->nz, &vs,
             &o[0], &o[1], &o[2]) != 7 || d->nx < 1 || d->ny < 1 || d->nz < 1 ||
      d->nx > GRID_MAX_AXIS || d->ny > GRID_MAX_AXIS || d->nz > GRID_MAX_AXIS || !(vs > 0.0))
    return bk_fail(err, BK_ERR_INPUT, "%s: shard_grid '%s' is not a grid", s->path,
                   meta_get(s, "shard_grid"));
  d->voxel_size = (float)vs;
  for (int a = 0; a < 3; a++) d->origin[a] = (float)o[a];
  return BK_OK;
}

/* The sums and their scales, added over the shards. */
static int add_sums(const merge_shard_t *sh, int n, const grid_dims_t *d, pm_sums_t *k,
                    bk_error_t *err) {
  memset(k, 0, sizeof *k);
  k->voxels = grid_count(d);
  k->channels = (int)sh[0].channels;
  k->stride = (int)sh[0].stride;
  k->mode = (int)sh[0].mode;
  double ws = 0.0;
  if (sscanf(meta_get(&sh[0], "shard_sum_scales"), "%la %la %la %u %la", &k->to_radiance[0],
             &k->to_radiance[1], &k->to_radiance[2], &k->count_shift, &ws) != 5)
    return bk_fail(err, BK_ERR_INPUT, "%s: shard_sum_scales is not readable", sh[0].path);
  k->weight_scale = (float)ws;
  k->flux = meta_get(&sh[0], "shard_sum_flux") != NULL;
  const char *cam = meta_get(&sh[0], "shard_sum_camera");
  double cs = 0.0;
  if (cam && (sscanf(cam, "%la", &cs) != 1 || !(cs > 0.0 && cs <= 1.0) || !k->flux))
    return bk_fail(err, BK_ERR_INPUT, "%s: shard_sum_camera \"%s\" is not a scale in (0, 1]",
                   sh[0].path, cam);
  k->camera = cam != NULL;
  k->cam_scale = (float)cs;
  const int fslots = PM_FLUX_SLOTS_WITH(k->camera), slots = k->stride + (k->flux ? fslots : 0);
  int rc = grid_check_memory(d, (size_t)slots * (sizeof(uint64_t) + 3 * sizeof(float)),
                             sh[0].path, err);
  if (rc) return rc;
  k->acc = bk_calloc(k->voxels, (size_t)slots * sizeof(uint64_t), "merge: sums", err);
  float *enc = bk_calloc(k->voxels, 3 * sizeof(float), "merge: shard sum grid", err);
  if (!k->acc || !enc) {
    free(enc);
    return BK_ERR_RUNTIME;
  }
  for (int i = 0; i < n && !rc; i++)
    for (int s = 0; s < slots && !rc; s++) {
      char name[32];
      const int f = s - k->stride; /* >= 0: a flux counter (shard.c shard_grids) */
      snprintf(name, sizeof name, f < 0 ? "shard_sum_%d" : "shard_flux_%d", f < 0 ? s : f);
      if (!(rc = vdbio_read_box(sh[i].path, name, d, 3, enc, err)) &&
          !(f < 0 ? shard_decode_add(enc, k->voxels, k->stride, s, k->acc)
                  : shard_decode_add(enc, k->voxels, fslots, f,
                                     k->acc + k->voxels * k->stride)))
        rc = bk_fail(err, BK_ERR_INPUT, "%s: grid %s holds values that are not sums of this "
                     "baker (a corrupt shard)", sh[i].path, name);
    }
  free(enc);
  return rc;
}

/* The merged frame: its grids (NULL: not written) and statistics. */
typedef struct merge_out {
  grid_dims_t dims;
  int sca_channels;
  float medium_ior;
  float *ior, *extinction, *scattering, *density, *radiance, *count, *weight, *radius;
  float *ior_rgb; /* dispersion: the shards' n per channel */
  float *flux, *uncollided, *phase_g; /* the shards kept the flux (some g != 0) */
  ad_stats_t astats;
} merge_out_t;

static void merge_out_free(merge_out_t *o) {
  float *all[] = {o->ior,   o->extinction, o->scattering, o->density, o->radiance,
                  o->count, o->weight,     o->radius,     o->ior_rgb, o->flux,
                  o->uncollided, o->phase_g};
  for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) free(all[i]);
}

/* The medium grids, as the first shard holds them (the others' checksums
 * are equal: check_together). */
static int read_medium(const merge_shard_t *s, merge_out_t *o, bk_error_t *err) {
  char **names = NULL, **types = NULL;
  int count = 0, rc = vdbio_list_grids(s->path, &names, &types, &count, err);
  if (rc) return rc;
  o->sca_channels = 0;
  int dispersion = 0;
  for (int i = 0; i < count; i++) {
    if (!strcmp(names[i], "scattering")) o->sca_channels = strcmp(types[i], "float") ? 3 : 1;
    dispersion |= !strcmp(names[i], "ior_rgb");
  }
  vdbio_free_names(names, types, count);
  if (!o->sca_channels)
    return bk_fail(err, BK_ERR_INPUT, "%s: the shard has no scattering grid", s->path);
  double bg;
  if (sscanf(meta_get(s, "shard_ior_background"), "%la", &bg) != 1)
    return bk_fail(err, BK_ERR_INPUT, "%s: shard_ior_background is not a number", s->path);
  o->medium_ior = (float)bg;
  const size_t n = grid_count(&o->dims), mc = (size_t)o->sca_channels;
  struct { const char *name; float **out; size_t ch; } g[] = {
      {"ior", &o->ior, 1}, {"extinction", &o->extinction, mc},
      {"scattering", &o->scattering, mc}, {"density", &o->density, 1}, {"ior_rgb", &o->ior_rgb, 3}};
  for (size_t i = 0; i < sizeof g / sizeof g[0] - !dispersion && !rc; i++) {
    *g[i].out = bk_calloc(n, g[i].ch * sizeof(float), g[i].name, err);
    rc = *g[i].out ? vdbio_read_box(s->path, g[i].name, &o->dims, (int)g[i].ch, *g[i].out, err)
                   : BK_ERR_RUNTIME;
  }
  return rc;
}

/* What the bake does after its march: normalisation, and in adaptive mode
 * the unpacking and the filter as the shards recorded them (on the host). */
static int finish(const merge_shard_t *s, const pm_sums_t *k, merge_out_t *o, bk_error_t *err) {
  const size_t n = k->voxels;
  if (!(o->radiance = bk_calloc(n, 3 * sizeof(float), "radiance grid", err))) return err->code;
  if (k->mode == PM_MODE_REFERENCE) {
    pm_setup_t setup;
    pm_sums_setup(k, &setup);
    pm_to_radiance(&setup, k->acc, o->radiance, 3);
    if (!k->flux) return BK_OK;
    o->flux = bk_calloc(n, 3 * sizeof(float), "radiance_flux grid", err);
    o->uncollided = bk_calloc(n, (size_t)pm_uncollided_floats(&setup) * sizeof(float),
                              "radiance_uncollided grids", err);
    if (!o->flux || !o->uncollided) return err->code;
    pm_to_flux(&setup, k->acc, o->flux, o->uncollided);
    if (!(o->phase_g = bk_calloc(n, sizeof(float), "phase_g grid", err))) return err->code;
    return vdbio_read_box(s->path, "phase_g", &o->dims, 1, o->phase_g, err);
  }
  const char *f = meta_get(s, "shard_filter");
  ad_bake_opts_t ao;
  ad_bake_defaults(&ao);
  double max_radius, noise_k, alpha;
  int radius_grid;
  if (!f || sscanf(f, "filter=%d max_radius=%la noise_k=%la alpha=%la radius_grid=%d",
                   &ao.filter, &max_radius, &noise_k, &alpha, &radius_grid) != 5)
    return bk_fail(err, BK_ERR_INPUT, "%s: adaptive shard without a readable shard_filter",
                   s->path);
  ao.max_radius = (float)max_radius;
  ao.noise_k = (float)noise_k;
  o->count = bk_calloc(n, sizeof(float), "photon_count grid", err);
  o->weight = bk_calloc(n, sizeof(float), "photon_weight grid", err);
  if (radius_grid) o->radius = bk_calloc(n, sizeof(float), "filter_radius grid", err);
  if (!o->count || !o->weight || (radius_grid && !o->radius)) return err->code;
  return ad_finish(NULL, &o->dims, k, &ao, (float)alpha, o->radiance, o->count, o->weight,
                   o->radius, &o->astats, err);
}

#define MERGE_META_MAX 80

/* Texts the merged metadata points to. */
typedef struct merge_text {
  char settings[4096], devices[512], shards[4096];
  long long sums[6];
} merge_text_t;

static const char *const SUM_KEYS[6] = {"photon_count",      "photons_missed_grid",
                                        "photons_left_grid", "photons_absorbed",
                                        "photons_step_limit", "photon_steps"};

/* The first shard's metadata less the shard's own keys and checksums (the
 * writer makes new ones), with photon counts summed, the settings of the
 * whole bake, the filter as the merge ran it, and the shards merged. */
static int merged_meta(const merge_shard_t *sh, int n, const merge_out_t *o, merge_text_t *t,
                       vdbio_meta_t *meta) {
  int m = 0;
  memset(t->sums, 0, sizeof t->sums);
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 6; k++) {
      const char *v = meta_get(&sh[i], SUM_KEYS[k]);
      t->sums[k] += v ? strtoll(v, NULL, 10) : 0;
    }
  snprintf(t->settings, sizeof t->settings, "%s", meta_get(&sh[0], "bake_settings"));
  char *cut = strstr(t->settings, " shard=");
  if (cut) *cut = 0;
  size_t at = 0;
  t->devices[0] = 0;
  for (int i = 0; i < n; i++) {
    const char *d = meta_get(&sh[i], "opencl_device");
    if (d && !strstr(t->devices, d) && at + strlen(d) + 3 < sizeof t->devices)
      at += (size_t)snprintf(t->devices + at, sizeof t->devices - at, "%s%s", at ? "; " : "", d);
  }
  at = 0;
  for (int i = 0; i < n && at + 64 < sizeof t->shards; i++)
    at += (size_t)snprintf(t->shards + at, sizeof t->shards - at, "%s%lld/%lld [%lld,%lld) %s",
                           i ? "; " : "", sh[i].index, sh[i].count, sh[i].first, sh[i].last,
                           sh[i].path);
  for (int i = 0; i < sh[0].meta_count && m < MERGE_META_MAX - 2; i++) {
    const vdbio_meta_entry_t *e = &sh[0].meta[i];
    if (!strncmp(e->key, "shard_", 6) || !strncmp(e->key, "checksum_", 9)) continue;
    vdbio_meta_t out = {e->key, e->kind, e->value, 0, 0.0};
    if (e->kind == VDBIO_META_INT) out.i = strtoll(e->value, NULL, 10);
    if (e->kind == VDBIO_META_FLOAT) out.f = strtod(e->value, NULL);
    for (int k = 0; k < 6; k++)
      if (!strcmp(e->key, SUM_KEYS[k])) out.i = t->sums[k];
    if (!strcmp(e->key, "bake_settings")) out.s = t->settings;
    if (!strcmp(e->key, "opencl_device")) out.s = t->devices;
    if (!strcmp(e->key, "adaptive_filter")) out.s = o->astats.filtered ? "on" : "off";
    meta[m++] = out;
  }
  meta[m++] = (vdbio_meta_t){"merged_shard_count", VDBIO_META_INT, NULL, n, 0};
  meta[m++] = (vdbio_meta_t){"merged_shards", VDBIO_META_STRING, t->shards, 0, 0};
  return m;
}

/* The compression and half-float choice the shards were baked with. */
static vdbio_write_opts_t write_opts(const char *settings) {
  vdbio_write_opts_t w = {VDBIO_COMPRESS_BLOSC, 0, NULL, NULL};
  if (strstr(settings, "compression=zip")) w.compression = VDBIO_COMPRESS_ZIP;
  if (strstr(settings, "compression=none")) w.compression = VDBIO_COMPRESS_NONE;
  w.half_float = strstr(settings, " half=1") != NULL;
  return w;
}

static int same_file(const char *a, const char *b) {
  struct stat sa, sb;
  if (!strcmp(a, b)) return 1;
  return stat(a, &sa) == 0 && stat(b, &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

/* Reads, checks, adds, finishes and writes. */
static int merge_run(merge_shard_t *sh, int n, const char *out_path, bk_error_t *err) {
  merge_out_t o;
  pm_sums_t sums = {0};
  merge_text_t text;
  vdbio_meta_t meta[MERGE_META_MAX];
  vdbio_grid_t grids[BAKE_MAX_GRIDS];
  memset(&o, 0, sizeof o);
  for (int i = 0; i < n; i++)
    if (same_file(sh[i].path, out_path))
      return bk_fail(err, BK_ERR_INPUT, "-o %s: the output is one of the shards", out_path);
  int rc = bk_check_output_dir(out_path, err);
  for (int i = 0; i < n && !rc; i++) rc = read_shard(&sh[i], err);
  if (!rc) rc = check_together(sh, n, err);
  if (!rc) rc = check_complete(sh, n, err);
  if (!rc) rc = shard_dims(&sh[0], &o.dims, err);
  if (!rc) rc = add_sums(sh, n, &o.dims, &sums, err);
  if (!rc) rc = read_medium(&sh[0], &o, err);
  if (!rc) rc = finish(&sh[0], &sums, &o, err);
  if (!rc) {
    /* emission = scattering ⊙ radiance, made as the writer builds its tree */
    og_source_t src = {.scattering = o.scattering, .sca_channels = o.sca_channels,
                       .radiance = o.radiance, .voxels = sums.voxels};
    bake_arrays_t a = {og_dense(o.ior), og_dense(o.radiance), og_dense(o.extinction), og_dense(o.scattering),
                       og_dense(o.density), og_made(og_emission, &src),
                       o.count, o.weight, o.radius, o.sca_channels, o.medium_ior,
                       og_dense(o.ior_rgb), o.flux, o.uncollided, og_dense(o.phase_g),
                       o.uncollided ? pm_flux_uncollided(o.uncollided, sums.voxels) : NULL,
                       o.uncollided && sums.camera ? pm_radiance_camera(o.uncollided, sums.voxels)
                                                   : NULL};
    int count = bake_grid_list(&a, grids);
    int mc = merged_meta(sh, n, &o, &text, meta);
    vdbio_write_opts_t w = write_opts(text.settings);
    rc = vdbio_write(out_path, &o.dims, grids, count, meta, mc, &w, err);
  }
  if (!rc && bk_verbosity >= 1)
    printf("merged %d shard(s) of %lld photons -> %s (%dx%dx%d voxels)\n", n, sh[0].photons,
           out_path, o.dims.nx, o.dims.ny, o.dims.nz);
  pm_sums_free(&sums);
  merge_out_free(&o);
  return rc;
}

static const struct option merge_longopts[] = {{"output", required_argument, NULL, 'o'},
                                               CMD_COMMON_LONGOPTS,
                                               {NULL, 0, NULL, 0}};

int merge_main(int argc, char **argv) {
  cmd_parser_t p;
  bk_error_t err = {0, ""};
  const char *out = NULL;
  merge_shard_t *sh = calloc((size_t)argc + 1, sizeof *sh);
  int n = 0, c, rc = BK_OK;
  if (!sh) return BK_ERR_RUNTIME;
  cmd_begin(&p, argc, argv, "merge", "o:" CMD_COMMON_SHORTOPTS, merge_longopts);
  while (!rc && (c = cmd_next(&p, &err)) != CMD_END) {
    if (c == CMD_ERROR) rc = err.code;
    else if (c == CMD_HELP || c == CMD_VERSION) {
      if (c == CMD_HELP) merge_usage(stdout);
      else cmd_print_version();
      free(sh);
      return BK_OK;
    } else if (c == 'o') out = p.arg;
    else if (c == CMD_POSITIONAL) sh[n++].path = p.arg;
  }
  if (!rc && (!out || n == 0)) {
    fprintf(stderr, "baker merge: %s\n\n",
            !out ? "no output given (-o OUT.vdb)" : "no shards given");
    merge_usage(stderr);
    rc = BK_ERR_INPUT;
  } else if (!rc) {
    rc = merge_run(sh, n, out, &err);
  }
  if (rc && err.msg[0]) bk_report("merge", err.msg);
  for (int i = 0; i < n; i++) free(sh[i].meta);
  free(sh);
  return rc;
}
