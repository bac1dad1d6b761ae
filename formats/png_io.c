/* png_io.c: sRGB 8-bit PNG previews through libpng. */
#include "png_io.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdlib.h>
#include <string.h>

float png_srgb_oetf(float c) {
  if (!(c > 0.0f)) return 0.0f; /* also NaN */
  if (c >= 1.0f) return 1.0f;
  return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1.0f / 2.4f) - 0.055f;
}

/* libpng reports errors by longjmp; the message is kept for bk_fail. */
typedef struct png_err_ctx {
  char msg[256];
} png_err_ctx_t;

static void on_png_error(png_structp png, png_const_charp msg) {
  png_err_ctx_t *ctx = png_get_error_ptr(png);
  /* libpng's "Write Error" hides why: the failed fwrite left it in errno */
  if (errno)
    snprintf(ctx->msg, sizeof ctx->msg, "%s: %s", msg, strerror(errno));
  else
    snprintf(ctx->msg, sizeof ctx->msg, "%s", msg);
  png_longjmp(png, 1);
}
static void on_png_warning(png_structp png, png_const_charp msg) { (void)png; (void)msg; }

int png_write_preview(const char *path, int width, int height, const float *rgba,
                      float exposure_ev, bk_error_t *err) {
  char temp[4096];
  size_t row_bytes;
  if (width <= 0 || height <= 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: image size must be positive, got %dx%d", path, width,
                   height);
  if (!bk_mul_size((size_t)width, 3, &row_bytes))
    return bk_fail(err, BK_ERR_INPUT, "%s: image width %d overflows", path, width);
  bk_temp_path(path, temp, sizeof temp);

  int rc = BK_OK;
  FILE *f = NULL;
  png_structp png = NULL;
  png_infop info = NULL;
  png_err_ctx_t ctx = {{0}};
  /* volatile: assigned before setjmp, read after a longjmp */
  unsigned char *volatile row = bk_calloc(row_bytes, 1, "PNG row", err);
  if (!row) return BK_ERR_RUNTIME;
  f = fopen(temp, "wb");
  if (!f) {
    rc = bk_fail(err, BK_ERR_RUNTIME, "%s: cannot create %s: %s", path, temp, strerror(errno));
    goto error;
  }
  png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &ctx, on_png_error, on_png_warning);
  if (png) info = png_create_info_struct(png);
  if (!png || !info) {
    rc = bk_fail(err, BK_ERR_RUNTIME, "%s: libpng could not start (out of memory)", path);
    goto error;
  }
  if (setjmp(png_jmpbuf(png))) {
    rc = bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write PNG: %s", path, ctx.msg);
    goto error;
  }
  png_init_io(png, f);
  errno = 0;
  png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  const float gain = exp2f(exposure_ev);
  for (int y = 0; y < height; y++) {
    const float *src = rgba + (size_t)y * (size_t)width * 4;
    for (int x = 0; x < width; x++)
      for (int c = 0; c < 3; c++)
        row[3 * x + c] = (unsigned char)lrintf(255.0f * png_srgb_oetf(src[4 * x + c] * gain));
    png_write_row(png, row);
  }
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  if (fclose(f) != 0) {
    f = NULL;
    rc = bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write %s: %s", path, temp, strerror(errno));
    goto error;
  }
  f = NULL;
  free(row);
  return bk_commit_temp(temp, path, err);

error:
  if (png) png_destroy_write_struct(&png, info ? &info : NULL);
  if (f) fclose(f);
  remove(temp);
  free(row);
  return rc;
}
