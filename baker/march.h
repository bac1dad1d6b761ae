/* march.h: photon marching (pipeline stage 5), on OpenCL or in plain C.
 *
 * In: the scene (lights, photons.count/seed/integrator/step, already
 * overridden by the command line) and the voxelized volume (n, σs, σa).
 * Out: the `radiance` grid, L̄ = φ/(4π) in W m^-2 sr^-1, 3 floats per voxel,
 * estimated by track length: each photon adds Φ·ℓ/(4π V) to each voxel it
 * crosses (ℓ its path length in the voxel, m; V the voxel volume), with Φ
 * integrated exactly over the voxel, Φ0 (1 - e^{-σt ℓ})/σt (kernels/photon_march.h).
 *
 * Stages and what they cost (bk_timings_t rows): "octree" (the constant-block
 * pyramid of n, baker/octree.h, and the float4 field of ∇n and n the march
 * samples, baker/field.h), "photon generation"
 * (light set-up: the photons themselves are made in the kernel from their
 * index, kernels/light_sample.h), "photon marching".
 *
 * Accumulation is 64-bit fixed point, one counter per voxel and channel,
 * added with atom_add on ulong (cl_khr_int64_base_atomics): sums are exact
 * and independent of the order photons arrive in. The scale rule: a photon
 * deposits at most Φ0 (path_cap + D) W·voxel in all (the path cap is
 * PM_MAX_PATH_DIAGONALS grid diagonals D; the last straight piece is at most
 * one more D), so with P the total photon power of the brightest channel,
 *   S = 2^62 / (P (path_cap + D))   quanta per W·voxel
 * keeps every counter, and even the sum over all counters, below 2^62 (half
 * the ulong range, leaving room for the rounding of each deposit to the
 * nearest quantum). A deposit of a typical photon over one voxel is then
 * Φ0·S = 2^62 / (N (path_cap + D)) quanta: about 1e7 for N = 1e8 photons on a
 * 128^3 grid, a relative quantum of 1e-7 (and the deposit itself is a float,
 * good to 6e-8).
 *
 * One channel instead of three when the medium is grey and every light has
 * the same colour: the march carries the sum of RGB and the result is
 * coloured at the end (a third of the atomics). */
#ifndef BAKER_MARCH_H
#define BAKER_MARCH_H

#include "bounces.h"
#include "clhost.h"
#include "kernels/photon_march.h"
#include "octree.h"
#include "photons.h"
#include "scene.h"
#include "voxelize.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Photons per kernel launch: progress between launches, and PoCL never holds
 * the queue for long. */
#define PM_CHUNK 65536u
/* Work-items per work-group of the march (a divisor of PM_CHUNK). */
#define PM_LOCAL_SIZE 256u

typedef struct pm_stats {
  uint64_t photons, missed_grid, left_grid, absorbed, step_limit;
  uint64_t steps;      /* march iterations: integrator steps, straight blocks and runs of cells */
  uint64_t voxels;     /* voxel crossings (deposits) */
  double path_voxels;  /* total path length inside the grid, voxels */
  double ms_octree, ms_generate, ms_march;
  double ms_build;     /* OpenCL program build (or cache load), part of ms_march */
  /* Multiple scattering (bounces.h), sums of the photons' ms_tally: the
   * power that entered the grid and left it (W), the deposits of first legs
   * and of later ones (W·voxel), the scattering events. */
  int bounces;         /* events allowed per photon; 0: single scattering */
  double entered, escaped, deposit_first, deposit_later;
  uint64_t events;
} pm_stats_t;

/* pm_setup_t.cell_work's entries per light. */
#define PM_CELL_WORK_PER_LIGHT (2 * LD_CELLS)

