/* test_march_util.h: volumes, scenes and runs for the march tests. */
#ifndef TEST_MARCH_UTIL_H
#define TEST_MARCH_UTIL_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "march.h"
#include "test_util.h"

/* A volume of nx*ny*nz cubes of side h with its corner at origin, filled
 * with n and the given coefficients (per metre). Like the voxelizer's, its
 * sigma_t holds σa while objects are composited, until tv_summarise. */
static inline void tv_alloc(volume_t *v, int nx, int ny, int nz, float h, float ox, float oy,
                            float oz) {
  memset(v, 0, sizeof *v);
  v->dims.nx = nx, v->dims.ny = ny, v->dims.nz = nz;
  v->dims.voxel_size = h;
  v->dims.origin[0] = ox, v->dims.origin[1] = oy, v->dims.origin[2] = oz;
  size_t n = grid_count(&v->dims);
  v->ior = calloc(n, sizeof(float));
  v->sigma_s = malloc(3 * n * sizeof(float));
  v->sigma_t = malloc(3 * n * sizeof(float));
  REQUIRE(v->ior && v->sigma_s && v->sigma_t, "out of memory for a %dx%dx%d volume", nx, ny, nz);
}

static inline void tv_fill(volume_t *v, float n, const float ss[3], const float sa[3]) {
  size_t count = grid_count(&v->dims);
  for (size_t i = 0; i < count; i++) {
    v->ior[i] = n;
    for (int c = 0; c < 3; c++) {
      v->sigma_s[3 * i + c] = ss[c];
      v->sigma_t[3 * i + c] = sa[c];
    }
  }
}

/* Makes sigma_t σs + σa and the volume's summary flags, the way the
 * voxelizer does. */
static inline void tv_summarise(volume_t *v) {
  size_t count = grid_count(&v->dims);
  for (size_t i = 0; i < 3 * count; i++) v->sigma_t[i] += v->sigma_s[i];
  v->n_min = v->n_max = v->ior[0];
  v->homogeneous = v->grey = 1;
  for (size_t i = 0; i < count; i++) {
    v->n_min = fminf(v->n_min, v->ior[i]);
    v->n_max = fmaxf(v->n_max, v->ior[i]);
    for (int c = 0; c < 3; c++)
      if (v->sigma_s[3 * i + c] != v->sigma_s[c] || v->sigma_t[3 * i + c] != v->sigma_t[c])
        v->homogeneous = 0;
    if (v->sigma_s[3 * i] != v->sigma_s[3 * i + 1] || v->sigma_s[3 * i] != v->sigma_s[3 * i + 2] ||
        v->sigma_t[3 * i] != v->sigma_t[3 * i + 1] || v->sigma_t[3 * i] != v->sigma_t[3 * i + 2])
      v->grey = 0;
  }
  v->has_refraction = v->n_max > v->n_min;
}

static inline void tv_free(volume_t *v) {
  free(v->ior);
  free(v->ior_rb);
  free(v->sigma_s);
  free(v->sigma_t);
  free(v->sigma_code);
}

/* The voxelizer's smoothing profile (baker/voxelize.c): weight of the object
 * at signed distance d (voxels, negative inside) for smoothing s voxels. */
static inline float tv_weight(float d, float s) {
  float t = (d + 0.5f * s) / s;
  if (t <= 0.0f) return 1.0f;
  if (t >= 1.0f) return 0.0f;
  return 1.0f - t * t * (3.0f - 2.0f * t);
}

/* A ball of index n_obj, centre c (world) and radius r (world), smoothed over
 * s voxels, composited over the volume like the voxelizer does. Optional
 * object coefficients (NULL: keep the medium's). */
static inline void tv_ball(volume_t *v, const float c[3], float r, float n_obj, float s,
                           const float *ss, const float *sa) {
  const grid_dims_t *d = &v->dims;
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        float p[3];
        grid_voxel_center(d, i, j, k, p);
        float dx = p[0] - c[0], dy = p[1] - c[1], dz = p[2] - c[2];
        float dist = (sqrtf(dx * dx + dy * dy + dz * dz) - r) / d->voxel_size;
        float w = tv_weight(dist, s);
        if (w <= 0.0f) continue;
        size_t idx = grid_index(d, i, j, k);
        v->ior[idx] += w * (n_obj - v->ior[idx]);
        for (int ch = 0; ch < 3; ch++) {
          if (ss) v->sigma_s[3 * idx + ch] += w * (ss[ch] - v->sigma_s[3 * idx + ch]);
          if (sa) v->sigma_t[3 * idx + ch] += w * (sa[ch] - v->sigma_t[3 * idx + ch]);
        }
      }
}

