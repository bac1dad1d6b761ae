/* view_volume.c: a VDB file's grids on one dense box (view_volume.h):
 * which grids, each over its own box, their union, every grid moved onto it
 * (copied when aligned, else resampled), checked, and packed for the kernel. */
#define _POSIX_C_SOURCE 200809L
#include "view_volume.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/grid.h"
#include "base/parallel.h"
#include "budget.h"
#include "field.h"
#include "kernels/view_march.h"
#include "vdbio.h"
#include "view_aniso.h"
#include "view_arrays.h"
#include "view_budget.h"
#include "view_camera.h"
#include "view_fields.h"

void view_volume_free(view_volume_t *v) {
  free(v->medium);
  free(v->sigma_t4);
  free(v->aniso);
  free(v->aniso_s);
  vdbio_array_free(v->ior); /* may be the `ior` grid as read */
  free(v->ior_rb);
  free(v->ng);
  oct_free(&v->npyr);
  oct_free(&v->mpyr);
  memset(v, 0, sizeof *v);
}

static int find_name(char **names, int count, const char *name) {
  for (int i = 0; i < count; i++)
    if (!strcmp(names[i], name)) return i;
  return -1;
}
static int is_scalar_type(const char *t) { return !strcmp(t, "float") || !strcmp(t, "double"); }
static int is_vec3_type(const char *t) { return !strcmp(t, "vec3s") || !strcmp(t, "vec3d"); }

static int dense_is_empty(const vdbio_dense_t *d) {
  if (d->nx != 1 || d->ny != 1 || d->nz != 1) return 0;
  for (int c = 0; c < d->channels; c++)
    if (d->data[c] != 0.0f) return 0;
  return 1;
}

/* The linear part of i2w must be s·(rotation or reflection). */
static int check_similarity(const double m[3][4], const char *path, double *scale,
                            bk_error_t *err) {
  double col[3][3], len[3];
  for (int c = 0; c < 3; c++) {
    for (int r = 0; r < 3; r++) col[c][r] = m[r][c];
    len[c] = sqrt(view_dot3d(col[c], col[c]));
  }
  double s = (len[0] + len[1] + len[2]) / 3.0;
  int ok = s > 0.0 && isfinite(s);
  for (int c = 0; c < 3 && ok; c++) {
    if (fabs(len[c] - s) > 1e-5 * s) ok = 0;
    for (int d = c + 1; d < 3; d++)
      if (fabs(view_dot3d(col[c], col[d])) > 1e-5 * s * s) ok = 0;
  }
  if (!ok)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: grid \"radiance\" has a transform with non-uniform scale or shear "
                   "(index axes of world length %g, %g, %g); the viewing pass needs cubic "
                   "voxels (translation, rotation and uniform scale only)",
                   path, len[0], len[1], len[2]);
  *scale = s;
  return BK_OK;
}

/* Moves grid `d` (own box) onto the `like` box: a plain copy when its voxels
 * coincide with like's (same axes and size, integer offset), d's own array
 * when the boxes are the same; *out stays NULL otherwise, and the caller
 * resamples. Cells of like outside d's box are 0, the fog background. */
static int place_aligned(vdbio_dense_t *d, const vdbio_dense_t *like, float **out,
                         bk_error_t *err) {
  double m[3][3], off[3], zero[3] = {0, 0, 0}, w0[3];
  *out = NULL;
  view_affine_apply(d->index_to_world, zero, w0);
  view_affine_apply(like->world_to_index, w0, off);
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) {
      m[r][c] = 0.0;
      for (int k = 0; k < 3; k++) m[r][c] += like->world_to_index[r][k] * d->index_to_world[k][c];
      if (fabs(m[r][c] - (r == c ? 1.0 : 0.0)) > 1e-6) return BK_OK;
    }
  int o[3];
  for (int r = 0; r < 3; r++) {
    if (fabs(off[r] - nearbyint(off[r])) > 1e-4) return BK_OK;
    o[r] = (int)nearbyint(off[r]);
  }
  const int ch = d->channels;
  if (o[0] == 0 && o[1] == 0 && o[2] == 0 && d->nx == like->nx && d->ny == like->ny &&
      d->nz == like->nz) { /* the same box (the usual case): take the array, no copy */
    *out = d->data;
    d->data = NULL;
    return BK_OK;
  }
  size_t count = (size_t)like->nx * like->ny * like->nz;
  float *a = bk_calloc(count, sizeof(float) * (size_t)ch, "view: dense grid", err);
  if (!a) return BK_ERR_RUNTIME;
  for (int k = 0; k < d->nz; k++) {
    int K = k + o[2];
    if (K < 0 || K >= like->nz) continue;
    for (int j = 0; j < d->ny; j++) {
      int J = j + o[1];
      if (J < 0 || J >= like->ny) continue;
      for (int i = 0; i < d->nx; i++) {
        int I = i + o[0];
        if (I < 0 || I >= like->nx) continue;
        size_t src = ((size_t)i + (size_t)d->nx * ((size_t)j + (size_t)d->ny * k)) * ch;
        size_t dst = ((size_t)I + (size_t)like->nx * ((size_t)J + (size_t)like->ny * K)) * ch;
        memcpy(a + dst, d->data + src, sizeof(float) * (size_t)ch);
      }
    }
  }
  *out = a;
  return BK_OK;
}

