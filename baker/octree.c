/* octree.c: the constant-block pyramid (see octree.h). */
#include "octree.h"

#include <stdlib.h>
#include <string.h>

/* Min and max of one z-slice over the window [i-H, i+H] x [j-H, j+H]
 * (clipped), separably: along x into tmn/tmx, then along y into mn/mx. */
static void slice_minmax(int nx, int ny, int H, const float *s, float *tmn, float *tmx, float *mn,
                         float *mx) {
  for (int j = 0; j < ny; j++) {
    const float *row = s + (size_t)j * nx;
    for (int i = 0; i < nx; i++) {
      int lo = i - H < 0 ? 0 : i - H, hi = i + H >= nx ? nx - 1 : i + H;
      float a = row[lo], b = row[lo];
      for (int q = lo + 1; q <= hi; q++) {
        a = row[q] < a ? row[q] : a;
        b = row[q] > b ? row[q] : b;
      }
      tmn[(size_t)j * nx + i] = a;
      tmx[(size_t)j * nx + i] = b;
    }
  }
  for (int j = 0; j < ny; j++) {
    int lo = j - H < 0 ? 0 : j - H, hi = j + H >= ny ? ny - 1 : j + H;
    float *omn = mn + (size_t)j * nx, *omx = mx + (size_t)j * nx;
    memcpy(omn, tmn + (size_t)lo * nx, (size_t)nx * sizeof(float));
    memcpy(omx, tmx + (size_t)lo * nx, (size_t)nx * sizeof(float));
    for (int q = lo + 1; q <= hi; q++) {
      const float *a = tmn + (size_t)q * nx, *b = tmx + (size_t)q * nx;
      for (int i = 0; i < nx; i++) {
        omn[i] = a[i] < omn[i] ? a[i] : omn[i];
        omx[i] = b[i] > omx[i] ? b[i] : omx[i];
      }
    }
  }
}

/* Scratch of one channel's scan: two planes, a plane for a strided channel's
 * slice, then a ring of 2H+1 slices of (min, max) planes. */
typedef struct oct_scan {
  int nx, ny, nz, H;
  float *tmn, *tmx, *slice, *ring;
} oct_scan_t;

/* Slice k of channel ch of src as a contiguous plane. */
static const float *channel_slice(oct_scan_t *w, const oct_source_t *src, int ch, int k) {
  const size_t plane = (size_t)w->nx * w->ny;
  const float *p = src->values + (size_t)src->stride * plane * k + ch;
  if (src->stride == 1) return p;
  for (size_t v = 0; v < plane; v++) w->slice[v] = p[(size_t)src->stride * v];
  return w->slice;
}

/* Clears, in the finest blocks c0 (bx x by per z), every block holding a
 * voxel whose window sees channel ch of src vary. */
static void scan_channel(oct_scan_t *w, const oct_source_t *src, int ch,
                         unsigned char *c0, int bx, int by) {
  const int nx = w->nx, ny = w->ny, nz = w->nz, H = w->H, W = 2 * H + 1;
  const size_t plane = (size_t)nx * ny;
  int computed = 0; /* slices [0, computed) are in the ring */
  for (int kc = 0; kc < nz; kc++) {
    int klo = kc - H < 0 ? 0 : kc - H, khi = kc + H >= nz ? nz - 1 : kc + H;
    for (; computed <= khi; computed++) {
      float *mn = w->ring + (size_t)(2 * (computed % W)) * plane, *mx = mn + plane;
      slice_minmax(nx, ny, H, channel_slice(w, src, ch, computed), w->tmn, w->tmx, mn, mx);
    }
    unsigned char *crow = c0 + (size_t)bx * by * (kc >> OCT_BLOCK_SHIFT);
    for (int j = 0; j < ny; j++)
      for (int i = 0; i < nx; i++) {
        size_t at = (size_t)j * nx + i;
        float a = w->ring[(size_t)(2 * (klo % W)) * plane + at], b = a;
        for (int k = klo; k <= khi; k++) {
          const float *mn = w->ring + (size_t)(2 * (k % W)) * plane;
          a = mn[at] < a ? mn[at] : a;
          b = mn[plane + at] > b ? mn[plane + at] : b;
        }
        if (a != b) crow[(i >> OCT_BLOCK_SHIFT) + (size_t)bx * (j >> OCT_BLOCK_SHIFT)] = 0;
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
  const size_t plane = (size_t)nx * ny;
  /* each voxel's window must overlap its neighbour's for the windows to
   * chain into one constant block: at least 1 */
  const int H = halo < 1 ? 1 : halo > OCT_MAX_HALO ? OCT_MAX_HALO : halo;
  float *work = NULL;
  unsigned char *c[OCT_LEVELS] = {NULL};
  int dims[OCT_LEVELS][3];
  memset(out, 0, sizeof *out);
  /* level 0: the finest blocks; each next level 4 times wider */
  dims[0][0] = rc_blocks(nx), dims[0][1] = rc_blocks(ny), dims[0][2] = rc_blocks(nz);
  for (int l = 1; l < OCT_LEVELS; l++)
    for (int a = 0; a < 3; a++) dims[l][a] = (dims[l - 1][a] + 3) >> 2;
  out->bx = dims[0][0], out->by = dims[0][1], out->bz = dims[0][2];
  const size_t nb0 = (size_t)out->bx * out->by * out->bz;

  work = bk_calloc(plane, (3 + 2 * (2 * H + 1)) * sizeof(float), "octree: slice buffers", err);
  out->level = bk_calloc(nb0, 1, "octree: block levels", err);
  if (!work || !out->level) goto error;
  for (int l = 0; l < OCT_LEVELS; l++) {
    c[l] = bk_calloc((size_t)dims[l][0] * dims[l][1] * dims[l][2], 1, "octree: blocks", err);
    if (!c[l]) goto error;
  }
  memset(c[0], 1, nb0);
  oct_scan_t w = {nx, ny, nz, H, work, work + plane, work + 2 * plane, work + 3 * plane};
  for (int s = 0; s < nsrc; s++)
    for (int ch = 0; ch < src[s].channels; ch++) scan_channel(&w, &src[s], ch, c[0], out->bx, out->by);
  /* a parent is constant when all its children are: neighbouring constant
   * blocks overlap in their halos, so they share one value */
  for (int l = 1; l < OCT_LEVELS; l++) coarsen(c[l - 1], dims[l - 1], c[l], dims[l]);
  fill_levels(nx, ny, nz, c, dims, out);
  rc = BK_OK;
error:
  free(work);
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
