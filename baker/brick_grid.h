/* brick_grid.h: a float grid kept as 8³ bricks, a brick whose voxels all
 * hold one value stored as that value.
 *
 * For a grid that the bake must still write but no longer reads voxel by
 * voxel: the volume's n once the march has its {∇n, n} field (a glass
 * object in fog: n is constant in nine bricks of ten, so about 0.4 bytes
 * per voxel instead of 4). The values come back bit for bit. */
#ifndef BAKER_BRICK_GRID_H
#define BAKER_BRICK_GRID_H

#include <stddef.h>

#include "base/common.h"
#include "base/grid.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BG_SIDE 8

typedef struct brick_grid {
  grid_dims_t dims;
  int bx, by, bz;  /* bricks per axis */
  int *slot;       /* per brick: its index in values, or -1: constant */
  float *konst;    /* per brick: its value when constant */
  float *values;   /* BG_SIDE³ per stored brick, x fastest */
} brick_grid_t;

/* The bricks of dense (x fastest over dims). BK_ERR_RUNTIME when out of
 * memory (nothing to free then). */
int bg_build(const grid_dims_t *dims, const float *dense, brick_grid_t *out, bk_error_t *err);
/* Voxels [lo, hi) of the brick_grid_t at grid, in x-fastest order, into
 * out: a vdbio_fill_fn (formats/vdbio.h). */
void bg_fill(const void *grid, size_t lo, size_t hi, float *out);
/* Bytes the grid holds. */
size_t bg_bytes(const brick_grid_t *g);
void bg_free(brick_grid_t *g);

#ifdef __cplusplus
}
#endif
#endif
