/* photons.c: lights -> ph_light (see photons.h). */
#include "photons.h"

#include <math.h>
#include <string.h>

double ph_light_power(const scene_light_t *l, const grid_dims_t *d, double rgb[3]) {
  const light_kind_t *k = light_kind(l->type);
  if (!k) return rgb[0] = rgb[1] = rgb[2] = 0.0; /* not a light: no photons */
  return k->power(l, d, rgb);
}

int ph_kernel_defines(const ph_setup_t *s, char *buf, size_t n) {
  size_t used = 0;
  if (n) buf[0] = 0;
  for (int i = 0; i < LIGHT_KIND_COUNT; i++) {
    int w = snprintf(buf + used, n - used, "%s-D%s=%d", i ? " " : "", light_kinds[i].define,
                     s->has_type[i]);
    if (w < 0 || (size_t)w >= n - used) return BK_ERR_RUNTIME;
    used += (size_t)w;
  }
  return BK_OK;
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

uint64_t ph_batch_photons(uint64_t photons, int batches, int batch) {
  uint64_t b = batches > 0 ? (uint64_t)batches : 1;
  return photons / b + ((uint64_t)batch % b < photons % b ? 1 : 0);
}

/* The Cranley–Patterson rotation of light l in batch b: batch 0 keeps the
 * rotation of an unbatched bake (so one batch reproduces it bit for bit);
 * every other batch hashes its index in as well, independently. */
static void batch_rotation(unsigned seed, int l, int batch, float *ru, float *rv) {
  uint32_t hsh = bk_mix32((uint32_t)seed * 0x9e3779b9u ^ bk_mix32((uint32_t)l + 0x632be5abu));
  if (batch) hsh = bk_mix32(hsh ^ bk_mix32((uint32_t)batch * 0x85ebca6bu + 0x27d4eb2fu));
  *ru = (float)(hsh >> 8) * (1.0f / 16777216.0f);
  *rv = (float)(bk_mix32(hsh) >> 8) * (1.0f / 16777216.0f);
}

int ph_prepare(const scene_t *scene, const grid_dims_t *g, uint64_t photons, unsigned seed,
               ph_setup_t *out, bk_error_t *err) {
  return ph_prepare_batch(scene, g, photons, seed, 0, out, err);
}

int ph_prepare_batch(const scene_t *scene, const grid_dims_t *g, uint64_t photons, unsigned seed,
                     int batch, ph_setup_t *out, bk_error_t *err) {
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
  for (int l = 0; l < scene->light_count; l++)
    weights[l] = ph_light_power(&scene->lights[l], g, rgb[l]);
  ph_share(weights, scene->light_count, photons, counts);

  uint64_t first = 0;
  for (int l = 0; l < scene->light_count; l++) {
    if (counts[l] == 0) continue;
    const scene_light_t *sl = &scene->lights[l];
    ph_light *L = &out->lights[out->count];
    memset(L, 0, sizeof *L);
    L->type = (int)sl->type;
    light_kinds[sl->type].frame(sl, g, L);
    batch_rotation(seed, l, batch, &L->rot_u, &L->rot_v);
    for (int a = 0; a < 3; a++) {
      L->power[a] = (float)(rgb[l][a] / (double)counts[l]);
      out->power[a] += rgb[l][a];
    }
    L->first = (bk_uint)first;
    L->count = (bk_uint)counts[l];
    ph_launch_plan(L->count, &L->tile_rows, &L->tile_stride);
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
