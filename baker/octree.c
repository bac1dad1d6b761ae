/* octree.c: the constant-block pyramid (see octree.h). */
#include "octree.h"

#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"

/* A block is constant when its voxels' windows (the block grown by the halo
 * H, clipped to the grid) hold one value. A box holds one value exactly when
 * no two face-adjacent voxels in it differ, so each differing adjacent pair
 * clears the blocks whose grown box holds both of its voxels, and a voxel
 * costs three comparisons: the scan runs at memory speed. The exact
 * comparison (!=) is the one the march relies on (-0 == 0). */

/* Blocks b along one axis (block size B, n voxels, `last` the last block)
 * whose grown box [bB - H, min(bB + B - 1, n - 1) + H] holds [a0, a1]. */
static void pair_blocks(int a0, int a1, int H, int last, int *b0, int *b1) {
  const int B = 1 << OCT_BLOCK_SHIFT;
  int lo = a1 - H - (B - 1);
  lo = lo <= 0 ? 0 : (lo + B - 1) >> OCT_BLOCK_SHIFT;
  int hi = (a0 + H) >> OCT_BLOCK_SHIFT;
  *b0 = lo;
  *b1 = hi > last ? last : hi;
}

/* What one thread of the scan needs: the grid, the source, the halo and the
 * finest blocks' flags. */
typedef struct oct_scan {
  int nx, ny, nz, H, bx, by;
  const oct_source_t *src;
  int nsrc;
  unsigned char *c0;
} oct_scan_t;

static inline float src_at(const oct_source_t *s, int ch, size_t v) {
  return s->values[(size_t)s->stride * v + (size_t)ch];
}

/* Clears the blocks of rows [kb0, kb1] whose grown box holds the voxel box
 * [x0,x1] x [y0,y1] x [z0,z1]. */
static void clear_pair(const oct_scan_t *w, int kb0, int kb1, int x0, int x1, int y0, int y1,
                       int z0, int z1) {
  int i0, i1, j0, j1, k0, k1;
  pair_blocks(x0, x1, w->H, w->bx - 1, &i0, &i1);
  pair_blocks(y0, y1, w->H, w->by - 1, &j0, &j1);
  pair_blocks(z0, z1, w->H, kb1, &k0, &k1);
  if (k0 < kb0) k0 = kb0;
  for (int k = k0; k <= k1; k++)
    for (int j = j0; j <= j1; j++)
      memset(w->c0 + (size_t)i0 + (size_t)w->bx * ((size_t)j + (size_t)w->by * k), 0,
             (size_t)(i1 - i0 + 1));
}

/* Whether voxel (i, row) differs from its +x, +y (when `dy`) or +z (when
 * `dz`) neighbour in any channel: bit 0, 1, 2. */
static int voxel_differs(const oct_scan_t *w, size_t v, int i, int dy, int dz) {
  const size_t sy = (size_t)w->nx, sz = sy * (size_t)w->ny;
  int bits = 0;
  for (int s = 0; s < w->nsrc; s++)
    for (int ch = 0; ch < w->src[s].channels; ch++) {
      float a = src_at(&w->src[s], ch, v);
      if (i + 1 < w->nx && src_at(&w->src[s], ch, v + 1) != a) bits |= 1;
      if (dy && src_at(&w->src[s], ch, v + sy) != a) bits |= 2;
      if (dz && src_at(&w->src[s], ch, v + sz) != a) bits |= 4;
    }
  return bits;
}

/* Block rows [kb0, kb1): the slices their grown boxes reach, every voxel's
 * three forward pairs. Only these rows' flags are written, so threads on
 * other rows never touch the same byte. */
static void scan_rows(void *ctx, size_t kb0, size_t kb1) {
  const oct_scan_t *w = ctx;
  const int B = 1 << OCT_BLOCK_SHIFT, H = w->H;
  const int lo = (int)kb0 * B - H, hi = (int)kb1 * B - 1 + H;
  const int z0 = lo < 0 ? 0 : lo, z1 = hi > w->nz - 1 ? w->nz - 1 : hi;
  for (int k = z0; k <= z1; k++)
    for (int j = 0; j < w->ny; j++) {
      const size_t row = (size_t)w->nx * ((size_t)j + (size_t)w->ny * k);
      const int dy = j + 1 < w->ny, dz = k + 1 <= z1;
      for (int i = 0; i < w->nx; i++) {
        int bits = voxel_differs(w, row + (size_t)i, i, dy, dz);
        if (!bits) continue;
        if (bits & 1) clear_pair(w, (int)kb0, (int)kb1 - 1, i, i + 1, j, j, k, k);
        if (bits & 2) clear_pair(w, (int)kb0, (int)kb1 - 1, i, i, j, j + 1, k, k);
        if (bits & 4) clear_pair(w, (int)kb0, (int)kb1 - 1, i, i, j, j, k, k + 1);
      }
    }
}