static inline void ts_init(scene_t *s, scene_light_t *lights, int nlights, long long photons) {
  scene_defaults(s); /* seed 1, step 0.5, Euler, as a scene file without them */
  snprintf(s->path, sizeof s->path, "test-scene.json");
  s->bounces = 0; /* the analytic truths here are single scattering */
  s->lights = lights;
  s->light_count = nlights;
  s->photon_count = photons;
}

static inline scene_light_t tl_directional(float dx, float dy, float dz, float e) {
  scene_light_t l;
  memset(&l, 0, sizeof l);
  l.type = LIGHT_DIRECTIONAL;
  float n = sqrtf(dx * dx + dy * dy + dz * dz);
  l.direction[0] = dx / n, l.direction[1] = dy / n, l.direction[2] = dz / n;
  l.irradiance[0] = l.irradiance[1] = l.irradiance[2] = e;
  return l;
}

static inline scene_light_t tl_point(float x, float y, float z, float r, float g, float b) {
  scene_light_t l;
  memset(&l, 0, sizeof l);
  l.type = LIGHT_POINT;
  l.position[0] = x, l.position[1] = y, l.position[2] = z;
  l.intensity[0] = r, l.intensity[1] = g, l.intensity[2] = b;
  return l;
}

static inline scene_light_t tl_spot(float x, float y, float z, float dx, float dy, float dz,
                                    float angle, float r, float g, float b) {
  scene_light_t l = tl_point(x, y, z, r, g, b);
  l.type = LIGHT_SPOT;
  float n = sqrtf(dx * dx + dy * dy + dz * dz);
  l.direction[0] = dx / n, l.direction[1] = dy / n, l.direction[2] = dz / n;
  l.angle_deg = angle;
  return l;
}

/* "host" or "cl" from the command line; the OpenCL context is made once. */
static clh_context_t tm_cl_ctx;
static int tm_cl_ready;
static inline clh_context_t *tm_path(const char *name) {
  if (!name || strcmp(name, "host") == 0) return NULL;
  REQUIRE(strcmp(name, "cl") == 0, "path must be host or cl, got %s", name);
  if (!tm_cl_ready) {
    bk_error_t err;
    memset(&err, 0, sizeof err);
    REQUIRE(clh_init(&tm_cl_ctx, NULL, &err) == BK_OK, "clh_init: %s", err.msg);
    tm_cl_ready = 1;
  }
  return &tm_cl_ctx;
}

/* Bakes and returns the radiance grid (3 floats per voxel, caller frees). */
static inline float *tm_bake(clh_context_t *cl, const scene_t *s, const volume_t *v,
                             pm_stats_t *stats) {
  bk_error_t err;
  memset(&err, 0, sizeof err);
  float *rad = calloc(3 * grid_count(&v->dims), sizeof(float));
  REQUIRE(rad, "out of memory");
  int rc = pm_bake(cl, s, v, rad, stats, NULL, &err);
  REQUIRE(rc == BK_OK, "pm_bake: %s", err.msg);
  REQUIRE(stats->photons == stats->missed_grid + stats->left_grid + stats->absorbed + stats->step_limit,
        "photon fates do not add up");
  return rad;
}

static inline void tm_print_stats(const char *what, const pm_stats_t *st) {
  printf("%s: %llu photons: %llu missed, %llu left, %llu absorbed, %llu step limit; %llu steps, "
         "%llu voxel crossings, march %.1f ms\n",
         what, (unsigned long long)st->photons, (unsigned long long)st->missed_grid,
         (unsigned long long)st->left_grid, (unsigned long long)st->absorbed,
         (unsigned long long)st->step_limit, (unsigned long long)st->steps,
         (unsigned long long)st->voxels, st->ms_march);
}

#endif
