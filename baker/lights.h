/* lights.h: the kinds of light, as one table.
 *
 * In: a light's entry in the scene file (`lights[i]`), then the grid. Out: a
 * scene_light_t, the power it sends towards the grid (W, RGB) and the
 * ph_light the march samples photons from (kernels/light_sample.h).
 *
 * Each kind is one row of light_kinds[], indexed by its light_type_t, which is
 * also ph_light.type on the device (PH_DIRECTIONAL, PH_SPOT, PH_POINT). A
 * row names the kind as the scene file does, lists the keys it takes (all
 * required), reads them, computes its power and its device frame, and names
 * the -D flag that keeps its generator in a specialised kernel. Adding a
 * light is one row here plus its mapping in ph_map (kernels/light_sample.h).
 *
 * Power towards the grid: directional E·A (A the area of the rectangle
 * perpendicular to the light covering the grid's projection, m^2), spot I·Ω
 * with Ω = 2π(1 - cos θ), point I·4π. */
#ifndef BAKER_LIGHTS_H
#define BAKER_LIGHTS_H

#include "base/grid.h"
#include "kernels/light_sample.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The scene loader's typed reads of the light being parsed, for a kind's
 * parse function. Each reads lights[i].KEY, checks it and on failure returns
 * the loader's error ("scene.json:L:C: lights[i].KEY: expected ..."). */
typedef struct light_reader {
  void *ctx;
  int (*position)(void *ctx, const char *key, float out[3]);  /* any 3 numbers */
  int (*colour)(void *ctx, const char *key, float out[3]);    /* >= 0, a number or [r, g, b] */
  int (*angle)(void *ctx, const char *key, float *out);       /* degrees in (0, 90] */
  int (*direction)(void *ctx, const char *key, float out[3]); /* non-zero, normalised on load */
} light_reader_t;

#define LIGHT_MAX_KEYS 8

typedef struct light_kind {
  const char *name;                   /* lights[i].type in the scene file */
  light_type_t type;                  /* its row in light_kinds[]; = ph_light.type */
  const char *define;                 /* -D flag keeping its generator in the march kernel */
  const char *keys[LIGHT_MAX_KEYS];   /* keys it takes, all required, NULL-terminated */
  int (*parse)(const light_reader_t *r, scene_light_t *l);
  /* W towards the grid per channel into rgb; returns their sum */
  double (*power)(const scene_light_t *l, const grid_dims_t *g, double rgb[3]);
  /* origin or rectangle, direction, basis and cone in voxel coordinates */
  void (*frame)(const scene_light_t *l, const grid_dims_t *g, ph_light *L);
} light_kind_t;

#define LIGHT_KIND_COUNT 3
extern const light_kind_t light_kinds[LIGHT_KIND_COUNT];

/* Every key some kind takes, after "type", NULL-terminated: keys outside it
 * are unknown, keys in it but not the kind's are ignored with a warning. */
extern const char *const light_keys[];

/* The kind named `name`, or NULL. */
const light_kind_t *light_kind_find(const char *name);
/* The kind of a light; NULL for a type outside the table. */
const light_kind_t *light_kind(light_type_t t);
/* Whether kind k takes `key`. */
int light_kind_takes(const light_kind_t *k, const char *key);

#ifdef __cplusplus
}
#endif
#endif