/* AND of the children of each parent block (factor 4 per axis). */
static void coarsen(const unsigned char *c, const int *cd, unsigned char *p, const int *pd) {
  memset(p, 1, (size_t)pd[0] * pd[1] * pd[2]);
  for (int k = 0; k < cd[2]; k++)
    for (int j = 0; j < cd[1]; j++)
      for (int i = 0; i < cd[0]; i++)
        if (!c[(size_t)i + (size_t)cd[0] * (j + (size_t)cd[1] * k)])
          p[(size_t)(i >> 2) + (size_t)pd[0] * ((j >> 2) + (size_t)pd[1] * (k >> 2))] = 0;
}

/* Per finest block, the coarsest constant level from the per-level
 * constant flags c, and the voxels at each level. */
static void fill_levels(int nx, int ny, int nz, unsigned char **c, int dims[][3],
                        oct_pyramid_t *out) {
  const int B = 1 << OCT_BLOCK_SHIFT;
  for (int k = 0; k < out->bz; k++)
    for (int j = 0; j < out->by; j++)
      for (int i = 0; i < out->bx; i++) {
        int lv = 0;
        for (int l = OCT_LEVELS - 1; l >= 0 && !lv; l--) {
          int sh = 2 * l;
          if (c[l][(size_t)(i >> sh) + (size_t)dims[l][0] * ((j >> sh) + (size_t)dims[l][1] * (k >> sh))])
            lv = l + 1;
        }
        out->level[(size_t)i + (size_t)out->bx * (j + (size_t)out->by * k)] = (unsigned char)lv;
        int x0 = i * B, y0 = j * B, z0 = k * B;
        uint64_t w = (uint64_t)(x0 + B > nx ? nx - x0 : B) * (uint64_t)(y0 + B > ny ? ny - y0 : B) *
                     (uint64_t)(z0 + B > nz ? nz - z0 : B);
        out->voxels_at_level[lv] += w;
      }
}

int oct_build_fields(int nx, int ny, int nz, const oct_source_t *src, int nsrc, int halo,
                     oct_pyramid_t *out, bk_error_t *err) {
  int rc = BK_ERR_RUNTIME;
  /* each voxel's window must overlap its neighbour's for the windows to
   * chain into one constant block: at least 1 */
  const int H = halo < 1 ? 1 : halo > OCT_MAX_HALO ? OCT_MAX_HALO : halo;
  unsigned char *c[OCT_LEVELS] = {NULL};
  int dims[OCT_LEVELS][3];
  memset(out, 0, sizeof *out);
  /* level 0: the finest blocks; each next level 4 times wider */
  dims[0][0] = rc_blocks(nx), dims[0][1] = rc_blocks(ny), dims[0][2] = rc_blocks(nz);
  for (int l = 1; l < OCT_LEVELS; l++)
    for (int a = 0; a < 3; a++) dims[l][a] = (dims[l - 1][a] + 3) >> 2;
  out->bx = dims[0][0], out->by = dims[0][1], out->bz = dims[0][2];
  const size_t nb0 = (size_t)out->bx * out->by * out->bz;

  out->level = bk_calloc(nb0, 1, "octree: block levels", err);
  if (!out->level) goto error;
  for (int l = 0; l < OCT_LEVELS; l++) {
    c[l] = bk_calloc((size_t)dims[l][0] * dims[l][1] * dims[l][2], 1, "octree: blocks", err);
    if (!c[l]) goto error;
  }
  memset(c[0], 1, nb0);
  oct_scan_t w = {nx, ny, nz, H, out->bx, out->by, src, nsrc, c[0]};
  /* a thread's slab re-reads 2H slices: at least 16 block rows each */
  bk_parallel((size_t)out->bz, 16, scan_rows, &w);
  /* a parent is constant when all its children are: neighbouring constant
   * blocks overlap in their halos, so they share one value */
  for (int l = 1; l < OCT_LEVELS; l++) coarsen(c[l - 1], dims[l - 1], c[l], dims[l]);
  fill_levels(nx, ny, nz, c, dims, out);
  rc = BK_OK;
error:
  for (int l = 0; l < OCT_LEVELS; l++) free(c[l]);
  if (rc != BK_OK) oct_free(out);
  return rc;
}

int oct_build(const grid_dims_t *d, const float *ior, oct_pyramid_t *out, bk_error_t *err) {
  const oct_source_t n = {ior, 1, 1};
  return oct_build_fields(d->nx, d->ny, d->nz, &n, 1, OCT_HALO, out, err);
}

void oct_free(oct_pyramid_t *p) {
  if (!p) return;
  free(p->level);
  p->level = NULL;
}
