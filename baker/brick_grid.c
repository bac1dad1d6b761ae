/* brick_grid.c: a float grid as 8³ bricks (see brick_grid.h). */
#include "brick_grid.h"

#include <stdlib.h>
#include <string.h>

/* Brick b's voxel range clipped to the grid, and its first voxel. */
static void brick_box(const brick_grid_t *g, size_t b, int lo[3], int hi[3]) {
  const size_t bx = (size_t)g->bx, by = (size_t)g->by;
  const int o[3] = {BG_SIDE * (int)(b % bx), BG_SIDE * (int)(b / bx % by),
                    BG_SIDE * (int)(b / (bx * by))};
  const int n[3] = {g->dims.nx, g->dims.ny, g->dims.nz};
  for (int a = 0; a < 3; a++) {
    lo[a] = o[a];
    hi[a] = o[a] + BG_SIDE < n[a] ? o[a] + BG_SIDE : n[a];
  }
}

/* Pass 1: slot 1 where a brick's voxels are not all bit-equal to its first
 * (so -0.0 and 0.0, or NaNs, keep their bits), else its value. */
static void classify(const float *dense, brick_grid_t *g, size_t bricks) {
  const grid_dims_t *d = &g->dims;
  for (size_t b = 0; b < bricks; b++) {
    int l[3], h[3], varies = 0;
    brick_box(g, b, l, h);
    const float *first = dense + grid_index(d, l[0], l[1], l[2]);
    for (int k = l[2]; k < h[2] && !varies; k++)
      for (int j = l[1]; j < h[1] && !varies; j++) {
        const float *row = dense + grid_index(d, l[0], j, k);
        for (int i = 0; i < h[0] - l[0]; i++) varies |= memcmp(row + i, first, sizeof *first) != 0;
      }
    g->slot[b] = varies;
    g->konst[b] = *first;
  }
}

/* Pass 2: the stored bricks' voxels. */
static void copy_bricks(const float *dense, brick_grid_t *g, size_t bricks) {
  for (size_t b = 0; b < bricks; b++) {
    if (g->slot[b] < 0) continue;
    int l[3], h[3];
    brick_box(g, b, l, h);
    float *v = g->values + (size_t)g->slot[b] * BG_SIDE * BG_SIDE * BG_SIDE;
    for (int k = l[2]; k < h[2]; k++)
      for (int j = l[1]; j < h[1]; j++)
        memcpy(v + BG_SIDE * ((j - l[1]) + BG_SIDE * (k - l[2])),
               dense + grid_index(&g->dims, l[0], j, k), (size_t)(h[0] - l[0]) * sizeof(float));
  }
}

int bg_build(const grid_dims_t *dims, const float *dense, brick_grid_t *out, bk_error_t *err) {
  memset(out, 0, sizeof *out);
  out->dims = *dims;
  out->bx = (dims->nx + BG_SIDE - 1) / BG_SIDE;
  out->by = (dims->ny + BG_SIDE - 1) / BG_SIDE;
  out->bz = (dims->nz + BG_SIDE - 1) / BG_SIDE;
  const size_t bricks = (size_t)out->bx * out->by * out->bz;
  out->slot = bk_calloc(bricks, sizeof(int), "brick grid: table", err);
  out->konst = bk_calloc(bricks, sizeof(float), "brick grid: constants", err);
  if (!out->slot || !out->konst) goto fail;
  /* one thread: the bake packs n between OpenCL's start and its kernel
   * build, where short-lived worker threads made LeakSanitizer's exit-time
   * tracer crash (mitsuba_small under ASan with a cold kernel cache, three
   * runs of three; in none of two with this). One read of n: 14 ms at 256^3. */
  classify(dense, out, bricks);
  int stored = 0;
  for (size_t b = 0; b < bricks; b++) out->slot[b] = out->slot[b] ? stored++ : -1;
  out->values = bk_calloc((size_t)stored * BG_SIDE * BG_SIDE * BG_SIDE, sizeof(float),
                          "brick grid: bricks", err);
  if (!out->values && stored) goto fail;
  copy_bricks(dense, out, bricks);
  return BK_OK;
fail:
  bg_free(out);
  return BK_ERR_RUNTIME;
}

void bg_fill(const void *grid, size_t lo, size_t hi, float *out) {
  const brick_grid_t *g = grid;
  const grid_dims_t *d = &g->dims;
  const size_t nx = (size_t)d->nx, plane = nx * (size_t)d->ny;
  size_t at = lo;
  while (at < hi) { /* a run of one row inside one brick at a time */
    const int i = (int)(at % nx), j = (int)(at / nx % (size_t)d->ny), k = (int)(at / plane);
    const size_t b = (size_t)(i / BG_SIDE) + (size_t)g->bx * ((size_t)(j / BG_SIDE) +
                                                             (size_t)g->by * (size_t)(k / BG_SIDE));
    size_t run = (size_t)(BG_SIDE - i % BG_SIDE);
    if (run > nx - (size_t)i) run = nx - (size_t)i;
    if (run > hi - at) run = hi - at;
    if (g->slot[b] < 0) {
      for (size_t r = 0; r < run; r++) out[r] = g->konst[b];
    } else {
      const size_t in = (size_t)(i % BG_SIDE) +
                        BG_SIDE * ((size_t)(j % BG_SIDE) + BG_SIDE * (size_t)(k % BG_SIDE));
      const float *v = g->values + (size_t)g->slot[b] * BG_SIDE * BG_SIDE * BG_SIDE + in;
      memcpy(out, v, run * sizeof(float));
    }
    out += run;
    at += run;
  }
}

size_t bg_bytes(const brick_grid_t *g) {
  const size_t bricks = (size_t)g->bx * g->by * g->bz;
  size_t stored = 0;
  for (size_t b = 0; g->slot && b < bricks; b++) stored += g->slot[b] >= 0;
  return bricks * (sizeof(int) + sizeof(float)) +
         stored * BG_SIDE * BG_SIDE * BG_SIDE * sizeof(float);
}

void bg_free(brick_grid_t *g) {
  if (!g) return;
  free(g->slot);
  free(g->konst);
  free(g->values);
  memset(g, 0, sizeof *g);
}
