/* view_camera.c: the pinhole camera of `baker view`: from flags, a scene or
 * defaults, checked, and framed on the volume when not given; and the
 * double-precision vector helpers the viewing pass places it with. */
#include "view_camera.h"

#include <math.h>
#include <string.h>

void view_affine_apply(const double m[3][4], const double p[3], double out[3]) {
  for (int r = 0; r < 3; r++) out[r] = m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3];
}

double view_dot3d(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
void view_cross3d(const double a[3], const double b[3], double out[3]) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}
int view_normalize3d(double a[3]) {
  double l = sqrt(view_dot3d(a, a));
  if (!(l > 0.0) || !isfinite(l)) return 0;
  for (int k = 0; k < 3; k++) a[k] /= l;
  return 1;
}

void view_cam_from_inputs(const view_cam_overrides_t *o, const scene_t *sc, view_cam_t *c) {
  memset(c, 0, sizeof *c);
  c->up[1] = 1.0f;
  c->fov = VIEW_DEFAULT_FOV;
  c->width = VIEW_DEFAULT_WIDTH;
  c->height = VIEW_DEFAULT_HEIGHT;
  snprintf(c->src, sizeof c->src, "default camera");
  if (sc) {
    c->fov = sc->camera.fov_deg;
    c->width = sc->camera.width;
    c->height = sc->camera.height;
    if (sc->camera.present) {
      memcpy(c->pos, sc->camera.position, sizeof c->pos);
      memcpy(c->look, sc->camera.look_at, sizeof c->look);
      memcpy(c->up, sc->camera.up, sizeof c->up);
      c->has_pos = c->has_look = 1;
      snprintf(c->src, sizeof c->src, "%s: camera", sc->path);
    }
  }
  if (o->has_pos || o->has_look || o->has_up) {
    char flags[64];
    snprintf(flags, sizeof flags, "%s%s%s", o->has_pos ? " --camera-pos" : "",
             o->has_look ? " --look-at" : "", o->has_up ? " --up" : "");
    if (sc && sc->camera.present)
      snprintf(c->src + strlen(c->src), sizeof c->src - strlen(c->src), " overridden by%s", flags);
    else
      snprintf(c->src, sizeof c->src, "camera from%s", flags);
  }
  if (o->has_pos) memcpy(c->pos, o->pos, sizeof c->pos), c->has_pos = 1;
  if (o->has_look) memcpy(c->look, o->look, sizeof c->look), c->has_look = 1;
  if (o->has_up) memcpy(c->up, o->up, sizeof c->up);
  if (o->has_fov) c->fov = o->fov;
  if (o->has_res) c->width = o->width, c->height = o->height;
}

int view_cam_validate(const view_cam_t *c, bk_error_t *err) {
  if (c->width < 1 || c->height < 1)
    return bk_fail(err, BK_ERR_INPUT, "%s: resolution must be at least 1x1, got %dx%d", c->src,
                   c->width, c->height);
  if (!(c->fov > 0.0f && c->fov < 180.0f))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: vertical field of view must be in (0, 180) degrees, got %g", c->src,
                   c->fov);
  if (!c->has_pos || !c->has_look) return BK_OK;
  double f[3], u[3] = {c->up[0], c->up[1], c->up[2]}, r[3];
  double scale = 0.0;
  for (int k = 0; k < 3; k++) {
    f[k] = (double)c->look[k] - c->pos[k];
    scale = fmax(scale, fmax(fabs(c->look[k]), fabs(c->pos[k])));
  }
  if (!(sqrt(view_dot3d(f, f)) > 1e-6 * fmax(scale, 1e-30)))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: the look-at point (%g, %g, %g) equals the camera position; expected a "
                   "point to look at away from the camera", c->src, c->look[0], c->look[1],
                   c->look[2]);
  view_cross3d(f, u, r);
  if (!(view_dot3d(r, r) > 1e-12 * view_dot3d(f, f) * view_dot3d(u, u)))
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: up (%g, %g, %g) is zero or along the line of sight; expected a vector "
                   "not parallel to look-at - position", c->src, c->up[0], c->up[1], c->up[2]);
  return BK_OK;
}

void view_cam_fill_default(view_cam_t *c, const double bmin[3], const double bmax[3]) {
  double ctr[3], r2 = 0.0;
  for (int k = 0; k < 3; k++) {
    ctr[k] = 0.5 * (bmin[k] + bmax[k]);
    r2 += 0.25 * (bmax[k] - bmin[k]) * (bmax[k] - bmin[k]);
  }
  double radius = fmax(sqrt(r2), 1e-6);
  double half_y = 0.5 * c->fov * VIEW_PI / 180.0;
  double half_x = atan(tan(half_y) * (double)c->width / (double)c->height);
  double dist = 1.05 * radius / sin(fmin(half_x, half_y));
  double dir[3] = {0.0, 0.25, -1.0};
  view_normalize3d(dir);
  if (!c->has_look)
    for (int k = 0; k < 3; k++) c->look[k] = (float)ctr[k];
  if (!c->has_pos)
    for (int k = 0; k < 3; k++) c->pos[k] = (float)(ctr[k] + dist * dir[k]);
  c->has_pos = c->has_look = 1;
}
