/* photons.c: lights -> ph_light (see photons.h). */
#include "photons.h"

#include <math.h>
#include <string.h>

/* Orthonormal u, w perpendicular to unit d (Duff et al. 2017, branchless). */
static void basis(const double d[3], double u[3], double w[3]) {
  double s = d[2] >= 0.0 ? 1.0 : -1.0;
  double a = -1.0 / (s + d[2]), b = d[0] * d[1] * a;
  u[0] = 1.0 + s * d[0] * d[0] * a;
  u[1] = s * b;
  u[2] = -s * d[0];
  w[0] = b;
  w[1] = s + d[1] * d[1] * a;
  w[2] = -d[1];
}

static void unit_direction(const float in[3], double d[3]) {
  double l = sqrt((double)in[0] * in[0] + (double)in[1] * in[1] + (double)in[2] * in[2]);
  for (int a = 0; a < 3; a++) d[a] = l > 0.0 ? in[a] / l : (a == 2 ? 1.0 : 0.0);
}

/* The directional light's rectangle in voxel coordinates: perpendicular to
 * d, covering the projection of the grid's box, one voxel before it.
 * Returns its area in m^2. */
static double directional_rect(const scene_light_t *l, const grid_dims_t *g, double corner[3],
                               double U[3], double V[3]) {
  double d[3], u[3], w[3];
  unit_direction(l->direction, d);
  basis(d, u, w);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int c = 0; c < 8; c++) {
    double p[3] = {(c & 1) ? g->nx : 0, (c & 2) ? g->ny : 0, (c & 4) ? g->nz : 0};
    double q[3] = {p[0] * u[0] + p[1] * u[1] + p[2] * u[2], p[0] * w[0] + p[1] * w[1] + p[2] * w[2],
                   p[0] * d[0] + p[1] * d[1] + p[2] * d[2]};
    for (int a = 0; a < 3; a++) {
      lo[a] = q[a] < lo[a] ? q[a] : lo[a];
      hi[a] = q[a] > hi[a] ? q[a] : hi[a];
    }
  }
  for (int a = 0; a < 3; a++) {
    corner[a] = lo[0] * u[a] + lo[1] * w[a] + (lo[2] - 1.0) * d[a];
    U[a] = (hi[0] - lo[0]) * u[a];
    V[a] = (hi[1] - lo[1]) * w[a];
  }
  double h = g->voxel_size;
  return (hi[0] - lo[0]) * (hi[1] - lo[1]) * h * h;
}

double ph_light_power(const scene_light_t *l, const grid_dims_t *d, double rgb[3]) {
  double k;
  const float *c;
  switch (l->type) {
  case LIGHT_DIRECTIONAL: {
    double corner[3], U[3], V[3];
    k = directional_rect(l, d, corner, U, V);
    c = l->irradiance;
    break;
  }
  case LIGHT_SPOT:
    k = 2.0 * M_PI * (1.0 - cos((double)l->angle_deg * M_PI / 180.0));
    c = l->intensity;
    break;
  default:
    k = 4.0 * M_PI;
    c = l->intensity;
    break;
  }
  for (int a = 0; a < 3; a++) rgb[a] = k * (double)c[a];
  return rgb[0] + rgb[1] + rgb[2];
}

void ph_share(const double *weights, int n, uint64_t total, uint64_t *counts) {
  double sum = 0.0;
  for (int i = 0; i < n; i++) sum += weights[i] > 0.0 ? weights[i] : 0.0;
  uint64_t given = 0;
  for (int i = 0; i < n; i++) {
    double w = weights[i] > 0.0 ? weights[i] : 0.0;
    counts[i] = sum > 0.0 ? (uint64_t)floor((double)total * (w / sum)) : 0;
    if (counts[i] > total) counts[i] = total;
    given += counts[i];
  }
  if (sum <= 0.0) return;
  /* hand out the rest one by one to the largest remainders */
  while (given < total) {
    int best = -1;
    double best_r = -1.0;
    for (int i = 0; i < n; i++) {
      if (!(weights[i] > 0.0)) continue;
      double r = (double)total * (weights[i] / sum) - (double)counts[i];
      if (r > best_r) {
        best_r = r;
        best = i;
      }
    }
    counts[best]++;
    given++;
  }
}