enum { G_RAD = 0, G_IOR, G_EXT, G_SCA, G_IOR_RGB, G_FLUX, G_PHG, G_UNC, G_FUNC, G_CAM, G_COUNT };

/* One file's grids while they are read and moved onto one box. */
typedef struct view_load {
  const char *path;
  char **names, **types;
  int count;
  const char *gname[G_COUNT];
  int present[G_COUNT], ch[G_COUNT], empty[G_COUNT];
  vdbio_dense_t own[G_COUNT], like;
  float *arr[G_COUNT];
  double scale;
  view_load_hooks_t hooks;
  uint64_t max_bytes; /* --max-memory; 0: what the machine has available */
} view_load_t;

/* Which grids the file has, and of which types. */
static int load_select(view_load_t *L, bk_error_t *err) {
  const char *path = L->path;
  char **names = L->names, **types = L->types;
  int count = L->count;
  int idx[G_COUNT];
  for (int g = 0; g < G_COUNT; g++) idx[g] = find_name(names, count, L->gname[g]);
  if (idx[G_EXT] < 0 && (idx[G_EXT] = find_name(names, count, "density")) >= 0)
    L->gname[G_EXT] = "density";
  if (idx[G_RAD] < 0) {
    char list[1024] = "";
    for (int i = 0; i < count; i++)
      snprintf(list + strlen(list), sizeof list - strlen(list), "%s\"%s\" (%s)", i ? ", " : "",
               names[i], types[i]);
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: no \"radiance\" grid, which `baker view` renders (the Vec3f grid `baker "
                   "bake` writes); the file has %s", path, count ? list : "no grids");
  }
  for (int g = 0; g < G_COUNT; g++) {
    if (idx[g] < 0) continue;
    const char *t = types[idx[g]];
    int ok = g == G_RAD || g == G_IOR_RGB || g == G_FLUX || g == G_FUNC ? is_vec3_type(t)
             : g == G_IOR || g == G_PHG || g == G_UNC || g == G_CAM ? is_scalar_type(t)
                                                        : (is_scalar_type(t) || is_vec3_type(t));
    if (!ok)
      return bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" holds %s values, expected %s", path,
                     L->gname[g], t,
                     g == G_RAD                               ? "Vec3f (vec3s) radiance"
                     : g == G_IOR_RGB                         ? "Vec3f (vec3s) n per channel"
                     : g == G_FLUX || g == G_FUNC             ? "Vec3f (vec3s)"
                     : g == G_IOR || g == G_PHG || g == G_UNC || g == G_CAM ? "float"
                                                              : "float or Vec3f");
    L->present[g] = 1;
  }
  return BK_OK;
}

/* Each grid over its own active box, its checksum checked when the file
 * records one (a corrupt grid is refused, naming it; a file without
 * checksums is warned about once); the radiance transform sets the voxel. */