/* Everything the march needs, prepared once on the host. */
typedef struct pm_setup {
  pm_params params;
  ph_setup_t lights;
  grid_dims_t dims;
  size_t voxels;
  int channels;          /* 1 or 3 */
  int has_refraction, homogeneous, grey;
  float *ng;             /* has_refraction: the padded {∇n, n} field (baker/field.h) */
  oct_pyramid_t pyramid; /* has_refraction */
  /* The volume's σ per metre (the kernels scale it by h), not owned: σt,
   * read unless homogeneous; σs and g, read by scattering events where they
   * vary (ms.sigma_grid, ms.g_grid; g NULL: uniform). Plain arrays of
   * params.sigma_stride channels per voxel, or for a coded volume
   * (kernels/medium_code.h, params.sigma_stride | PM_SIGMA_CODED_FLAG) both
   * the one buffer of sigma_floats floats. */
  const float *sigma_t, *sigma_s, *g;
  size_t sigma_floats;
  double to_radiance[3]; /* accumulator quanta -> W m^-2 sr^-1, per output channel */
  int octree_enabled;    /* 0: step everywhere (tests of the stepping itself) */
  unsigned seed;         /* photons.seed, for pm_derive */
  /* The launch slots this march traces, [first, last) of lights.photons:
   * all of them after pm_prepare and pm_derive; a photon shard
   * (baker/shard.h) narrows it with pm_set_range. Slot i traces photon
   * ph_photon_of_slot(i) (kernels/light_sample.h: a permutation of all
   * lights.photons, Hammersley point j of N keeping its place) on the host
   * and on every device, so the sums of disjoint ranges add up to the whole
   * march exactly, whichever path baked each. */
  uint64_t first, last;
  ms_setup_t ms;         /* multiple scattering: params.max_bounces 0 when off */
  /* The optional inputs (params.mode, kernels/photon_march.h), not owned: */
  uint64_t *masks;       /* origin recorder: pm_mask_count masks, zeroed by the caller */
  /* optional, any mode: per light PM_CELL_WORK_PER_LIGHT entries, LD_CELLS
   * photon counts then LD_CELLS sums of their pm_work, by the light-domain
   * cell of the photon's (unwarped) Hammersley point; zeroed by the caller */
  uint64_t *cell_work;
  const float *tables;   /* sampling tables: LD_TABLE_FLOATS(8, 8) floats per light */
  /* ng and pyramid belong to a pm_field_cache_t (not freed with the
   * setup): 1 built by this prepare, 2 taken from an earlier frame's
   * (fields_frame); 0: owned */
  int fields_kept, fields_frame;
} pm_setup_t;

/* The march's fields of one volume (the pyramid, the {∇n, n} field and
 * what the volume scan found), kept by a batch of frames
 * (baker/frame_reuse.h) for the next frame whose volume has the same key
 * (volume_t.key: the hash of the voxelize stage's inputs, so the same n and
 * σ voxel for voxel) and the march the same channel count. */
typedef struct pm_field_cache {
  uint64_t key;          /* the volume's key; 0: empty */
  int frame;             /* the frame that built them */
  int has_refraction, homogeneous, grey; /* the volume scan */
  /* ms_decide's outcome (before ms_build), for photons.bounces `bounces`
   * (its other inputs are the volume's); decided 0: none yet */
  int decided, bounces, grey_scatter;
  ms_setup_t ms;
  int channels;          /* of the fields below; 0: none built yet */
  float *ng;
  oct_pyramid_t pyramid;
} pm_field_cache_t;
void pm_field_cache_free(pm_field_cache_t *c);
/* march_fields.c, for pm_prepare: the volume's specialisations (has_refraction,
 * homogeneous, grey), from the cache when it holds this volume; then the
 * fields, taken from the cache when they match, else built (and, with a
 * cache, kept in it, the old ones freed first). kept may be NULL. */
void pm_fields_scan(const volume_t *vol, pm_field_cache_t *kept, int frame, pm_setup_t *s);
int pm_fields_build(const volume_t *vol, pm_field_cache_t *kept, pm_setup_t *s,
                    bk_error_t *err);
/* ms_decide (bounces.h), its outcome taken from the cache when it holds
 * this volume decided for the same photons.bounces. */
void pm_fields_decide(const scene_t *scene, const volume_t *vol, pm_field_cache_t *kept,
                      ms_setup_t *ms, int *grey_scatter);

/* The grid as the kernels see it (kernels/shared.h). */
bk_grid pm_kernel_grid(const grid_dims_t *d);

/* The fixed-point scale for total photon power `power_max` (W, brightest
 * channel) and a bound `path_bound` (voxels) on any photon's deposited path. */
double pm_fixed_scale(double power_max, double path_bound);

/* Builds the pyramid, the n/∇n field, the extinction grid and the lights.
 * Timings (may be NULL) get the "octree" and "photon generation" rows. */
