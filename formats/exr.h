/* exr.h: OpenEXR images of the viewing pass, behind a C interface.
 *
 * In: linear RGBA floats, row-major from the top row, and what produced them.
 * Out: a scan-line EXR with half-float R, G, B, A (ZIP compressed) whose
 * header records the camera (V3f cameraPosition, cameraLookAt, cameraUp;
 * float cameraFovYDeg, the VERTICAL field of view in degrees; the standard
 * worldToCamera matrix), the source file (string sourceFile), the frame (int
 * frame) and the software. Values beyond half range are clamped to ±65504 and
 * NaN becomes 0, so the file never holds inf/NaN. The file is written under a
 * temporary name and renamed. All C++ exceptions stop at this boundary and
 * become BK_ERR_RUNTIME (write) or BK_ERR_INPUT (read, naming the file). */
#ifndef BAKER_EXR_H
#define BAKER_EXR_H

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct exr_info {
  const char *source;     /* input file, NULL to leave out */
  int has_frame;
  int frame;
  int has_camera;
  float cam_position[3], cam_look_at[3], cam_up[3];
  float cam_fov_y_deg;    /* vertical */
  const char *comments;   /* standard "comments" attribute, NULL to leave out */
} exr_info_t;

int exr_write_rgba(const char *path, int width, int height, const float *rgba,
                   const exr_info_t *info, bk_error_t *err);

/* Reads any RGBA EXR (missing channels read as 0, A as 1) into a malloc'ed
 * float array of width*height*4, top row first. */
int exr_read_rgba(const char *path, int *width, int *height, float **rgba, bk_error_t *err);

/* One header attribute as text: V3f "x y z", float/int/double as numbers,
 * string as is. BK_ERR_INPUT when the file or the attribute is missing or of
 * another type. */
int exr_read_attribute(const char *path, const char *name, char *out, size_t len,
                       bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