static int load_read_own(view_load_t *L, bk_error_t *err) {
  int rc, unchecked = 0, count = 0, which[G_COUNT], checked[G_COUNT], grey[G_COUNT];
  const char *names[G_COUNT];
  vdbio_dense_t own[G_COUNT];
  for (int g = 0; g < G_COUNT; g++)
    if (L->present[g]) {
      /* grey light's radiance as one channel, unless the phase lobes read
       * its colour (load_aniso) */
      grey[count] = g == G_RAD && !L->present[G_FLUX] && !L->present[G_CAM];
      which[count] = g, names[count++] = L->gname[g];
    }
  /* the grids side by side, one reader per core */
  if ((rc = vdbio_read_dense_verified_all(L->path, count, names, grey, own, checked,
                                          L->hooks.meanwhile, L->hooks.ctx, err)))
    return rc;
  for (int i = 0; i < count; i++) {
    const int g = which[i];
    L->own[g] = own[i];
    unchecked += !checked[i];
    L->ch[g] = L->own[g].channels;
    L->empty[g] = dense_is_empty(&L->own[g]);
  }
  if (unchecked)
    bk_warn("%s: the file records no checksums for %d of its grids (written by another tool or "
            "an older baker): corruption cannot be detected", L->path, unchecked);
  return check_similarity(L->own[G_RAD].index_to_world, L->path, &L->scale, err);
}

/* The budget's view of the grids' channels (0: absent). */
static view_budget_grids_t budget_grids(const int ch[G_COUNT]) {
  const view_budget_grids_t b = {ch[G_RAD],  ch[G_IOR], ch[G_EXT], ch[G_SCA],  ch[G_IOR_RGB],
                                 ch[G_FLUX], ch[G_PHG], ch[G_UNC], ch[G_FUNC], ch[G_CAM]};
  return b;
}

/* L->like: the union of the non-empty boxes, in radiance index space
 * (v->empty when there is none), checked against the machine's memory. */
static int load_box(view_load_t *L, view_volume_t *v, bk_error_t *err) {
  const vdbio_dense_t *rad = &L->own[G_RAD];
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  int any = 0;
  for (int g = 0; g < G_COUNT; g++) {
    if (!L->present[g] || L->empty[g]) continue;
    any = 1;
    const vdbio_dense_t *d = &L->own[g];
    for (int c = 0; c < 8; c++) {
      double p[3] = {(c & 1) ? d->nx - 0.5 : -0.5, (c & 2) ? d->ny - 0.5 : -0.5,
                     (c & 4) ? d->nz - 0.5 : -0.5};
      double w[3], u[3];
      view_affine_apply(d->index_to_world, p, w);
      view_affine_apply(rad->world_to_index, w, u);
      for (int k = 0; k < 3; k++) {
        lo[k] = fmin(lo[k], u[k]);
        hi[k] = fmax(hi[k], u[k]);
      }
    }
  }
  vdbio_dense_t *like = &L->like;
  *like = *rad;
  like->data = NULL;
  if (!any) {
    v->empty = 1;
    like->nx = like->ny = like->nz = 1;
  } else {
    int ilo[3], n[3];
    for (int k = 0; k < 3; k++) {
      ilo[k] = (int)floor(lo[k] + 0.5 + 1e-6);
      int ihi = (int)ceil(hi[k] - 0.5 - 1e-6);
      n[k] = ihi - ilo[k] + 1;
      if (n[k] < 1 || n[k] > GRID_MAX_AXIS)
        return bk_fail(err, BK_ERR_INPUT,
                       "%s: the grids span %d voxels along axis %d (at most %d)", L->path, n[k],
                       k, GRID_MAX_AXIS);
    }
    double shift[3] = {ilo[0], ilo[1], ilo[2]}, t[3];
    for (int r = 0; r < 3; r++) {
      t[r] = 0.0;
      for (int c = 0; c < 3; c++) t[r] += rad->index_to_world[r][c] * shift[c];
      like->index_to_world[r][3] += t[r];
      like->world_to_index[r][3] -= shift[r];
    }
    like->nx = n[0];
    like->ny = n[1];
    like->nz = n[2];
  }
  /* the estimate again with the channels as read (grey radiance: one), the
   * grids read counting in what this process may use */
  int ch[G_COUNT];
  double held = 0.0;
  for (int g = 0; g < G_COUNT; g++) {
    ch[g] = L->present[g] ? L->ch[g] : 0;
    held += 4.0 * ch[g] * (double)L->own[g].nx * (double)L->own[g].ny * L->own[g].nz;
  }
  const view_budget_grids_t bg = budget_grids(ch);
  const int n[3] = {like->nx, like->ny, like->nz};
  return view_budget_check(L->path, n, &bg, held, L->max_bytes, err);
}

/* Before any grid is read: the estimate over the box a baker file records
 * (checksum_box, which holds every active voxel), each grid's channels
 * from its type, radiance's three (its grey read is not known yet). Files
 * of other tools record no box; their check comes after the read. A large
 * box is checked against the device's largest buffer first. */
