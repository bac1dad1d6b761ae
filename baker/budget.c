/* budget.c: the bake's peak memory before anything is allocated (see
 * budget.h). */
#include "budget.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "march.h"
#include "vdbio.h"
#include "vox_crop.h"

/* Some medium has g != 0: the march keeps the flux too. */
static int budget_anisotropic(const scene_t *s) {
  int any = s->medium_g != 0.0f;
  for (int i = 0; i < s->object_count; i++) any |= s->objects[i].g != 0.0f;
  return any;
}

/* R = G = B for both coefficients of the medium and of every object: the
 * volume is grey (a density VDB scales the channels alike), and stores σ
 * once per voxel (voxelize.h). */
int budget_grey(const scene_t *s) {
  int grey = s->medium_sigma_s[0] == s->medium_sigma_s[1] &&
             s->medium_sigma_s[0] == s->medium_sigma_s[2] &&
             s->medium_sigma_a[0] == s->medium_sigma_a[1] &&
             s->medium_sigma_a[0] == s->medium_sigma_a[2];
  for (int i = 0; i < s->object_count; i++) {
    const scene_object_t *o = &s->objects[i];
    grey &= o->sigma_s[0] == o->sigma_s[1] && o->sigma_s[0] == o->sigma_s[2] &&
            o->sigma_a[0] == o->sigma_a[1] && o->sigma_a[0] == o->sigma_a[2];
  }
  return grey;
}

double budget_shard_bytes(const scene_t *s) {
  return budget_grey(s) ? BUDGET_SHARD_GREY_BYTES : BUDGET_SHARD_BYTES;
}

double budget_output_bytes(const scene_t *s, const char *out_path) {
  return vdbio_is_nano_path(out_path) && budget_grey(s) ? BUDGET_NANOVDB_GREY_BYTES : 0.0;
}

/* The objects' world box as given (NULL: the bake does not crop, and the
 * box is never read: zeros). */
static void box_of(const float (*given)[3], float box[2][3]) {
  memset(box, 0, 2 * 3 * sizeof(float));
  if (given) memcpy(box, given, 2 * 3 * sizeof(float));
}

/* The grid the bake allocates: the scene's, or its crop around the
 * objects' world box (vox_crop.h). */
static int grid_in(const scene_t *s, int resolution, const float box[2][3], grid_dims_t *d,
                   bk_error_t *err) {
  grid_dims_t whole;
  int off[3], cropped;
  return vox_grid_for(s, resolution, box[0], box[1], &whole, d, off, &cropped, err);
}

/* The estimate for that grid. */
static int estimate_in(const scene_t *s, int resolution, const float box[2][3], budget_t *b,
                       bk_error_t *err) {
  const grid_dims_t *d = &b->dims;
  int rc = grid_in(s, resolution, box, &b->dims, err);
  if (rc) return rc;
  b->voxels = (double)d->nx * (double)d->ny * (double)d->nz;
  const int grey = budget_grey(s), adaptive = s->mode == MODE_ADAPTIVE;
  const int flux = !adaptive && budget_anisotropic(s);
  const int camera = flux && s->camera.present && s->camera.bake_phase;
  b->per_voxel = (grey ? (adaptive ? BUDGET_ADAPTIVE_GREY_BYTES : BUDGET_REFERENCE_GREY_BYTES)
                       : (adaptive ? BUDGET_ADAPTIVE_BYTES : BUDGET_REFERENCE_BYTES)) +
                 (scene_has_dispersion(s) ? BUDGET_DISPERSION_BYTES : 0.0) +
                 (s->ior_vdb.present ? BUDGET_IOR_VDB_BYTES : 0.0) +
                 (flux ? BUDGET_FLUX_BYTES : 0.0) + (camera ? BUDGET_CAMERA_BYTES : 0.0) +
                 (adaptive && s->target_error > 0.0f
                      ? (grey ? BUDGET_ADAPTIVE_TARGET_GREY_BYTES : BUDGET_ADAPTIVE_TARGET_BYTES)
                      : 0.0);
  b->peak = BUDGET_FIXED_BYTES + b->per_voxel * b->voxels;
  return BK_OK;
}

