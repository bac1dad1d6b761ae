/* octree.h: the constant-block pyramid (pipeline stage 3), the one
 * empty-space structure of the ray core (kernels/ray_core.h).
 *
 * In: a field, one or more floats per voxel. Out: one byte per finest block
 * (2^3 voxels) saying which is the coarsest constant block containing it: 0
 * where the field varies, L in 1..OCT_LEVELS for the block of 2 * 4^(L-1)
 * voxels a side (2, 8, 32, 128; RC_BLOCK_SHIFT, RC_LEVELS). A block is
 * constant when every channel takes one value over the
 * block and a halo around it (clipped to the grid). The photon march builds
 * it over n with a halo of OCT_HALO and crosses constant blocks in a straight
 * line with an exact DDA instead of integrating d/ds(n dx/ds) = ∇n step by
 * step; the view builds it over n the same way, and over its medium (σs·L̄,
 * σt) with a halo of 1, where one step crosses a whole block.
 *
 * Why a 2-voxel halo: inside a constant block the march must see exactly
 * ∇n = 0. ∇n at a voxel is a central difference (kernels/ray_core.h) reaching one
 * voxel out, and between voxel centres it is interpolated trilinearly, which
 * near a block face reads the neighbour voxel's gradient: two voxels out.
 * Why 2^3 finest blocks: a varying band (the smoothed surface plus the halo
 * on both sides) is rounded up to whole blocks; with 2^3 blocks instead of
 * 4^3 the ball-lens march takes 17% fewer steps.
 *
 * Storing the coarsest level per finest block (a flattened octree) makes the
 * march's question "how far may I go straight?" a single byte lookup. The
 * build compares every voxel with its three forward neighbours (a box holds
 * one value when no adjacent pair in it differs) and clears the blocks whose
 * halo-grown box holds a differing pair: one parallel pass over the field
 * (bk_parallel, slabs of block rows), the pairs reduced per row, slice and
 * block row; memory beyond the flags: one row and one slice of blocks per
 * thread. */
#ifndef BAKER_OCTREE_H
#define BAKER_OCTREE_H

#include "base/grid.h"
#include "kernels/ray_core.h"

#ifdef __cplusplus
extern "C" {
#endif

#define OCT_HALO 2
/* the block sizes are the ray core's (kernels/ray_core.h) */
#define OCT_LEVELS RC_LEVELS
#define OCT_BLOCK_SHIFT RC_BLOCK_SHIFT
#define OCT_MAX_HALO 2

typedef struct oct_pyramid {
  int bx, by, bz;        /* finest blocks along each axis (the last ones may be partial) */
  unsigned char *level;  /* bx*by*bz bytes, x-fastest; then cell_bytes of cell flags */
  size_t cell_bytes;     /* oct_add_cells: the field's constant cells, after the levels */
  /* voxels lying in constant blocks of each level (index 1..OCT_LEVELS), and
   * in no constant block (index 0): the share of the grid the march may cross
   * straight */
  uint64_t voxels_at_level[OCT_LEVELS + 1];
} oct_pyramid_t;

/* One input of a pyramid: `channels` floats every `stride` floats per voxel;
 * pad 1: stored with one layer of voxels around the grid (field.h's padded
 * layout), 0: the grid alone. */
typedef struct oct_source {
  const float *values;
  int stride, channels;
  int pad;
} oct_source_t;

/* The pyramid: constant where every channel of every source takes one
 * value over the block and `halo` (1..OCT_MAX_HALO) voxels around (n:
 * OCT_HALO, exact equality). BK_ERR_RUNTIME when out of memory. */
int oct_build_fields(int nx, int ny, int nz, const oct_source_t *src, int nsrc, int halo,
                     oct_pyramid_t *out, bk_error_t *err);
/* The constant cells of the {∇n, n} field (photon march and view), after the levels
 * (kernels/ray_core.h, rc_cell_flag): one bit per trilinear cell (the cube
 * between 8 voxel centres; padded lower-corner index p in [0, n] per axis,
 * one byte per 8 cells along x, rows of (nx + 8) / 8 bytes), set when no
 * corner (voxel p - 1 or p per axis, clamped onto the grid) differs from a
 * face neighbour in any channel of src. Then the corners hold one n and
 * their differences, central or one-sided, are exactly 0, so n and ∇n are
 * one value over the cell, ∇n = 0, and a ray in it is straight, as in a
 * constant block. Only the cells asked about from a varying block are
 * tested (two bk_parallel passes over block slices: the varying blocks'
 * voxels, then their cells; the others stay 0). BK_ERR_RUNTIME when out of
 * memory. */
int oct_add_cells(int nx, int ny, int nz, const oct_source_t *src, int nsrc, oct_pyramid_t *pyr,
                  bk_error_t *err);
/* Bytes of p->level: the levels and the cell flags, what the march uploads. */
static inline size_t oct_bytes(const oct_pyramid_t *p) {
  return (size_t)p->bx * p->by * p->bz + p->cell_bytes;
}
void oct_free(oct_pyramid_t *p);

#ifdef __cplusplus
}
#endif
#endif