static int load_budget(const view_load_t *L, bk_error_t *err) {
  char text[96];
  int n[3];
  bk_error_t e = {0, ""};
  if (vdbio_read_meta(L->path, "checksum_box", text, sizeof text, &e) != BK_OK ||
      sscanf(text, "%d %d %d", &n[0], &n[1], &n[2]) != 3 || n[0] < 1 || n[1] < 1 || n[2] < 1)
    return BK_OK;
  if (L->hooks.max_buffer && view_budget_least_buffer(n) > BUDGET_DEVICE_CHECK_BYTES) {
    const char *device = "";
    const uint64_t max_alloc = L->hooks.max_buffer(L->hooks.ctx, &device);
    int rc = view_budget_device_check(L->path, n, max_alloc, device, err);
    if (rc) return rc;
  }
  int ch[G_COUNT];
  for (int g = 0; g < G_COUNT; g++) {
    const int i = L->present[g] ? find_name(L->names, L->count, L->gname[g]) : -1;
    ch[g] = i < 0 ? 0 : is_vec3_type(L->types[i]) ? 3 : 1;
  }
  const view_budget_grids_t bg = budget_grids(ch);
  return view_budget_check(L->path, n, &bg, 0.0, L->max_bytes, err);
}

/* Every grid onto the like box: copied when aligned, else resampled. */
static int load_place(view_load_t *L, const view_volume_t *v, bk_error_t *err) {
  int rc;
  for (int g = 0; g < G_COUNT; g++) {
    if (!L->present[g] || v->empty) continue;
    if ((rc = place_aligned(&L->own[g], &L->like, &L->arr[g], err))) return rc;
    if (!L->arr[g]) {
      vdbio_dense_t r;
      int found = 0;
      if ((rc = vdbio_read_dense_like(L->path, L->gname[g], &L->like, &r, &found, err)))
        return rc;
      if (!found)
        return bk_fail(err, BK_ERR_RUNTIME, "%s: grid \"%s\" vanished while reading", L->path,
                       L->gname[g]);
      L->arr[g] = r.data;
    }
    vdbio_dense_free(&L->own[g]);
  }
  return BK_OK;
}

static void load_describe(const view_load_t *L, view_volume_t *v) {
  v->nx = L->like.nx;
  v->ny = L->like.ny;
  v->nz = L->like.nz;
  memcpy(v->i2w, L->like.index_to_world, sizeof v->i2w);
  memcpy(v->w2i, L->like.world_to_index, sizeof v->w2i);
  v->voxel_size = L->scale;
  snprintf(v->desc, sizeof v->desc, "%dx%dx%d voxels of %g; radiance", v->nx, v->ny, v->nz,
           L->scale);
  for (int g = 1; g < G_COUNT; g++)
    if (L->present[g])
      snprintf(v->desc + strlen(v->desc), sizeof v->desc - strlen(v->desc), ", %s (%s)",
               L->gname[g], L->ch[g] == 1 ? "float" : "Vec3f");
}

/* n below 1 raised to 1, and n's range, in chunks (min and max: exact in
 * any order; an empty chunk leaves its slot out of range). */
typedef struct ior_ctx {
  float *n;
  float lo[VIEW_CHUNKS], hi[VIEW_CHUNKS];
} ior_ctx_t;

static void ior_chunk(void *arg, size_t k, size_t a, size_t b) {
  ior_ctx_t *x = arg;
  float lo = 1e30f, hi = -1e30f;
  for (size_t i = a; i < b; i++) {
    const float n = x->n[i] < 1.0f ? 1.0f : x->n[i];
    x->n[i] = n;
    lo = n < lo ? n : lo;
    hi = n > hi ? n : hi;
  }
  x->lo[k] = lo, x->hi[k] = hi;
}

/* n: values below 1 are background (0) or nonsense; n >= 1 by contract. */
static int load_ior(view_load_t *L, view_volume_t *v, size_t nvox, bk_error_t *err) {
  if (!L->arr[G_IOR]) {
    v->n_min = v->n_max = 1.0f;
    return BK_OK;
  }
  v->ior = L->arr[G_IOR];
  L->arr[G_IOR] = NULL;
  ior_ctx_t x;
  x.n = v->ior;
  bk_parallel_chunks(nvox, VIEW_CHUNKS, ior_chunk, &x);
  v->n_min = 1e30f;
  v->n_max = -1e30f;
  for (int k = 0; k < VIEW_CHUNKS; k++) {
    v->n_min = x.lo[k] < v->n_min ? x.lo[k] : v->n_min;
    v->n_max = x.hi[k] > v->n_max ? x.hi[k] : v->n_max;
  }
  v->refraction = v->n_max - v->n_min > VIEW_N_EPS;
  return BK_OK;
}

