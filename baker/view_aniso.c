/* view_aniso.c: the phase lobes of an anisotropic medium for the camera
 * rays (view_aniso.h). */
#include "view_aniso.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "field.h"
#include "kernels/view_march.h"
#include "vdbio.h"
#include "view_arrays.h"

/* g·v/y in index space (m: world -> index, a similarity), its length at
 * most |g| (VIEW_ANISO_MAX): the HG lobe of the light whose flux is v and
 * luminance y, scattered once more by g; zero where y is. */
static void aniso_lobe(const double m[3][3], const double *v, double y, double g, float *out) {
  double d[3], len = 0.0;
  for (int r = 0; r < 3; r++) {
    d[r] = m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2];
    len += d[r] * d[r];
  }
  len = sqrt(len);
  if (!(y > 0.0) || !(len > 0.0)) return; /* zeroed: isotropic */
  double k = fmin(len / y, 1.0) * fmax(fmin(g, VIEW_ANISO_MAX), -VIEW_ANISO_MAX) / len;
  for (int r = 0; r < 3; r++) out[r] = (float)(k * d[r]);
}

/* The phase lobes per voxel (view_march.h), in index space: the
 * uncollided light, share u = Y0 / Y(L̄), as an HG lobe of its own flux F0
 * (a beam along it for one light: |F0| = Y0), aniso = {g F0 / Y0, u}; the
 * scattered rest as an HG lobe of its flux F − F0, aniso_s =
 * {g (F − F0) / (Y(L̄) − Y0), 0}; each |g·mean| at most VIEW_ANISO_MAX.
 * Only with radiance_flux and phase_g (without radiance_uncollided: u = 0;
 * without radiance_flux_uncollided, files of before it: F0 = Y0 F̂, one
 * direction for both, which misplaces the lobes in thick fog). */
static void aniso_voxel(const float *F, float g, const float *l, const float *y0, const float *f0,
                        const double m[3][3], float *a, float *as) {
  double y = 0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2], len = 0.0;
  for (int r = 0; r < 3; r++) len += (double)F[r] * F[r];
  len = sqrt(len);
  if (!(y > 0.0)) return; /* zeroed: isotropic */
  double u = y0 ? fmin(fmax(*y0 / y, 0.0), 1.0) : 0.0, beam[3], rest[3];
  for (int r = 0; r < 3; r++) {
    beam[r] = f0 ? f0[r] : len > 0.0 ? u * y * F[r] / len : 0.0;
    rest[r] = F[r] - beam[r];
  }
  aniso_lobe(m, beam, u * y, g, a);
  if (u < 1.0) aniso_lobe(m, rest, (1.0 - u) * y, g, as);
  a[3] = (float)u;
}

/* `radiance_camera`'s point (bake.h bake_camera_meta); 0 when the file
 * names none, which leaves the lobes alone. */
static int camera_point(const char *path, double out[3]) {
  char text[128];
  bk_error_t e = {0, ""};
  if (vdbio_read_meta(path, "radiance_camera_position", text, sizeof text, &e) != BK_OK ||
      sscanf(text, "[%lf, %lf, %lf]", &out[0], &out[1], &out[2]) != 3 ||
      !(isfinite(out[0]) && isfinite(out[1]) && isfinite(out[2]))) {
    bk_warn("%s: grid \"radiance_camera\" without a readable radiance_camera_position: "
            "the phase towards the camera comes from the flux's lobes", path);
    return 0;
  }
  return 1;
}

/* The lobes of one slab's rows, in chunks side by side, written straight
 * into the padded layout: per chunk the first voxel with a g out of range
 * (SIZE_MAX: none) and whether any lobe is not isotropic (the same answers
 * in any order). */
typedef struct aniso_ctx {
  const float *F, *g, *rad, *unc, *func, *cam; /* cam: NULL unless camera_phase */
  double m[3][3];                             /* world -> index, unit length */
  float *a, *as;
  int nx, ny;
  size_t row0; /* the slab's first row */
  size_t bad[VIEW_CHUNKS];
  int any[VIEW_CHUNKS];
} aniso_ctx_t;

