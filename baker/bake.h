/* bake.h: the bake pipeline, scene -> voxelize -> photons -> .vdb, and the
 * `baker bake` command over it.
 *
 * In: a scene file (optionally a frame pattern), command-line overrides.
 * Out: one .vdb per frame with the grids of DESIGN.md §5, written under a
 * temporary name and renamed, and a per-stage timing table. Frames whose
 * output already exists and opens as a baker file are skipped, so a killed
 * batch job restarts where it stopped. */
#ifndef BAKER_BAKE_H
#define BAKER_BAKE_H

#include "scene.h"
#include "vdbio.h"

typedef struct bake_options {
  const char *scene_path;   /* may hold a frame pattern */
  const char *out_path;     /* may hold a frame pattern */
  const char *frames;       /* "A", "A-B" or "A-BxS"; NULL: one frame */
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
  vdbio_write_opts_t write;
  int no_filter;            /* adaptive: skip the reconstruction filter */
  int write_filter_radius;  /* adaptive: also write the filter_radius grid (debug) */
} bake_options_t;

/* The command (bake_cmd.c): argv[0] is "bake", as main() passes argv + 1.
 * Returns the exit status: 0 ok, 2 bad input or usage, 1 runtime failure;
 * prints its own messages. */
int bake_main(int argc, char **argv);

/* No overrides, one frame, blosc compression. */
void bake_options_defaults(bake_options_t *opt);
/* Bakes the frames opt asks for (--frames, else $SLURM_ARRAY_TASK_ID for a
 * patterned output, else frame 0), skipping complete outputs unless
 * opt->force. */
int bake_run(const bake_options_t *opt, bk_error_t *err);
/* Bakes one frame; `frame` is recorded in the metadata. */
int bake_frame(const bake_options_t *opt, const char *scene_path, const char *out_path, int frame,
               bk_error_t *err);

#endif