/* Dispersion: n per channel from `ior_rgb` (below 1 raised to 1, as n), G
 * replacing `ior`; a grid whose channels agree everywhere changes nothing. */
static int load_ior_rgb(view_load_t *L, view_volume_t *v, size_t nvox, bk_error_t *err) {
  const float *rgb = L->arr[G_IOR_RGB];
  size_t i = 0;
  while (rgb && i < nvox && rgb[3 * i] == rgb[3 * i + 1] && rgb[3 * i + 2] == rgb[3 * i + 1]) i++;
  if (!rgb || i == nvox) return BK_OK;
  if ((!v->ior && !(v->ior = view_alloc(nvox, sizeof(float), "view: ior", err))) ||
      !(v->ior_rb = view_alloc(nvox, 2 * sizeof(float), "view: ior per channel", err)))
    return BK_ERR_RUNTIME;
  for (i = 0; i < nvox; i++)
    for (int c = 0; c < 3; c++) {
      float n = rgb[3 * i + c] < 1.0f ? 1.0f : rgb[3 * i + c];
      *(c == 1 ? v->ior + i : v->ior_rb + (c / 2) * nvox + i) = n;
      v->n_min = n < v->n_min ? n : v->n_min;
      v->n_max = n > v->n_max ? n : v->n_max;
    }
  v->refraction = 1;
  return BK_OK;
}

/* The phase lobes (view_aniso.h) from the grids as read. */
static int load_aniso(view_load_t *L, view_volume_t *v, bk_error_t *err) {
  view_aniso_grids_t g = {L->path, L->arr[G_FLUX], L->arr[G_PHG], L->arr[G_RAD], L->arr[G_UNC],
                          L->arr[G_FUNC], L->arr[G_CAM], L->scale, {{0}}};
  memcpy(g.world_to_index, L->like.world_to_index, sizeof g.world_to_index);
  return view_aniso_build(&g, v, err);
}

/* Coefficients: σs absent -> σt; σt absent -> σs; both absent -> 0. */
static int load_coefficients(view_load_t *L, view_volume_t *v, size_t nvox, bk_error_t *err) {
  float **arr = L->arr;
  int *ch = L->ch, rc;
  if (!arr[G_EXT] && arr[G_SCA]) {
    arr[G_EXT] = arr[G_SCA];
    ch[G_EXT] = ch[G_SCA];
    arr[G_SCA] = NULL;
  }
  if (!arr[G_EXT])
    bk_warn("%s: no extinction, density or scattering grid: the medium is transparent and the "
            "image shows only the background", L->path);
  if (arr[G_EXT] && arr[G_SCA] && ch[G_SCA] != ch[G_EXT]) {
    int g = ch[G_SCA] == 1 ? G_SCA : G_EXT;
    if ((rc = view_expand_to_rgb(&arr[g], nvox, err))) return rc;
    ch[g] = 3;
  }
  v->sigma_ch = arr[G_EXT] ? ch[G_EXT] : 1;
  return BK_OK;
}

typedef struct pack_ctx {
  const float *ext, *sca, *rad;
  int sc, radc; /* channels of ext and sca, of rad */
  float scale;
  int nx, ny;
  int mf;                   /* floats per voxel of medium: 4, or 2 under grey light */
  float *medium, *sigma_t4; /* padded (field.h): the kernel's layout */
  size_t row0;              /* pack_source: the first row of its range */
} pack_ctx_t;

/* {S = σs L̄ (RGB, or one channel under grey light), σt (grey; 0 for RGB,
 * whose σt goes to sigma_t4)} of the rows row0 + [lo, hi) (row j + ny k),
 * written straight into the padded layout. */