static void aniso_chunk(void *arg, size_t k, size_t lo, size_t hi) {
  aniso_ctx_t *x = arg;
  int any = x->any[k];
  for (size_t row = x->row0 + lo; row < x->row0 + hi; row++) {
    float *a = x->a + 4 * view_padded_row(x->nx, x->ny, row);
    float *as = x->as + 4 * view_padded_row(x->nx, x->ny, row);
    memset(a, 0, 4 * sizeof(float) * (size_t)x->nx); /* zero: isotropic */
    memset(as, 0, 4 * sizeof(float) * (size_t)x->nx);
    for (size_t i = row * (size_t)x->nx; i < (row + 1) * (size_t)x->nx; i++, a += 4, as += 4) {
      if (!(x->g[i] > -1.0f && x->g[i] < 1.0f)) {
        if (x->bad[k] == SIZE_MAX) x->bad[k] = i;
        continue;
      }
      const float *unc = x->unc ? x->unc + i : NULL;
      aniso_voxel(x->F + 3 * i, x->g[i], x->rad + 3 * i, unc,
                  unc && x->func ? x->func + 3 * i : NULL, x->m, a, as);
      for (int c = 0; c < 3; c++) any |= a[c] != 0.0f || as[c] != 0.0f;
      if (x->cam) { /* what the voxel scatters towards the bake's camera per unit σs L̄ */
        const float *l = x->rad + 3 * i;
        double y = 0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2];
        as[3] = y > 0.0 && x->cam[i] > 0.0f ? (float)(x->cam[i] / y) : 0.0f;
      }
    }
  }
  x->any[k] = any;
}

int view_aniso_build(const view_aniso_grids_t *in, view_volume_t *v, bk_error_t *err) {
  aniso_ctx_t x;
  memset(&x, 0, sizeof x);
  x.F = in->flux, x.g = in->phase_g, x.rad = in->radiance;
  x.unc = in->uncollided, x.func = in->flux_uncollided;
  if (!x.F || !x.g) {
    if (x.F) bk_warn("%s: grid \"radiance_flux\" without \"phase_g\": in-scattering is shown "
                     "isotropic", in->path);
    return BK_OK;
  }
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) x.m[r][c] = in->world_to_index[r][c] * in->scale;
  if (in->camera && (v->camera_phase = camera_point(in->path, v->camera_world)))
    x.cam = in->camera;
  /* padded like the medium (field.h), every entry written by aniso_chunk
   * and fld_pad4_faces */
  const size_t padded = fld_padded_count(v->nx, v->ny, v->nz);
  v->aniso = view_alloc_unset(padded, 4 * sizeof(float), "view: anisotropy", err);
  v->aniso_s = view_alloc_unset(padded, 4 * sizeof(float), "view: anisotropy", err);
  if (!v->aniso || !v->aniso_s) return BK_ERR_RUNTIME;
  x.a = v->aniso, x.as = v->aniso_s;
  x.nx = v->nx, x.ny = v->ny;
  for (int k = 0; k < VIEW_CHUNKS; k++) x.bad[k] = SIZE_MAX;
  const size_t slice = (size_t)v->nx * v->ny;
  for (size_t k0 = 0; k0 < (size_t)v->nz; k0 += VIEW_PACK_SLAB) {
    const size_t k1 = view_slab_end(k0, v->nz);
    x.row0 = k0 * (size_t)v->ny;
    bk_parallel_chunks((k1 - k0) * (size_t)v->ny, VIEW_CHUNKS, aniso_chunk, &x);
    size_t bad = SIZE_MAX;
    for (int k = 0; k < VIEW_CHUNKS; k++) bad = x.bad[k] < bad ? x.bad[k] : bad;
    if (bad != SIZE_MAX)
      return bk_fail(err, BK_ERR_INPUT, "%s: grid \"phase_g\" holds %g; expected -1 < g < 1",
                     in->path, (double)x.g[bad]);
    const float *done[] = {x.F, x.g, x.unc, x.func, x.cam};
    const int ch[] = {3, 1, 1, 3, 1};
    for (int i = 0; i < 5; i++) view_release_slices(done[i], ch[i], slice, k0, k1);
  }
  fld_pad4_faces(v->nx, v->ny, v->nz, v->aniso);
  fld_pad4_faces(v->nx, v->ny, v->nz, v->aniso_s);
  for (int k = 0; k < VIEW_CHUNKS; k++) v->anisotropic |= x.any[k];
  v->anisotropic |= v->camera_phase;
  if (!v->anisotropic) {
    free(v->aniso), v->aniso = NULL;
    free(v->aniso_s), v->aniso_s = NULL;
  }
  return BK_OK;
}

