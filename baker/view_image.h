/* view_image.h: the outputs of `baker view`: a linear half RGBA OpenEXR
 * (camera, source file, frame and integrator in the header), an optional
 * 8-bit sRGB PNG preview, and the per-stage timing table. */
#ifndef BAKER_VIEW_IMAGE_H
#define BAKER_VIEW_IMAGE_H

#include "view_camera.h"
#include "view_render.h"

/* Writes out (EXR) and png (NULL: none) from rgba; the frame goes in the
 * header when has_frame, else the one in the input's metadata if any. */
int view_write_images(const char *in, const char *out, const char *png, const view_cam_t *c,
                      const float *rgba, int has_frame, int frame, float exposure,
                      int integrator, float step, bk_error_t *err);
/* Rays stopped at the step limit (a warning when many), and at verbosity 1
 * the timing table on stdout. */
void view_report(const view_totals_t *tot, int with_png);

#endif