static void pack_source(void *arg, size_t lo, size_t hi) {
  const pack_ctx_t *x = arg;
  const int sc = x->sc, radc = x->radc, mf = x->mf, sn = mf == 2 ? 1 : 3;
  for (size_t row = x->row0 + lo; row < x->row0 + hi; row++) {
    float *m = x->medium + (size_t)mf * view_padded_row(x->nx, x->ny, row);
    for (size_t i = row * (size_t)x->nx; i < (row + 1) * (size_t)x->nx; i++, m += mf) {
      for (int c = 0; c < sn; c++)
        m[c] = x->sca ? x->scale * x->sca[i * sc + (sc == 3 ? c : 0)] *
                            x->rad[i * radc + (radc == 3 ? c : 0)]
                      : 0.0f;
      m[mf - 1] = sc == 1 && x->ext ? x->scale * x->ext[i] : 0.0f; /* the array is not zeroed */
    }
  }
}

static void pack_sigma_t(void *arg, size_t lo, size_t hi) {
  const pack_ctx_t *x = arg;
  for (size_t row = x->row0 + lo; row < x->row0 + hi; row++) {
    float *s = x->sigma_t4 + 4 * view_padded_row(x->nx, x->ny, row);
    for (size_t i = row * (size_t)x->nx; i < (row + 1) * (size_t)x->nx; i++, s += 4) {
      for (int c = 0; c < 3; c++) s[c] = x->scale * x->ext[3 * i + c];
      s[3] = 0.0f; /* the array is not zeroed */
    }
  }
}

/* Packs {S = σs L̄, σt (grey)} and, for RGB, {σt}; σ per voxel length. */
static int load_medium(view_load_t *L, view_volume_t *v, size_t nvox, bk_error_t *err) {
  int rc = load_coefficients(L, v, nvox, err);
  if (rc) return rc;
  const float *ext = L->arr[G_EXT], *sca = L->arr[G_SCA] ? L->arr[G_SCA] : L->arr[G_EXT];
  const float *rad = L->arr[G_RAD];
  const int sc = v->sigma_ch, radc = L->ch[G_RAD];
  const double scale = L->scale;
  const size_t padded = fld_padded_count(v->nx, v->ny, v->nz);
  const size_t grain = BK_GRAIN / (size_t)v->nx + 1;
  /* grey σ under grey light: {S, σt}, half the bytes (view_march.h) */
  v->medium_floats = sc == 1 && radc == 1 ? 2 : 4;
  /* every entry written by pack_source and fld_pad_faces: no zeroing */
  v->medium = view_alloc_unset(padded, (size_t)v->medium_floats * sizeof(float), "view: medium",
                               err);
  if (!v->medium) return BK_ERR_RUNTIME;
  pack_ctx_t x = {ext,   sca,   rad,   sc, radc, (float)scale, v->nx, v->ny, v->medium_floats,
                  v->medium, NULL, 0};
  /* VIEW_PACK_SLAB z slices at a time, each slab's radiance, σs and grey
   * σt (read nowhere else) given back once packed: the medium's pages come
   * as the inputs' go (docs/memory.md, "baker view's memory") */
  const size_t slice = (size_t)v->nx * v->ny;
  for (size_t k0 = 0; k0 < (size_t)v->nz; k0 += VIEW_PACK_SLAB) {
    const size_t k1 = view_slab_end(k0, v->nz);
    x.row0 = k0 * (size_t)v->ny;
    bk_parallel((k1 - k0) * (size_t)v->ny, grain, pack_source, &x);
    view_release_slices(rad, radc, slice, k0, k1);
    if (L->arr[G_SCA]) /* σs's own grid, not σt standing in for it */
      view_release_slices(sca, sc, slice, k0, k1);
    if (sc == 1) /* grey σt lives on in the medium's 4th float; RGB's is packed below */
      view_release_slices(ext, 1, slice, k0, k1);
  }
  fld_pad_faces(v->nx, v->ny, v->nz, v->medium_floats, v->medium);
  if (sc == 1) return BK_OK;
  v->homogeneous = view_is_constant(ext, nvox, 3, v->st_const);
  for (int c = 0; c < 3; c++) v->st_const[c] *= (float)scale;
  if (v->homogeneous) return BK_OK;
  /* every entry written by pack_sigma_t and fld_pad4_faces; RGB σt given
   * back a slab at a time as its pages come */
  v->sigma_t4 = view_alloc_unset(padded, 4 * sizeof(float), "view: extinction", err);
  if (!v->sigma_t4) return BK_ERR_RUNTIME;
  x.sigma_t4 = v->sigma_t4;
  for (size_t k0 = 0; k0 < (size_t)v->nz; k0 += VIEW_PACK_SLAB) {
    const size_t k1 = view_slab_end(k0, v->nz);
    x.row0 = k0 * (size_t)v->ny;
    bk_parallel((k1 - k0) * (size_t)v->ny, grain, pack_sigma_t, &x);
    view_release_slices(ext, 3, slice, k0, k1);
  }
  fld_pad4_faces(v->nx, v->ny, v->nz, v->sigma_t4);
  return BK_OK;
}