uint64_t budget_available(uint64_t max_bytes) {
  uint64_t avail = 0;
  FILE *f = fopen("/proc/meminfo", "r");
  if (f) {
    char line[256];
    unsigned long long kb;
    while (fgets(line, sizeof line, f))
      if (sscanf(line, "MemAvailable: %llu kB", &kb) == 1) avail = (uint64_t)kb * 1024;
    fclose(f);
  }
  if (!avail) avail = bk_physical_memory();
  return max_bytes > 0 && (avail == 0 || max_bytes < avail) ? max_bytes : avail;
}

/* The estimate plus `kept` bytes per voxel held over from frame to frame. */
static int estimate_kept(const scene_t *s, int resolution, const float box[2][3], double kept,
                         budget_t *b, bk_error_t *err) {
  int rc = estimate_in(s, resolution, box, b, err);
  b->per_voxel += kept;
  b->peak += kept * b->voxels;
  return rc;
}

/* Bytes a grid of the given resolution needs of one kind (`arg`: that
 * kind's parameter); negative when no such grid can be made. */
typedef double (*bytes_at_fn)(const scene_t *s, int resolution, const float box[2][3],
                              double arg);

/* The bake's peak, `arg` bytes per voxel kept from frame to frame. */
static double peak_at(const scene_t *s, int resolution, const float box[2][3], double arg) {
  budget_t b;
  bk_error_t e = {0};
  return estimate_kept(s, resolution, box, arg, &b, &e) == BK_OK ? b.peak : -1.0;
}

/* The march's sums over d, `slots` 64-bit counters per voxel. */
static double sums_over(const grid_dims_t *d, double slots) {
  return (double)d->nx * (double)d->ny * (double)d->nz * slots * sizeof(uint64_t);
}

/* The same for the grid at `resolution`, `arg` counters per voxel. */
static double sums_at(const scene_t *s, int resolution, const float box[2][3], double arg) {
  grid_dims_t d;
  bk_error_t e = {0};
  return grid_in(s, resolution, box, &d, &e) == BK_OK ? sums_over(&d, arg) : -1.0;
}

