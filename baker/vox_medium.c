/* vox_medium.c: the medium under the objects (see vox_medium.h). */
#include "vox_medium.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "vdbio.h"

/* The uniform medium over voxels [lo, hi): the grid's first touch, hundreds
 * of MiB at 256^3, so spread over the cores. */
typedef struct medium_fill {
  const scene_t *scene;
  volume_t *out;
} medium_fill_t;

static void fill_ior_range(void *ctx, size_t lo, size_t hi) {
  const medium_fill_t *f = ctx;
  for (size_t v = lo; v < hi; v++) f->out->ior[v] = f->scene->medium_ior;
}

static void fill_sigma_range(void *ctx, size_t lo, size_t hi) {
  const medium_fill_t *f = ctx;
  const float *ms = f->scene->medium_sigma_s, *ma = f->scene->medium_sigma_a;
  float *s = f->out->sigma_s, *a = f->out->sigma_a;
  for (size_t v = lo; v < hi; v++)
    for (int ch = 0; ch < 3; ch++) {
      s[3 * v + ch] = ms[ch];
      a[3 * v + ch] = ma[ch];
    }
}

int vox_medium(const scene_t *scene, volume_t *out, bk_error_t *err) {
  const grid_dims_t *d = &out->dims;
  const size_t count = grid_count(d);
  float *density = NULL;
  int rc = BK_OK;

  if (scene->ior_vdb.present) {
    const scene_vdb_ref_t *ref = &scene->ior_vdb;
    rc = vdbio_resample_float(ref->file, ref->grid, d, out->ior, ref->where, err);
    if (rc) goto error;
    size_t clamped = 0;
    float lowest = 1.0f;
    for (size_t v = 0; v < count; v++) {
      if (!isfinite(out->ior[v])) {
        rc = bk_fail(err, BK_ERR_INPUT, "%s: %s: grid \"%s\" gives a non-finite n at voxel %zu",
                     ref->where, ref->file, ref->grid, v);
        goto error;
      }
      if (out->ior[v] < 1.0f) { /* e.g. a zero background outside the active voxels */
        lowest = fminf(lowest, out->ior[v]);
        out->ior[v] = 1.0f;
        clamped++;
      }
    }
    if (clamped)
      bk_warn("%s: %s: grid \"%s\": %zu voxels had n < 1 (lowest %g), raised to 1", ref->where,
              ref->file, ref->grid, clamped, lowest);
  } else {
    medium_fill_t f = {scene, out};
    bk_parallel(count, BK_GRAIN, fill_ior_range, &f);
  }

  if (scene->density_vdb.present) {
    const scene_vdb_ref_t *ref = &scene->density_vdb;
    density = bk_calloc(count, sizeof *density, "voxelize: density_vdb", err);
    if (!density) {
      rc = BK_ERR_RUNTIME;
      goto error;
    }
    rc = vdbio_resample_float(ref->file, ref->grid, d, density, ref->where, err);
    if (rc) goto error;
    size_t clamped = 0;
    for (size_t v = 0; v < count; v++) {
      float rho = density[v];
      if (!isfinite(rho)) {
        rc = bk_fail(err, BK_ERR_INPUT, "%s: %s: grid \"%s\" gives a non-finite density at voxel %zu",
                     ref->where, ref->file, ref->grid, v);
        goto error;
      }
      if (rho < 0.0f) {
        rho = 0.0f;
        clamped++;
      }
      for (int ch = 0; ch < 3; ch++) {
        out->sigma_s[3 * v + ch] = scene->medium_sigma_s[ch] * rho;
        out->sigma_a[3 * v + ch] = scene->medium_sigma_a[ch] * rho;
      }
    }
    if (clamped)
      bk_warn("%s: %s: grid \"%s\": %zu voxels had a negative density, set to 0", ref->where,
              ref->file, ref->grid, clamped);
  } else {
    medium_fill_t f = {scene, out};
    bk_parallel(count, BK_GRAIN, fill_sigma_range, &f);
  }

  if (rc == BK_OK && scene_has_dispersion(scene)) { /* the medium's n in every channel */
    if (!(out->ior_rb = bk_calloc(count, 2 * sizeof(float), "voxelize: ior per channel", err)))
      return BK_ERR_RUNTIME;
    memcpy(out->ior_rb, out->ior, count * sizeof(float));
    memcpy(out->ior_rb + count, out->ior, count * sizeof(float));
  }
error:
  free(density);
  return rc;
}

void vox_blend_dispersion(const scene_object_t *obj, float w, size_t gv, size_t plane, float *rb) {
  for (int p = 0; p < 2; p++) {
    float n = scene_object_n(obj, 2 * p), *x = rb + p * plane + gv;
    *x = w >= 1.0f ? n : *x + w * (n - *x);
  }
}
