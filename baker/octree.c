/* octree.c: the constant-block pyramid of n (see octree.h). */
#include "octree.h"

#include <stdlib.h>
#include <string.h>

#define OCT_WINDOW (2 * OCT_HALO + 1)

/* Min and max of one z-slice over the window [i-H, i+H] x [j-H, j+H]
 * (clipped), separably: along x into tmn/tmx, then along y into mn/mx. */
static void slice_minmax(int nx, int ny, const float *s, float *tmn, float *tmx, float *mn,
                         float *mx) {
  for (int j = 0; j < ny; j++) {
    const float *row = s + (size_t)j * nx;
    for (int i = 0; i < nx; i++) {
      int lo = i - OCT_HALO < 0 ? 0 : i - OCT_HALO, hi = i + OCT_HALO >= nx ? nx - 1 : i + OCT_HALO;
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
    int lo = j - OCT_HALO < 0 ? 0 : j - OCT_HALO, hi = j + OCT_HALO >= ny ? ny - 1 : j + OCT_HALO;
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

/* AND of the children of each parent block (factor 4 per axis). */
static void coarsen(const unsigned char *c, const int *cd, unsigned char *p, const int *pd) {
  memset(p, 1, (size_t)pd[0] * pd[1] * pd[2]);
  for (int k = 0; k < cd[2]; k++)
    for (int j = 0; j < cd[1]; j++)
      for (int i = 0; i < cd[0]; i++)
        if (!c[(size_t)i + (size_t)cd[0] * (j + (size_t)cd[1] * k)])
          p[(size_t)(i >> 2) + (size_t)pd[0] * ((j >> 2) + (size_t)pd[1] * (k >> 2))] = 0;
}

int oct_build(const grid_dims_t *d, const float *ior, oct_pyramid_t *out, bk_error_t *err) {
  int rc = BK_ERR_RUNTIME;
  const int nx = d->nx, ny = d->ny, nz = d->nz, B = 1 << OCT_BLOCK_SHIFT;
  const size_t plane = (size_t)nx * ny;
  float *work = NULL;
  unsigned char *c[OCT_LEVELS] = {NULL};
  int dims[OCT_LEVELS][3];
  memset(out, 0, sizeof *out);
  /* level 0: the finest blocks; each next level 4 times wider */
  dims[0][0] = (nx + B - 1) >> OCT_BLOCK_SHIFT;
  dims[0][1] = (ny + B - 1) >> OCT_BLOCK_SHIFT;
  dims[0][2] = (nz + B - 1) >> OCT_BLOCK_SHIFT;
  for (int l = 1; l < OCT_LEVELS; l++)
    for (int a = 0; a < 3; a++) dims[l][a] = (dims[l - 1][a] + 3) >> 2;
  out->bx = dims[0][0], out->by = dims[0][1], out->bz = dims[0][2];
  const size_t nb0 = (size_t)out->bx * out->by * out->bz;

  /* 2 scratch planes, then OCT_WINDOW slices of (min, max) planes */
  work = bk_calloc(plane, (2 + 2 * OCT_WINDOW) * sizeof(float), "octree: slice buffers", err);
  out->level = bk_calloc(nb0, 1, "octree: block levels", err);
  if (!work || !out->level) goto error;
  for (int l = 0; l < OCT_LEVELS; l++) {
    c[l] = bk_calloc((size_t)dims[l][0] * dims[l][1] * dims[l][2], 1, "octree: blocks", err);
    if (!c[l]) goto error;
  }
  memset(c[0], 1, nb0);
  float *tmn = work, *tmx = work + plane, *ring = work + 2 * plane;

  int computed = 0; /* slices [0, computed) are in the ring */
  for (int kc = 0; kc < nz; kc++) {
    int klo = kc - OCT_HALO < 0 ? 0 : kc - OCT_HALO;
    int khi = kc + OCT_HALO >= nz ? nz - 1 : kc + OCT_HALO;
    for (; computed <= khi; computed++) {
      float *mn = ring + (size_t)(2 * (computed % OCT_WINDOW)) * plane, *mx = mn + plane;
      slice_minmax(nx, ny, ior + (size_t)computed * plane, tmn, tmx, mn, mx);
    }
    unsigned char *crow = c[0] + (size_t)out->bx * out->by * (kc >> OCT_BLOCK_SHIFT);
    for (int j = 0; j < ny; j++)
      for (int i = 0; i < nx; i++) {
        size_t at = (size_t)j * nx + i;
        float a = ring[(size_t)(2 * (klo % OCT_WINDOW)) * plane + at], b = a;
        for (int k = klo; k <= khi; k++) {
          const float *mn = ring + (size_t)(2 * (k % OCT_WINDOW)) * plane;
          a = mn[at] < a ? mn[at] : a;
          b = mn[plane + at] > b ? mn[plane + at] : b;
        }
        if (a != b) crow[(i >> OCT_BLOCK_SHIFT) + (size_t)out->bx * (j >> OCT_BLOCK_SHIFT)] = 0;
      }
  }
  /* a parent is constant when all its children are: neighbouring constant
   * blocks overlap in their halos, so they share one value */
  for (int l = 1; l < OCT_LEVELS; l++) coarsen(c[l - 1], dims[l - 1], c[l], dims[l]);
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
  rc = BK_OK;
error:
  free(work);
  for (int l = 0; l < OCT_LEVELS; l++) free(c[l]);
  if (rc != BK_OK) oct_free(out);
  return rc;
}

void oct_free(oct_pyramid_t *p) {
  if (!p) return;
  free(p->level);
  p->level = NULL;
}
