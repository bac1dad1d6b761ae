/* octree.c: the constant-block pyramid (see octree.h). */
#include "octree.h"

#include <stdlib.h>
#include <stdatomic.h>
#include <string.h>

#include "base/parallel.h"

/* A block is constant when its voxels' windows (the block grown by the halo
 * H, clipped to the grid) hold one value. A box holds one value exactly when
 * no two face-adjacent voxels in it differ, so a block is cleared when its
 * grown box holds both voxels of a differing pair. A voxel costs three
 * comparisons per channel; the pairs are then reduced per row (per block of
 * the row), per slice (per block column) and per block row, each a few
 * byte ORs per block, not a clear of every block a pair touches (that cost
 * ~25 instructions per voxel where the whole field varies: the view's lit
 * fog). The exact comparison (!=) is the one the march relies on (-0 == 0). */

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
 * finest blocks' flags; `failed` is set when a thread's scratch could not be
 * allocated. */
typedef struct oct_scan {
  int nx, ny, nz, H, bx, by;
  const oct_source_t *src;
  int nsrc;
  unsigned char *c0;
  atomic_int failed;
} oct_scan_t;

/* Source s's entry of voxel (i, j, k) of an nx x ny grid (its padded
 * layout's when s->pad): the index of its first float over the stride. */
static size_t source_index(const oct_source_t *s, int nx, int ny, int i, int j, int k) {
  const size_t pad = s->pad ? 1 : 0, sx = (size_t)nx + 2 * pad, sy = (size_t)ny + 2 * pad;
  return (size_t)s->stride * ((size_t)i + pad + sx * ((size_t)j + pad + sy * ((size_t)k + pad)));
}

/* Row (j, k): f[i] gets bit 0, 1, 2 when voxel i differs from its +x, +y
 * (when `dy`) or +z (when `dz`) neighbour in any channel; returns the OR of
 * all. Channel by channel along the row, so the loop is branch-free. */
static unsigned row_pairs(const oct_scan_t *w, int j, int k, int dy, int dz, unsigned char *f) {
  const int n = w->nx;
  memset(f, 0, (size_t)n);
  for (int s = 0; s < w->nsrc; s++)
    for (int ch = 0; ch < w->src[s].channels; ch++) {
      const size_t st = (size_t)w->src[s].stride, pad = w->src[s].pad ? 1 : 0;
      const size_t sx = (size_t)n + 2 * pad, sy = (size_t)w->ny + 2 * pad;
      const float *p = w->src[s].values + source_index(&w->src[s], n, w->ny, 0, j, k) + (size_t)ch;
      /* without a neighbour, the voxel itself: masked off below */
      const size_t oy = dy ? st * sx : 0, oz = dz ? st * sx * sy : 0;
      for (int i = 0; i < n; i++) {
        const float *q = p + st * (size_t)i;
        const float a = q[0], x = i + 1 < n ? q[st] : a;
        f[i] |= (unsigned char)((x != a) | (q[oy] != a) << 1 | (q[oz] != a) << 2);
      }
    }
  const unsigned mask = 1u | (dy ? 2u : 0u) | (dz ? 4u : 0u);
  unsigned any = 0;
  for (int i = 0; i < n; i++) any |= f[i] &= (unsigned char)mask;
  return any;
}

/* One row's pair bits f[0..nx) reduced per block of the row (r[0..bx)):
 * bit 0 when an x pair lies inside the block's grown x range, bits 1, 2 when
 * a y or z pair starts in it (its other voxel is in the next row or slice). */
static void row_blocks(const oct_scan_t *w, const unsigned char *f, unsigned char *r) {
  const int B = 1 << OCT_BLOCK_SHIFT, H = w->H, n = w->nx;
  for (int b = 0; b < w->bx; b++) {
    int g0 = b * B - H, g1 = (b * B + B - 1 < n - 1 ? b * B + B - 1 : n - 1) + H;
    g0 = g0 < 0 ? 0 : g0;
    g1 = g1 > n - 1 ? n - 1 : g1;
    unsigned acc = f[g1] & 6u; /* the last voxel's x pair leaves the box */
    for (int i = g0; i < g1; i++) acc |= f[i];
    r[b] = (unsigned char)acc;
  }
}

/* Slice k reduced per block column (s[bi + bx bj]): bit 0 when an x or y
 * pair lies inside the block's grown box in x and y, bit 1 when a z pair
 * starts there (`dz`: the slab holds slice k + 1). f, r: nx and bx bytes of
 * scratch. */
