/* frame_reuse.h: what one frame of a batch leaves the next (docs/animation.md).
 *
 * In a batch where only the light moves, the frames' voxels, the march's
 * fields and the OpenCL context are the same, so they are kept: each kept
 * piece carries a hash of the inputs its stage read, and the next frame
 * takes it only when its own inputs hash the same, never by guessing from
 * what the scene looks like.
 *   voxelize  (volume)   the grid (bounds, resolution, ior_smoothing); the
 *                        medium (σs, σa, n, g, density_vdb and ior_vdb: path,
 *                        grid name, file contents); every object (mesh path
 *                        and file contents, n and its per-channel n, σs, σa,
 *                        g, transform);
 *   octree    (fields)   the volume's key and the march's channel count
 *                        (march.h: pm_field_cache_t);
 *   OpenCL init          the device spec; the context keeps its programs by
 *                        expanded source, -D options and device (clhost.h),
 *                        so a light of another type builds its own kernel.
 * One frame's state at a time: a changed input frees the kept state before
 * the new one is built. The volume lived through the write before too; the
 * fields now do (FR_KEPT_FIELDS_BYTES more per voxel, counted in the memory
 * budget), and only when the run bakes more than one frame. Frames
 * are baked exactly as alone (the grids are bit-identical); only the work
 * is skipped. */
#ifndef BAKER_FRAME_REUSE_H
#define BAKER_FRAME_REUSE_H

#include <pthread.h>

#include "clhost.h"
#include "march.h"
#include "scene.h"
#include "voxelize.h"

/* Bytes per voxel the kept fields add to a frame's peak (they outlive the
 * march into the write): the {∇n, n} field (at most 23, FLD_WORST_BYTES_PER_VOXEL;
 * three with dispersion, counted apart) and the pyramid (1/8); σ is the
 * volume's. */
#define FR_KEPT_FIELDS_BYTES 23.125

typedef struct bake_reuse {
  int several_frames;           /* a batch of several frames: the volume is kept */
  int keep_fields;              /* ... and the march's fields, unless memory is short */
  double extra_bytes;           /* per voxel beyond the budget's mode figure (a shard's sums, a NanoVDB output) */
  int has_volume, volume_frame; /* the kept volume, its key volume.key */
  volume_t volume;
  pm_field_cache_t fields;      /* the octree stage's (march.h) */
  int has_cl, cl_frame;
  uint64_t cl_key;
  clh_context_t cl;
  /* fr_volume's early start: the context opening on a thread of its own */
  int cl_opening;
  pthread_t cl_thread;
  const char *cl_device;
  int cl_rc;
  bk_error_t cl_err;
  double cl_ms;
  int cl_unreported;            /* opened so, its stage row not yet added (fr_opencl) */
  double cl_waited_ms;          /* the wait for it before the voxels (fr_volume's device check) */
} bake_reuse_t;

/* A file's contents, hashed (one that cannot be read hashes its error; a
 * pipe or a device is not read and gets a key no other call gives); never
 * 0. `baker view --frames` keeps a frame's volume for the next when
 * its input's key is the same. */
uint64_t fr_file_key(const char *path);
/* The hash of every input the voxelize stage reads (above); files are
 * hashed by content (one that cannot be read hashes its error: vox_build
 * then says what is wrong). Never 0. */
uint64_t fr_volume_key(const scene_t *s);
/* The frame's volume in r->volume: the kept one when the key matches (a
 * "voxelize" row saying so), else the kept one freed, the memory budget
 * checked (max_memory: --max-memory; the kept fields counted when
 * keep_fields: when only they do not fit, keep_fields is cleared with a
 * warning and every frame builds its own) and the volume built.
 * cl_device (NULL: none; "" the default device): the frame will want the
 * OpenCL context of that device, so once the budget has passed and the
 * meshes are read, a context not kept already starts opening on a thread
 * of its own while the voxels are made (loading the driver is ~30-70 ms on
 * one core); fr_opencl takes it. Not when the voxelizer reads a VDB file:
 * mesh and VDB readers are forked children, and a fork while another
 * thread loads libraries is not safe. */
int fr_volume(bake_reuse_t *r, const scene_t *s, uint64_t max_memory, const char *cl_device,
              bk_timings_t *t, bk_error_t *err);
/* The OpenCL context in r->cl: the kept one for the same device spec (an
 * "OpenCL init" row saying so), the one fr_volume started (the row holds
 * the wait for it), else a new one. */
int fr_opencl(bake_reuse_t *r, const char *device, int frame, bk_timings_t *t, bk_error_t *err);
/* Waits for a context still opening (a frame that failed before it took
 * it), so that nothing forks while it loads; it is kept if it opened. */
void fr_opencl_settle(bake_reuse_t *r);
/* After a runtime failure: the context may be broken, so it is not kept. */
void fr_drop_opencl(bake_reuse_t *r);
void fr_free(bake_reuse_t *r);

#endif
