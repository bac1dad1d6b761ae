/* bake.h: the bake pipeline, scene -> voxelize -> photons -> .vdb, and the
 * `baker bake` command over it.
 *
 * In: a scene file (optionally a frame pattern), command-line overrides.
 * Out: one .vdb per frame with the grids of DESIGN.md §5, written under a
 * temporary name and renamed, and a per-stage timing table. A frame whose
 * output already exists is skipped only when that file is complete and
 * records the scene hash and bake settings this run would bake with
 * (bake_settings); otherwise it is re-baked with a line saying why. So a
 * killed batch job restarts where it stopped, and a changed scene or option
 * never leaves stale frames behind. */
#ifndef BAKER_BAKE_H
#define BAKER_BAKE_H

#include "scene.h"
#include "out_grids.h"
#include "vdbio.h"

typedef struct bake_options {
  const char *scene_path;   /* may hold a frame pattern */
  const char *out_path;     /* may hold a frame pattern */
  const char *frames;       /* frame list ("1-3,7,10-20x2", "1-20:2") or "task";
                               NULL: a scheduler's array task, else one frame */
  const char *const *sets;  /* --set KEY=VALUE, applied to the scene's JSON */
  int set_count;
  int keep_going;           /* bake the other frames after a failure */
  const char *device;       /* OpenCL device spec, NULL: PoCL/default */
  int host_only;            /* march with the host C path (no OpenCL) */
  int force;                /* re-bake frames whose output exists */
  /* Overrides of scene keys; negative/NULL: keep the scene's value. */
  int mode;                 /* photon_mode_t or -1 */
  long long photons;
  int integrator;           /* integrator_t or -1 */
  float step;
  int resolution;
  long long seed;
  int batches;              /* photons.batches or -1 */
  double target_error;      /* photons.target_error or -1 */
  double time_budget_s;     /* photons.time_budget_s or -1 */
  int error_grid;           /* also write radiance_error (per-voxel standard error) */
  const char *stats_path;   /* --stats: a JSON of the bake per frame (may hold a pattern) */
  vdbio_write_opts_t write;
  int no_filter;            /* adaptive: skip the reconstruction filter */
  int write_filter_radius;  /* adaptive: also write the filter_radius grid (debug) */
  uint64_t max_memory;      /* --max-memory in bytes; 0: what the machine has available */
  int shard_index, shard_count; /* --shard I/N (1 <= I <= N): trace only the I-th of N
                                   slices of the photons and write raw sums
                                   (baker/shard.h); shard_count 0: the whole bake */
} bake_options_t;

/* The command (bake_cmd.c): argv[0] is "bake", as main() passes argv + 1.
 * Returns the exit status: 0 ok, 2 bad input or usage, 1 runtime failure;
 * prints its own messages. */
int bake_main(int argc, char **argv);

/* No overrides, one frame, blosc compression. */
void bake_options_defaults(bake_options_t *opt);
/* Bakes the frames opt asks for (bake_batch.c: --frames, else the array
 * task of Slurm, SGE or PBS for a patterned output, else frame 0), skipping
 * up-to-date outputs unless opt->force. */
int bake_run(const bake_options_t *opt, bk_error_t *err);
/* The scene with the command's --set and option overrides at `frame`
 * (its keyframed values), as bake_frame bakes it (frame patterns inside the
 * scene not yet expanded). */
int bake_load_scene(const bake_options_t *opt, const char *scene_path, int frame, scene_t *s,
                    bk_error_t *err);
/* What an output depends on besides the meshes and VDBs the scene names, as
 * "scene=HASH mode=M photons=N integrator=I step=S seed=S resolution=R
 * compression=C half=H filter=F": recorded in each file's `bake_settings`
 * metadata and compared before a frame is skipped. */
void bake_settings(const bake_options_t *opt, const scene_t *s, char *out, size_t len);
/* The output arrays of one frame (DESIGN.md §5), dense, x fastest, or made
 * at the write (out_grids.h); NULL or none: the grid is not written.
 * scattering has sca_channels floats per voxel (1 when the medium is grey),
 * extinction too; radiance and emission 3. */
typedef struct bake_arrays {
  og_values_t ior, radiance, extinction, scattering, density, emission; /* made at the write, or dense */
  const float *photon_count, *photon_weight, *filter_radius;
  int sca_channels;
  float medium_ior;  /* the ior grid's background: n outside the box */
  og_values_t ior_rgb; /* dispersion: n per channel (R, G, B), 3 per voxel; else none */
  /* some g != 0: F = ∫ L_Y ω dω / (4π) (3 per voxel) and the uncollided
   * Y(L̄) (1, baker/march.h pm_to_flux), the Henyey–Greenstein g where
   * σs > 0 (1 per voxel); the uncollided light's own F (3 per voxel) */
  const float *radiance_flux, *radiance_uncollided;
  og_values_t phase_g;
  const float *radiance_flux_uncollided;
  /* the scene camera's: ∫ L_Y p(g, ω·ω_c) dω per voxel (baker/march.h
   * pm_to_flux), towards the point in the metadata
   * `radiance_camera_position` (bake_camera_meta) */
  const float *radiance_camera;
} bake_arrays_t;
#define BAKE_MAX_GRIDS 20
/* The metadata naming the camera point of `radiance_camera`: "[x, y, z]"
 * in world units, each float exact ("%.9g"), written into buf. */
void bake_camera_meta(const float position[3], char *buf, size_t size, vdbio_meta_t *out);
/* The grids of a frame in file order, as `baker bake` and `baker merge`
 * write them; returns their count. */
int bake_grid_list(const bake_arrays_t *a, vdbio_grid_t grids[BAKE_MAX_GRIDS]);

/* Bakes one frame; `frame` is recorded in the metadata and picks the
 * scene's keyframed values. reuse (frame_reuse.h; NULL: nothing kept) holds
 * what the frame before left: the stages whose inputs hash the same are
 * taken from it, and this frame leaves its own there. loaded (NULL: load it
 * here) is the frame's scene as bake_load_scene gave it, taken over: its
 * warnings were said when it was loaded. */
struct bake_reuse;
int bake_frame(const bake_options_t *opt, const char *scene_path, const char *out_path, int frame,
               scene_t *loaded, struct bake_reuse *reuse, bk_error_t *err);

#endif