static void slice_blocks(const oct_scan_t *w, int k, int dz, unsigned char *f, unsigned char *r,
                         unsigned char *s) {
  const size_t bx = (size_t)w->bx;
  memset(s, 0, bx * (size_t)w->by);
  for (int j = 0; j < w->ny; j++) {
    if (!row_pairs(w, j, k, j + 1 < w->ny, dz, f)) continue;
    row_blocks(w, f, r);
    int a0, a1, p0, p1; /* block rows whose grown y range holds j; and j + 1 too */
    pair_blocks(j, j, w->H, w->by - 1, &a0, &a1);
    pair_blocks(j, j + 1, w->H, w->by - 1, &p0, &p1);
    for (int bj = a0; bj <= a1; bj++) {
      const unsigned keep = bj >= p0 && bj <= p1 ? 7u : 5u; /* a y pair needs j + 1 inside */
      unsigned char *sr = s + bx * (size_t)bj;
      for (size_t bi = 0; bi < bx; bi++) {
        const unsigned v = r[bi] & keep;
        sr[bi] |= (unsigned char)((v & 3u ? 1u : 0u) | (v & 4u ? 2u : 0u));
      }
    }
  }
}

/* Block rows [kb0, kb1): the slices their grown boxes reach, every voxel's
 * three forward pairs, reduced per row, then per slice, then cleared in the
 * blocks whose grown box holds the slice. Only these rows' flags are
 * written, so threads on other rows never touch the same byte. */
