/* png_io.h: 8-bit sRGB PNG previews of linear images.
 *
 * In: linear RGBA floats (top row first) and an exposure in stops. Out: an
 * 8-bit RGB PNG (alpha dropped: the preview shows the image as rendered, over
 * its background) with each channel c -> round(255 · OETF(clamp(c·2^EV, 0, 1))),
 * OETF the sRGB transfer curve (12.92 c below 0.0031308, else
 * 1.055 c^(1/2.4) − 0.055), tagged with an sRGB chunk. Written under a
 * temporary name and renamed. */
#ifndef BAKER_PNG_IO_H
#define BAKER_PNG_IO_H

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The sRGB transfer curve (linear [0,1] -> encoded [0,1]). */
float png_srgb_oetf(float linear);

int png_write_preview(const char *path, int width, int height, const float *rgba,
                      float exposure_ev, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
