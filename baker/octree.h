/* octree.h: the constant-block pyramid of n (pipeline stage 3).
 *
 * In: n, one float per voxel. Out: one byte per finest block (2^3 voxels)
 * saying which is the coarsest constant block containing it: 0 where n
 * varies, L in 1..OCT_LEVELS for the block of 2 * 4^(L-1) voxels a side
 * (2, 8, 32, 128; kernels/march.h PM_BLOCK_SHIFT, PM_LEVELS). A block is
 * constant when n takes one value over the block and a halo of OCT_HALO
 * voxels around it (clipped to the grid); the march then crosses it in a
 * straight line with an exact DDA instead of integrating d/ds(n dx/ds) = ∇n
 * step by step.
 *
 * Why a 2-voxel halo: inside a constant block the march must see exactly
 * ∇n = 0. ∇n at a voxel is a central difference (kernels/ior.h) reaching one
 * voxel out, and between voxel centres it is interpolated trilinearly, which
 * near a block face reads the neighbour voxel's gradient: two voxels out.
 * Why 2^3 finest blocks: a varying band (the smoothed surface plus the halo
 * on both sides) is rounded up to whole blocks; with 2^3 blocks instead of
 * 4^3 the ball-lens march takes 17% fewer steps.
 *
 * Storing the coarsest level per finest block (a flattened octree) makes the
 * march's question "how far may I go straight?" a single byte lookup. The
 * build is a separable min/max filter of width 2 OCT_HALO + 1 over a rolling
 * window of five z-slices, so its extra memory is O(nx ny), not O(voxels). */
#ifndef BAKER_OCTREE_H
#define BAKER_OCTREE_H

#include "grid.h"
#include "kernels/march.h"

#ifdef __cplusplus
extern "C" {
#endif

#define OCT_HALO 2
/* the block sizes are the march's (kernels/march.h) */
#define OCT_LEVELS PM_LEVELS
#define OCT_BLOCK_SHIFT PM_BLOCK_SHIFT

typedef struct oct_pyramid {
  int bx, by, bz;        /* finest blocks along each axis (the last ones may be partial) */
  unsigned char *level;  /* bx*by*bz bytes, x-fastest */
  /* voxels lying in constant blocks of each level (index 1..OCT_LEVELS), and
   * in no constant block (index 0): the share of the grid the march may cross
   * straight */
  uint64_t voxels_at_level[OCT_LEVELS + 1];
} oct_pyramid_t;

/* Builds the pyramid of `ior` (grid_count(d) floats). BK_ERR_RUNTIME when out
 * of memory. */
int oct_build(const grid_dims_t *d, const float *ior, oct_pyramid_t *out, bk_error_t *err);
void oct_free(oct_pyramid_t *p);

#ifdef __cplusplus
}
#endif
#endif