static void scan_rows(void *ctx, size_t kb0, size_t kb1) {
  oct_scan_t *w = ctx;
  const int B = 1 << OCT_BLOCK_SHIFT, H = w->H;
  const int lo = (int)kb0 * B - H, hi = (int)kb1 * B - 1 + H;
  const int z0 = lo < 0 ? 0 : lo, z1 = hi > w->nz - 1 ? w->nz - 1 : hi;
  const size_t plane = (size_t)w->bx * (size_t)w->by;
  unsigned char *f = malloc((size_t)w->nx + (size_t)w->bx + plane);
  if (!f) {
    atomic_store(&w->failed, 1);
    return;
  }
  unsigned char *r = f + w->nx, *s = r + w->bx;
  for (int k = z0; k <= z1; k++) {
    slice_blocks(w, k, k + 1 <= z1, f, r, s);
    int a0, a1, p0, p1; /* block rows whose grown z range holds k; and k + 1 too */
    pair_blocks(k, k, H, (int)kb1 - 1, &a0, &a1);
    pair_blocks(k, k + 1, H, (int)kb1 - 1, &p0, &p1);
    for (int bk = a0 < (int)kb0 ? (int)kb0 : a0; bk <= a1; bk++) {
      const unsigned keep = bk >= p0 && bk <= p1 ? 3u : 1u; /* a z pair needs k + 1 inside */
      unsigned char *c = w->c0 + plane * (size_t)bk;
      for (size_t b = 0; b < plane; b++)
        if (s[b] & keep) c[b] = 0;
    }
  }
  free(f);
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
  oct_scan_t w = {nx, ny, nz, H, out->bx, out->by, src, nsrc, c[0], 0};
  /* a thread's slab re-reads 2H slices: at least 16 block rows each */
  bk_parallel((size_t)out->bz, 16, scan_rows, &w);
  if (atomic_load(&w.failed)) {
    bk_fail(err, BK_ERR_RUNTIME, "octree: cannot allocate a slice of block flags");
    goto error;
  }
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

/* ---- the field's constant cells (oct_add_cells) ---- */

/* Bytes of a row of one bit per entry along x. */
static size_t bit_row_bytes(int entries) { return ((size_t)entries + 7) / 8; }

/* What the two passes of the cell flags need: `odd` holds a bit per voxel,
 * set where the voxel differs from a face neighbour in some channel. */
typedef struct oct_cells {
  int nx, ny, nz;
  const oct_source_t *src;
  int nsrc;
  const oct_pyramid_t *pyr;
  unsigned char *odd, *flags;
} oct_cells_t;

/* Channel ch of source s at voxel (i, j, k). */
static float cell_value(const oct_cells_t *w, const oct_source_t *s, int ch, int i, int j, int k) {
  return s->values[source_index(s, w->nx, w->ny, i, j, k) + (size_t)ch];
}

/* Whether voxel c differs from one of its face neighbours in the grid. */
static int voxel_odd(const oct_cells_t *w, const int *c) {
  const int n[3] = {w->nx, w->ny, w->nz};
  for (int s = 0; s < w->nsrc; s++)
    for (int ch = 0; ch < w->src[s].channels; ch++) {
      const float a = cell_value(w, &w->src[s], ch, c[0], c[1], c[2]);
      for (int ax = 0; ax < 3; ax++)
        for (int step = -1; step <= 1; step += 2) {
          int q[3] = {c[0], c[1], c[2]};
          q[ax] += step;
          if (q[ax] >= 0 && q[ax] < n[ax] && cell_value(w, &w->src[s], ch, q[0], q[1], q[2]) != a)
            return 1;
        }
    }
  return 0;
}

static int bit_at(const unsigned char *bits, size_t row_bytes, int ny, int i, int j, int k) {
  return bits[(size_t)(i >> 3) + row_bytes * ((size_t)j + (size_t)ny * k)] >> (i & 7) & 1;
}

/* Whether block (bx, by, bz) lies in the grid and varies. */
static int block_varies(const oct_pyramid_t *p, int bx, int by, int bz) {
  if (bz < 0 || bz >= p->bz) return 0;
  return !p->level[(size_t)bx + (size_t)p->bx * ((size_t)by + (size_t)p->by * bz)];
}

/* Pass 1, block slices [b0, b1): the odd voxels of the varying blocks (a
 * constant block's voxels equal their neighbours, the halo reaching past
 * them). A block's 2 voxels along x share a byte, its rows are its own. */
static void odd_rows(void *ctx, size_t b0, size_t b1) {
  oct_cells_t *w = ctx;
  const oct_pyramid_t *p = w->pyr;
  const size_t rb = bit_row_bytes(w->nx);
  for (int bz = (int)b0; bz < (int)b1; bz++)
    for (int by = 0; by < p->by; by++)
      for (int bx = 0; bx < p->bx; bx++) {
        if (!block_varies(p, bx, by, bz)) continue;
        for (int v = 0; v < 8; v++) {
          const int c[3] = {2 * bx + (v & 1), 2 * by + (v >> 1 & 1), 2 * bz + (v >> 2)};
          if (c[0] >= w->nx || c[1] >= w->ny || c[2] >= w->nz || !voxel_odd(w, c)) continue;
          w->odd[(size_t)(c[0] >> 3) + rb * ((size_t)c[1] + (size_t)w->ny * c[2])] |=
              (unsigned char)(1u << (c[0] & 7));
        }
      }
}

/* Whether cell p's corners (voxels p - 1 and p per axis, clamped onto the
 * grid as the padding replicates the edge) are all not odd: then they are
 * one value, and so are their face neighbours, which their central
 * differences read. */
static int cell_constant(const oct_cells_t *w, const int *p) {
  const int n[3] = {w->nx, w->ny, w->nz};
  const size_t rb = bit_row_bytes(w->nx);
  int lo[3], hi[3];
  for (int a = 0; a < 3; a++) {
    lo[a] = p[a] - 1 < 0 ? 0 : p[a] - 1;
    hi[a] = p[a] > n[a] - 1 ? n[a] - 1 : p[a];
  }
  for (int k = lo[2]; k <= hi[2]; k++)
    for (int j = lo[1]; j <= hi[1]; j++)
      for (int i = lo[0]; i <= hi[0]; i++)
        if (bit_at(w->odd, rb, w->ny, i, j, k)) return 0;
  return 1;
}

/* Pass 2, block slices [b0, b1) (up to bz inclusive: the last cell
 * plane): cell planes 2 bz and 2 bz + 1, so that a thread's bytes are its
 * own. A cell is asked about only from a voxel of a varying block
 * (pm_march_leg), voxel p - 1 or p per axis, so a varying block b asks
 * cells 2b to 2b + 2 per axis: only those are tested, the others stay 0. */
static void cell_rows(void *ctx, size_t b0, size_t b1) {
  oct_cells_t *w = ctx;
  const oct_pyramid_t *P = w->pyr;
  const rc_dims n = {w->nx, w->ny, w->nz};
  for (int bz = (int)b0; bz < (int)b1; bz++)
    for (int by = 0; by < P->by; by++)
      for (int bx = 0; bx < P->bx; bx++) {
        /* this slice's block asks planes 2 bz, 2 bz + 1; the one below, 2 bz */
        const int z1 = block_varies(P, bx, by, bz) ? 2 * bz + 1
                       : block_varies(P, bx, by, bz - 1) ? 2 * bz : -1;
        for (int pz = 2 * bz; pz <= z1 && pz <= w->nz; pz++)
          for (int py = 2 * by; py <= 2 * by + 2 && py <= w->ny; py++)
            for (int px = 2 * bx; px <= 2 * bx + 2 && px <= w->nx; px++) {
              const int p[3] = {px, py, pz};
              if (cell_constant(w, p))
                w->flags[rc_cell_byte(n, px, py, pz)] |= (unsigned char)(1u << (px & 7));
            }
      }
}

int oct_add_cells(int nx, int ny, int nz, const oct_source_t *src, int nsrc, oct_pyramid_t *pyr,
                  bk_error_t *err) {
  const size_t nb0 = (size_t)pyr->bx * pyr->by * pyr->bz;
  const rc_dims n = {nx, ny, nz};
  const size_t bytes = (size_t)rc_cell_byte(n, nx, ny, nz) + 1;
  unsigned char *odd = calloc(bit_row_bytes(nx) * (size_t)ny * (size_t)nz, 1);
  unsigned char *all = odd ? realloc(pyr->level, nb0 + bytes) : NULL;
  if (!all) {
    free(odd);
    return bk_fail(err, BK_ERR_RUNTIME, "octree: out of memory for %zu bytes of cell flags", bytes);
  }
  pyr->level = all;
  pyr->cell_bytes = bytes;
  memset(all + nb0, 0, bytes);
  oct_cells_t w = {nx, ny, nz, src, nsrc, pyr, odd, all + nb0};
  bk_parallel((size_t)pyr->bz, 8, odd_rows, &w);
  bk_parallel((size_t)pyr->bz + 1, 8, cell_rows, &w);
  free(odd);
  return BK_OK;
}

void oct_free(oct_pyramid_t *p) {
  if (!p) return;
  free(p->level);
  p->level = NULL;
}