/* 32-bit integer hash (Wellons' lowbias32). */
static uint32_t mix32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

int ph_prepare(const scene_t *scene, const grid_dims_t *g, uint64_t photons, unsigned seed,
               ph_setup_t *out, bk_error_t *err) {
  double weights[SCENE_MAX_LIGHTS] = {0}, rgb[SCENE_MAX_LIGHTS][3] = {{0}};
  uint64_t counts[SCENE_MAX_LIGHTS];
  memset(out, 0, sizeof *out);
  if (photons > PH_MAX_PHOTONS)
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: photons.count: expected at most %llu photons (the march indexes "
                   "photons with 32 bits), got %llu",
                   scene->path, (unsigned long long)PH_MAX_PHOTONS, (unsigned long long)photons);
  if (scene->light_count < 0 || scene->light_count > SCENE_MAX_LIGHTS)
    return bk_fail(err, BK_ERR_INPUT, "%s: lights: expected at most %d lights, got %d", scene->path,
                   SCENE_MAX_LIGHTS, scene->light_count);
  const double h = g->voxel_size;
  for (int l = 0; l < scene->light_count; l++)
    weights[l] = ph_light_power(&scene->lights[l], g, rgb[l]);
  ph_share(weights, scene->light_count, photons, counts);

  uint64_t first = 0;
  for (int l = 0; l < scene->light_count; l++) {
    if (counts[l] == 0) continue;
    const scene_light_t *sl = &scene->lights[l];
    ph_light *L = &out->lights[out->count];
    memset(L, 0, sizeof *L);
    double d[3], u[3], w[3], p[3];
    unit_direction(sl->direction, d);
    L->type = (int)sl->type;
    if (sl->type == LIGHT_DIRECTIONAL) {
      directional_rect(sl, g, p, u, w);
      L->cos_max = 1.0f;
    } else {
      basis(d, u, w);
      for (int a = 0; a < 3; a++) p[a] = ((double)sl->position[a] - g->origin[a]) / h;
      L->cos_max = sl->type == LIGHT_SPOT ? (float)cos((double)sl->angle_deg * M_PI / 180.0) : -1.0f;
    }
    L->px = (float)p[0], L->py = (float)p[1], L->pz = (float)p[2];
    L->dx = (float)d[0], L->dy = (float)d[1], L->dz = (float)d[2];
    L->ux = (float)u[0], L->uy = (float)u[1], L->uz = (float)u[2];
    L->vx = (float)w[0], L->vy = (float)w[1], L->vz = (float)w[2];
    uint32_t hsh = mix32((uint32_t)seed * 0x9e3779b9u ^ mix32((uint32_t)l + 0x632be5abu));
    L->rot_u = (float)(hsh >> 8) * (1.0f / 16777216.0f);
    L->rot_v = (float)(mix32(hsh) >> 8) * (1.0f / 16777216.0f);
    for (int a = 0; a < 3; a++) {
      L->power[a] = (float)(rgb[l][a] / (double)counts[l]);
      out->power[a] += rgb[l][a];
    }
    L->first = (bk_uint)first;
    L->count = (bk_uint)counts[l];
    first += counts[l];
    out->scene_index[out->count] = l;
    out->has_type[sl->type] = 1;
    out->count++;
  }
  out->photons = first;

  /* one colour: every light's RGB proportional to the first one's */
  out->one_colour = 1;
  for (int i = 0; i < out->count; i++) {
    int l = out->scene_index[i];
    double s = rgb[l][0] + rgb[l][1] + rgb[l][2];
    for (int a = 0; a < 3; a++) {
      double c = rgb[l][a] / s;
      if (i == 0) out->chroma[a] = c;
      else if (fabs(c - out->chroma[a]) > 1e-6) out->one_colour = 0;
    }
  }
  if (out->count == 0)
    for (int a = 0; a < 3; a++) out->chroma[a] = 1.0 / 3.0;
  return BK_OK;
}

void ph_make_grey(ph_setup_t *s) {
  for (int i = 0; i < s->count; i++) {
    ph_light *L = &s->lights[i];
    L->power[0] = L->power[0] + L->power[1] + L->power[2];
    L->power[1] = L->power[2] = 0.0f;
  }
}