int pm_prepare(const scene_t *scene, const volume_t *vol, pm_setup_t *s, bk_timings_t *timings,
               pm_stats_t *stats, bk_error_t *err);
/* The same, taking the fields from `kept` (may be NULL) when they were
 * built from this volume, and leaving the ones it builds there. */
int pm_prepare_kept(const scene_t *scene, const volume_t *vol, pm_field_cache_t *kept,
                    pm_setup_t *s, bk_timings_t *timings, pm_stats_t *stats, bk_error_t *err);
void pm_setup_free(pm_setup_t *s);
/* Frees only the fields ({grad n, n}, the pyramid) unless they are
 * kept for the next frame: after the march, before the output grids. */
void pm_setup_free_fields(pm_setup_t *s);
/* Treat every block as varying (after pm_prepare): the march then steps
 * everywhere, as the paper's reference pipeline without its octree. It
 * writes the pyramid: not for a setup whose fields are kept. */
void pm_disable_octree(pm_setup_t *s);

/* Several marches may share one prepared setup (the octree and the n/∇n
 * field are built once). pm_derive makes a shallow copy of base (it owns
 * nothing: free only base) whose lights carry `photons` photons, in
 * reference mode. Two optional inputs change what a march does
 * (kernels/light_domain.h); the march does not know who asks for them:
 * pm_record_origins makes it an origin recorder that deposits into cells of
 * 2^coarse_shift voxels a side and marks in each the light-domain cells of
 * the photons that reached it (masks: pm_mask_count entries, zeroed);
 * pm_sample_tables draws each light's photons from its sampling table (one
 * per light, in the order of lights.lights) with weight 1/pdf, w_max the
 * largest, and keeps per voxel the photon count and weight sum over all
 * the photons the bake may trace (total: its batches together, at least
 * lights.photons); it refuses totals whose packed count and weight sums
 * could overflow (PM_TABLES_MAX_PHOTONS holds with weights <= 2). The tables may change
 * between batches (pm_run_batches uploads run->tables before each). */
#define PM_TABLES_MAX_PHOTONS ((1ull << 25) - 1ull)
int pm_derive(const pm_setup_t *base, const scene_t *scene, uint64_t photons, pm_setup_t *out,
              bk_error_t *err);
void pm_record_origins(pm_setup_t *s, int coarse_shift, uint64_t *masks);
int pm_sample_tables(pm_setup_t *s, const float *tables, double w_max, uint64_t total,
                     bk_error_t *err);
/* A reference march that keeps the radiance sums of the voxels of even
 * (i, j, k) only, packed (pm_acc_count: 1/8 of the grid's): what the error
 * estimate's twins read. No flux sums. */
void pm_deposit_lattice(pm_setup_t *s);
/* Marches only photons [first, last) (first <= last <= lights.photons). */
/* Share `index` (1-based) of `count` of photons: [floor(photons (index-1) / count),
 * floor(photons index / count)), count < 2^17. Disjoint shares cover all. */
void pm_share_range(uint64_t photons, int index, int count, uint64_t *first, uint64_t *last);
/* Multiple scattering's timing row ("scattering") and log line. */
void pm_report_scattering(const pm_setup_t *s, pm_stats_t *stats, bk_timings_t *timings);
void pm_set_range(pm_setup_t *s, uint64_t first, uint64_t last);

/* Counters in the accumulator of the setup's mode (channels per voxel; the
 * recorder's per coarse cell; with sampling tables one more per voxel), and
 * the origin masks of a recorder (0 in other modes). */
size_t pm_acc_count(const pm_setup_t *s);
size_t pm_mask_count(const pm_setup_t *s);
/* 64-bit sums per voxel of a full-grid march: the channels, one more with
 * sampling tables (PM_MODE_TABLES), the flux counters (flux; camera: its
 * own). The memory budget sizes the device's largest buffer by it. */
size_t pm_sum_slots(int mode, int channels, int flux, int camera);

/* Counts one photon's outcome into st; and its energy accounting. */
void pm_stats_add(pm_stats_t *st, const pm_result *r);
/* A photon's march work, the cost model of the error twins and of the
 * adaptive tables: steps × the integrator's field evaluations per step
 * (integrators.h; integrator as pm_params.integrator) + voxel crossings. */
