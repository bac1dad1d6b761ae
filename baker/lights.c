/* lights.c: directional, spot and point lights (see lights.h). */
#include "lights.h"

#include <math.h>
#include <string.h>

_Static_assert(LIGHT_DIRECTIONAL == PH_DIRECTIONAL && LIGHT_SPOT == PH_SPOT &&
                   LIGHT_POINT == PH_POINT,
               "light_type_t is ph_light.type on the device");

/* --- geometry shared by the kinds ------------------------------------------ */

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

/* in normalised; a zero vector (a point light's) becomes +z. */
static void unit_direction(const float in[3], double d[3]) {
  double l = sqrt((double)in[0] * in[0] + (double)in[1] * in[1] + (double)in[2] * in[2]);
  for (int a = 0; a < 3; a++) d[a] = l > 0.0 ? in[a] / l : (a == 2 ? 1.0 : 0.0);
}

static void set_frame(ph_light *L, const double p[3], const double d[3], const double u[3],
                      const double w[3], float cos_max) {
  L->px = (float)p[0], L->py = (float)p[1], L->pz = (float)p[2];
  L->dx = (float)d[0], L->dy = (float)d[1], L->dz = (float)d[2];
  L->ux = (float)u[0], L->uy = (float)u[1], L->uz = (float)u[2];
  L->vx = (float)w[0], L->vy = (float)w[1], L->vz = (float)w[2];
  L->cos_max = cos_max;
}

static double colour_power(double k, const float c[3], double rgb[3]) {
  for (int a = 0; a < 3; a++) rgb[a] = k * (double)c[a];
  return rgb[0] + rgb[1] + rgb[2];
}

/* --- directional ----------------------------------------------------------- */

static int directional_parse(const light_reader_t *r, scene_light_t *l) {
  int rc;
  if ((rc = r->colour(r->ctx, "irradiance", l->irradiance)) ||
      (rc = r->direction(r->ctx, "direction", l->direction)))
    return rc;
  return BK_OK;
}

/* The rectangle in voxel coordinates: perpendicular to d, covering the
 * projection of the grid's box, one voxel before it. Returns its area in m^2. */
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

static double directional_power(const scene_light_t *l, const grid_dims_t *g, double rgb[3]) {
  double corner[3], U[3], V[3];
  return colour_power(directional_rect(l, g, corner, U, V), l->irradiance, rgb);
}

static void directional_frame(const scene_light_t *l, const grid_dims_t *g, ph_light *L) {
  double d[3], U[3], V[3], corner[3];
  unit_direction(l->direction, d);
  directional_rect(l, g, corner, U, V);
  set_frame(L, corner, d, U, V, 1.0f);
}

/* --- spot and point: a cone about the direction, the whole sphere for a point */

static int spot_parse(const light_reader_t *r, scene_light_t *l) {
  int rc;
  if ((rc = r->angle(r->ctx, "angle_deg", &l->angle_deg)) ||
      (rc = r->position(r->ctx, "position", l->position)) ||
      (rc = r->colour(r->ctx, "intensity", l->intensity)) ||
      (rc = r->direction(r->ctx, "direction", l->direction)))
    return rc;
  return BK_OK;
}

static int point_parse(const light_reader_t *r, scene_light_t *l) {
  int rc;
  if ((rc = r->position(r->ctx, "position", l->position)) ||
      (rc = r->colour(r->ctx, "intensity", l->intensity)))
    return rc;
  return BK_OK;
}

static double spot_cos(const scene_light_t *l) { return cos((double)l->angle_deg * M_PI / 180.0); }

static double spot_power(const scene_light_t *l, const grid_dims_t *g, double rgb[3]) {
  return colour_power(2.0 * M_PI * (1.0 - spot_cos(l)), l->intensity, rgb);
}

static double point_power(const scene_light_t *l, const grid_dims_t *g, double rgb[3]) {
  return colour_power(4.0 * M_PI, l->intensity, rgb);
}

static void cone_frame(const scene_light_t *l, const grid_dims_t *g, ph_light *L, float cos_max) {
  double d[3], u[3], w[3], p[3];
  unit_direction(l->direction, d);
  basis(d, u, w);
  for (int a = 0; a < 3; a++) p[a] = ((double)l->position[a] - g->origin[a]) / g->voxel_size;
  set_frame(L, p, d, u, w, cos_max);
}

static void spot_frame(const scene_light_t *l, const grid_dims_t *g, ph_light *L) {
  cone_frame(l, g, L, (float)spot_cos(l));
}

static void point_frame(const scene_light_t *l, const grid_dims_t *g, ph_light *L) {
  cone_frame(l, g, L, -1.0f);
}

/* --- the table --------------------------------------------------------------- */

const light_kind_t light_kinds[LIGHT_KIND_COUNT] = {
    {"directional", LIGHT_DIRECTIONAL, "LIGHT_DIRECTIONAL", {"direction", "irradiance", NULL},
     directional_parse, directional_power, directional_frame},
    {"spot", LIGHT_SPOT, "LIGHT_SPOT", {"position", "direction", "angle_deg", "intensity", NULL},
     spot_parse, spot_power, spot_frame},
    {"point", LIGHT_POINT, "LIGHT_POINT", {"position", "intensity", NULL}, point_parse, point_power,
     point_frame},
};

/* in this order the "did you mean" hint of an unknown key picks among ties */
const char *const light_keys[] = {"type", "position", "direction", "angle_deg",
                                  "intensity", "irradiance", NULL};

const light_kind_t *light_kind_find(const char *name) {
  for (int i = 0; i < LIGHT_KIND_COUNT; i++)
    if (strcmp(light_kinds[i].name, name) == 0) return &light_kinds[i];
  return NULL;
}

const light_kind_t *light_kind(light_type_t t) {
  return (int)t >= 0 && (int)t < LIGHT_KIND_COUNT ? &light_kinds[t] : NULL;
}

int light_kind_takes(const light_kind_t *k, const char *key) {
  for (const char *const *p = k->keys; *p; p++)
    if (strcmp(*p, key) == 0) return 1;
  return 0;
}