/* The largest resolution <= hi whose bytes fit in limit; 0 if none. */
static int largest_fitting(const scene_t *s, int hi, const float box[2][3], double arg,
                           double limit, bytes_at_fn bytes_at) {
  int lo = 0;
  while (lo < hi) {
    int mid = lo + (hi - lo + 1) / 2;
    const double bytes = bytes_at(s, mid, box, arg);
    if (bytes >= 0.0 && bytes <= limit) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

int budget_check(const scene_t *s, const float (*given)[3], uint64_t max_bytes, double kept,
                 int *code_grey, bk_error_t *err) {
  budget_t b;
  float box[2][3];
  box_of(given, box);
  *code_grey = 0;
  int rc = estimate_kept(s, s->resolution, box, kept, &b, err);
  if (rc != BK_OK) return rc;
  uint64_t limit = budget_available(max_bytes);
  char need[32], have[32];
  bk_log(2, "memory: estimated peak %s for %dx%dx%d voxels, %s available",
         bk_format_bytes(b.peak, need, sizeof need), b.dims.nx, b.dims.ny, b.dims.nz,
         bk_format_bytes((double)limit, have, sizeof have));
  if (!limit || b.peak <= (double)limit) return BK_OK;
  /* a grey volume coded: slower to march (about 3%), not refused */
  const double saves = budget_grey(s) ? BUDGET_GREY_CODE_SAVES : 0.0;
  b.per_voxel -= saves;
  b.peak -= saves * b.voxels;
  if (saves > 0.0 && b.peak <= (double)limit) {
    *code_grey = 1;
    bk_log(1, "%s: memory: the bake fits in %s only with its sigma coded (%.0f bytes per voxel "
           "less, estimated peak %s): coding it",
           s->path, bk_format_bytes((double)limit, have, sizeof have), saves,
           bk_format_bytes(b.peak, need, sizeof need));
    return BK_OK;
  }
  int fit = largest_fitting(s, s->resolution, box, kept - saves, (double)limit, peak_at);
  bk_format_bytes(b.peak, need, sizeof need);
  bk_format_bytes((double)limit, have, sizeof have);
  if (fit < 1)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: the bake would need about %s of memory; %s %s, less than the OpenCL "
                   "runtime alone takes",
                   s->path, need, max_bytes ? "--max-memory allows" : "this machine has", have);
  return bk_fail(err, BK_ERR_INPUT,
                 "%s: grid.resolution %d (%dx%dx%d voxels) would need about %s of memory at "
                 "its peak (%.0f bytes per voxel%s and the OpenCL runtime); %s %s available. The "
                 "largest grid.resolution that fits is %d",
                 s->path, s->resolution, b.dims.nx, b.dims.ny, b.dims.nz, need, b.per_voxel,
                 saves > 0.0 ? " with its sigma coded" : "",
                 max_bytes ? "--max-memory allows" : "this machine has", have, fit);
}

/* Counters per voxel the march's sums have at least: three channels where
 * the medium's own coefficients differ in colour (it fills the grid around
 * the objects; not through a density VDB, which may be zero), else one, as
 * the march has three only once the voxels show colour, or the lights or
 * n's dispersion ask for it (march.c); one more with the adaptive mode's
 * sampling tables. The flux of an anisotropic medium is not counted. */
static double sums_slots(const scene_t *s) {
  const float *cs = s->medium_sigma_s, *ca = s->medium_sigma_a;
  const int coloured = cs[0] != cs[1] || cs[0] != cs[2] || ca[0] != ca[1] || ca[0] != ca[2];
  const int channels = coloured && !s->density_vdb.present ? 3 : 1;
  return (double)pm_sum_slots(s->mode == MODE_ADAPTIVE ? PM_MODE_TABLES : PM_MODE_REFERENCE,
                              channels, 0, 0);
}

double budget_sums_bytes(const scene_t *s, const float (*given)[3]) {
  float box[2][3];
  box_of(given, box);
  return sums_at(s, s->resolution, box, sums_slots(s));
}

int budget_device_check(const scene_t *s, const float (*given)[3], uint64_t max_alloc,
                        const char *device, bk_error_t *err) {
  float box[2][3];
  box_of(given, box);
  grid_dims_t d;
  int rc = grid_in(s, s->resolution, box, &d, err);
  if (rc) return rc;
  const double slots = sums_slots(s), bytes = sums_over(&d, slots);
  if (!max_alloc || bytes <= (double)max_alloc) return BK_OK;
  const double mib = 1024.0 * 1024.0; /* MiB: GiB's one decimal would show 1.0 against 1.0 */
  return bk_fail(err, BK_ERR_INPUT,
                 "%s: grid.resolution %d (%dx%dx%d voxels): the photon march's sums need %.0f "
                 "MiB in one buffer, and OpenCL device %s allows %.0f MiB per buffer. The "
                 "largest grid.resolution that fits is %d; or march on the host with --host",
                 s->path, s->resolution, d.nx, d.ny, d.nz, bytes / mib, device,
                 (double)max_alloc / mib,
                 largest_fitting(s, s->resolution, box, slots, (double)max_alloc, sums_at));
}

int budget_parse_size(const char *text, uint64_t *bytes) {
  char *end;
  double v = strtod(text, &end);
  if (end == text || !(v > 0.0) || !isfinite(v)) return 0;
  double scale = 1.0;
  switch (*end) {
  case 'k': case 'K': scale = 1024.0; end++; break;
  case 'm': case 'M': scale = 1024.0 * 1024; end++; break;
  case 'g': case 'G': scale = 1024.0 * 1024 * 1024; end++; break;
  case 't': case 'T': scale = 1024.0 * 1024 * 1024 * 1024; end++; break;
  default: break;
  }
  if (*end == 'i') end++;
  if (*end == 'B' || *end == 'b') end++;
  if (*end || v * scale > 1.8e19) return 0;
  *bytes = (uint64_t)(v * scale);
  return 1;
}