uint64_t pm_work(unsigned integrator, uint64_t steps, uint64_t voxels);
/* Adds the result r of launch slot `slot` to s->cell_work (when set). */
void pm_count_cell_work(const pm_setup_t *s, uint64_t slot, const pm_result *r);
void pm_stats_add_tally(pm_stats_t *st, const ms_tally *t);
/* The share of the deposited energy after the first scattering event. */
double pm_scattered_share(const pm_stats_t *st);
/* Warns when 1% or more of the photons stopped at the step limit: the
 * light they still carried is missing from the grid. */
void pm_warn_step_limit(const scene_t *scene, const pm_stats_t *st);

/* Marches every photon into acc (pm_acc_count counters, zeroed by the
 * caller): in plain C on this thread, or with OpenCL on cl. */
int pm_run_host(const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats, bk_error_t *err);
int pm_run_cl(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
              bk_error_t *err);
/* Batches (baker/batches.h): one march set up once, its photons traced in
 * batches. Before each batch the runner calls next(ctx, done, acc, run,
 * err) with `done` batches traced and acc holding their sums (for the host
 * to read, not to change); the callback fills run->lights and run->params
 * for the next batch and returns PM_BATCH_GO, or PM_BATCH_GO_ZERO to have
 * the runner zero the sums first (on a GPU, on the device: nothing crosses
 * the bus), or returns 0 to stop, when it may also change acc (negative:
 * an error, in err). run starts as a copy of s;
 * the callback may change the lights, photon_total and light_count, not the
 * kernel's specialisation (-D flags: integrator, refraction, channels, mode)
 * but may change params.step and, with sampling tables, the tables' contents
 * (not their number: one per light). */
#define PM_BATCH_GO 1
#define PM_BATCH_GO_ZERO 2
typedef int (*pm_batch_fn)(void *ctx, int done, uint64_t *acc, pm_setup_t *run, bk_error_t *err);
int pm_run_batches(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
                   pm_batch_fn next, void *ctx, bk_error_t *err);
int pm_run_cl_batches(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *stats,
                      pm_batch_fn next, void *ctx, bk_error_t *err);
/* The fixed-point scale for photons traced as up to `batch_cap` batches that
 * each carry the lights' whole power (each batch a full estimate; the sum
 * of done batches divided by done is the result). batch_cap 1 is the scale
 * of an unbatched march. */
void pm_scale_batches(pm_setup_t *s, double batch_cap);

/* Floats per voxel radiance needs: 1 when the march carries one channel
 * and every light has grey colour (the three channels equal, 8 B per voxel
 * less through the write), else 3. */
int pm_radiance_channels(const pm_setup_t *s);
/* acc -> radiance (`channels` floats per voxel, 3, or 1 where
 * pm_radiance_channels allows it; W m^-2 sr^-1); reference and weighted
 * modes. */
void pm_to_radiance(const pm_setup_t *s, const uint64_t *acc, float *radiance, int channels);
/* The same, written over the accumulator itself (allocated with malloc),
 * which is then shrunk to the radiance's size and returned: the two never
 * take memory together. NULL (acc untouched) where a voxel's floats do not
 * fit in its counters' bytes (3 channels of one counter) or on no memory. */
float *pm_to_radiance_in_place(const pm_setup_t *s, uint64_t *acc, int channels);
/* params.flux (some g != 0, kernels/photon_march.h PM_FLUX): the flux
 * counters after the voxels' -> `radiance_flux`, 3 floats per voxel,
 * F = ∫ L_Y ω dω / (4π) in W m^-2 sr^-1, the first moment of the luminance
 * Y = 0.2126 R + 0.7152 G + 0.0722 B of radiance in radiance's own
 * normalisation (L̄ = ∫ L dω / (4π)): |F| <= Y(L̄), = for a parallel beam;
 * and `radiance_uncollided`, 1 float per voxel, the part of Y(L̄) that has
 * not scattered yet (Y(L̄) itself with bounces 0), followed in the same
 * array (4 floats per voxel in all) by `radiance_flux_uncollided`, 3 floats
 * per voxel, that part's own F (|F0| <= Y0, = for one beam), and with
 * params.camera (kernels/photon_march.h PM_CAMERA; 5 floats per voxel in
 * all) by `radiance_camera`, 1 float per voxel, ∫ L_Y(ω) p(g, ω·ω_c) dω:
 * the luminance the voxel scatters towards the camera, per unit σs.
 * pm_flux_scale: quanta -> those units. */