/* The grids as read that nothing reads any more (a list ending in -1),
 * given back. */
static void load_free(view_load_t *L, const int *grids) {
  for (; *grids >= 0; grids++) vdbio_array_free(L->arr[*grids]), L->arr[*grids] = NULL;
}

int view_volume_load(const char *path, view_volume_t *v, uint64_t max_bytes,
                     const view_load_hooks_t *hooks, bk_error_t *err) {
  view_load_t L;
  memset(&L, 0, sizeof L);
  memset(v, 0, sizeof *v);
  L.path = path;
  if (hooks) L.hooks = *hooks;
  L.max_bytes = max_bytes;
  L.scale = 1.0;
  const char *gname[G_COUNT] = {"radiance",      "ior",     "extinction",         "scattering",
                                "ior_rgb",       "radiance_flux", "phase_g",
                                "radiance_uncollided", "radiance_flux_uncollided",
                                "radiance_camera"};
  memcpy(L.gname, gname, sizeof gname);

  double t0 = bk_now_ms(), t1, t2;
  int rc = vdbio_list_grids(path, &L.names, &L.types, &L.count, err);
  if (rc) return rc;
  t1 = bk_now_ms();
  if ((rc = load_select(&L, err)) || (rc = load_budget(&L, err)) || (rc = load_read_own(&L, err)) ||
      (rc = load_box(&L, v, err)) || (rc = load_place(&L, v, err)))
    goto error;
  t2 = bk_now_ms();
  load_describe(&L, v);
  if (v->empty) goto done;

  size_t nvox = (size_t)v->nx * v->ny * v->nz;
  for (int g = 0; g < G_COUNT; g++)
    if (L.arr[g] && (rc = view_check_values(path, L.gname[g], L.arr[g], nvox * (size_t)L.ch[g],
                                       g == G_EXT || g == G_SCA, err)))
      goto error;
  /* each grid freed once the arrays made from it are (peak memory) */
  static const int after_ior_rgb[] = {G_IOR_RGB, -1},
                   after_aniso[] = {G_FLUX, G_PHG, G_UNC, G_FUNC, G_CAM, -1};
  if ((rc = load_ior(&L, v, nvox, err)) || (rc = load_ior_rgb(&L, v, nvox, err))) goto error;
  load_free(&L, after_ior_rgb);
  if ((rc = load_aniso(&L, v, err))) goto error;
  load_free(&L, after_aniso);
  if ((rc = load_medium(&L, v, nvox, err))) goto error;
  /* the grids as read are packed now: free them before padding (peak memory) */
  for (int g = 0; g < G_COUNT; g++) vdbio_array_free(L.arr[g]), L.arr[g] = NULL;
  double t3 = bk_now_ms();
  if ((rc = view_fields_build(v, err))) goto error;
  /* where the read stage goes (bench_view's profile) */
  bk_log(2, "view: read %s: list %.0f ms, grids %.0f ms, check and pack %.0f ms, fields and "
            "pyramids %.0f ms", path, t1 - t0, t2 - t1, t3 - t2, bk_now_ms() - t3);

done:
  rc = BK_OK;
error:
  for (int g = 0; g < G_COUNT; g++) {
    vdbio_dense_free(&L.own[g]);
    vdbio_array_free(L.arr[g]);
  }
  vdbio_free_names(L.names, L.types, L.count);
  if (rc) view_volume_free(v);
  return rc;
}

/* World bounding box of the volume's cells. */
void view_volume_world_box(const view_volume_t *v, double bmin[3], double bmax[3]) {
  for (int k = 0; k < 3; k++) bmin[k] = 1e300, bmax[k] = -1e300;
  for (int c = 0; c < 8; c++) {
    double p[3] = {(c & 1) ? v->nx - 0.5 : -0.5, (c & 2) ? v->ny - 0.5 : -0.5,
                   (c & 4) ? v->nz - 0.5 : -0.5};
    double w[3];
    view_affine_apply(v->i2w, p, w);
    for (int k = 0; k < 3; k++) bmin[k] = fmin(bmin[k], w[k]), bmax[k] = fmax(bmax[k], w[k]);
  }
}
