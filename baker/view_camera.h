/* view_camera.h: the pinhole camera of the viewing pass.
 *
 * In: command-line overrides, the scene's camera (optional), and the world
 * box of the volume for a default. Out: a world-space camera (position,
 * look-at, up, vertical field of view, image size) and a description of
 * where it came from for messages. The vector helpers work in double, as the
 * camera is placed in the volume's index space (view_render.c). */
#ifndef BAKER_VIEW_CAMERA_H
#define BAKER_VIEW_CAMERA_H

#include "base/common.h"
#include "scene.h"

#define VIEW_DEFAULT_FOV 40.0f   /* degrees, vertical; DESIGN.md's example camera */
#define VIEW_DEFAULT_WIDTH 800
#define VIEW_DEFAULT_HEIGHT 600
#define VIEW_MAX_AXIS 65536      /* pixels along one image side */
#define VIEW_PATH_MAX 4096
#define VIEW_PI 3.14159265358979323846

/* What the command line sets (--camera-pos, --look-at, --up, --fov,
 * --resolution); has_*: given. */
typedef struct view_cam_overrides {
  int has_pos, has_look, has_up, has_fov, has_res;
  float pos[3], look[3], up[3], fov;
  int width, height;
} view_cam_overrides_t;

/* The world-space camera and where each part came from, for messages. */
typedef struct view_cam {
  float pos[3], look[3], up[3], fov;
  int width, height;
  int has_pos, has_look;
  char src[VIEW_PATH_MAX + 160];
} view_cam_t;

/* Defaults, then the scene's camera (sc may be NULL), then the overrides. */
void view_cam_from_inputs(const view_cam_overrides_t *o, const scene_t *sc, view_cam_t *c);
/* Checks what is known of the camera: a view direction and an up that is not
 * along it. */
int view_cam_validate(const view_cam_t *c, bk_error_t *err);
/* Frames the world box: from the -z side, a little above, far enough that
 * its bounding sphere fits the narrower field of view. */
void view_cam_fill_default(view_cam_t *c, const double bmin[3], const double bmax[3]);

double view_dot3d(const double a[3], const double b[3]);
void view_cross3d(const double a[3], const double b[3], double out[3]);
/* 0 (a unchanged) when a is zero or not finite. */
int view_normalize3d(double a[3]);
/* Map p (3-vector) through a 3x4 affine matrix. */
void view_affine_apply(const double m[3][4], const double p[3], double out[3]);

#endif