void pm_to_flux(const pm_setup_t *s, const uint64_t *acc, float *flux, float *uncollided);
/* Floats per voxel of pm_to_flux's `uncollided` array: 4, 5 with the camera;
 * and where in it F0 (3 per voxel) and radiance_camera (1) begin. */
static inline int pm_uncollided_floats(const pm_setup_t *s) { return s->params.camera ? 5 : 4; }
static inline float *pm_flux_uncollided(float *unc, size_t voxels) { return unc + voxels; }
static inline float *pm_radiance_camera(float *unc, size_t voxels) { return unc + 4 * voxels; }
double pm_flux_scale(const pm_setup_t *s);
/* Weighted mode: per voxel the photon count and the mean weight (0 where no
 * photon came); either may be NULL. */
void pm_unpack_weights(const pm_setup_t *s, const uint64_t *acc, float *count,
                       float *mean_weight);

/* A march's raw fixed-point sums and what turns them into grids after it
 * (pm_to_radiance, pm_unpack_weights): what a photon shard writes instead
 * of radiance (baker/shard.h), and a merge adds. */
typedef struct pm_sums {
  uint64_t *acc;          /* pm_acc_count counters (stride per voxel), owned */
  size_t voxels;
  int channels, stride;   /* march channels (1 or 3); counters per voxel */
  int mode;               /* PM_MODE_REFERENCE or PM_MODE_TABLES */
  double to_radiance[3];  /* quanta -> W m^-2 sr^-1 per output channel */
  unsigned count_shift;   /* PM_MODE_TABLES: the packed count's shift */
  float weight_scale;     /* ... and the weight sum's quanta per unit weight */
  int flux;               /* PM_FLUX_SLOTS counters per voxel after voxels·stride (pm_to_flux) */
  int camera;             /* and one more, the camera's (PM_CAMERA_SLOT), with cam_scale */
  float cam_scale;
} pm_sums_t;
/* Takes acc (pm_acc_count(s) counters, now owned by out) with s's scales. */
void pm_sums_keep(const pm_setup_t *s, uint64_t *acc, pm_sums_t *out);
/* A setup that knows only what pm_to_radiance and pm_unpack_weights read
 * (voxels, channels, mode, scales), for sums made elsewhere. */
void pm_sums_setup(const pm_sums_t *k, pm_setup_t *out);
void pm_sums_free(pm_sums_t *k);

/* The whole stage: cl NULL marches on the host. Adds the "octree",
 * "photon generation" and "photon marching" timing rows. With sums non-NULL
 * it marches only photons [first, last) and hands back the raw sums instead
 * of radiance (a photon shard; radiance unused, may be NULL). */
int pm_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol, float *radiance,
            pm_stats_t *stats, bk_timings_t *timings, bk_error_t *err);
int pm_bake_range(clh_context_t *cl, const scene_t *scene, const volume_t *vol, uint64_t first,
                  uint64_t last, float *radiance, pm_sums_t *sums, pm_stats_t *stats,
                  bk_timings_t *timings, bk_error_t *err);

/* Host-only, for tests (reference mode): the path of photon `index` of the setup as points in
 * world coordinates (3 floats each: the light's origin, the grid entry, then
 * the end of every march iteration). *count is the number of points the path
 * had (only the first max_points are stored). res may be NULL. */
int pm_trace_photon(const pm_setup_t *s, uint32_t index, float *points, int max_points,
                    int *count, pm_result *res, bk_error_t *err);
/* The same for a ray given by its world origin and direction. */
int pm_trace_ray(const pm_setup_t *s, const float origin[3], const float dir[3], float *points,
                 int max_points, int *count, pm_result *res, bk_error_t *err);

/* For the precision test: n deposits of `value` quanta through the march's
 * deposit function into one counter, on the host or on cl (per_item deposits
 * per work-item). */
uint64_t pm_deposit_repeat_host(float value, uint64_t n);
int pm_deposit_repeat_cl(clh_context_t *cl, float value, uint32_t items, uint32_t per_item,
                         uint64_t *sum, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
