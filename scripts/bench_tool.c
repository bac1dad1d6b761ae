/* bench_tool: image and grid measurements for scripts/bench and
 * scripts/gpu-check that Python cannot make here (no OpenEXR module for
 * /usr/bin/python3; no pyopenvdb on a GPU node).
 *
 *   bench_tool exrdiff TEST.exr REF.exr
 *   bench_tool vdbdiff TEST.vdb REF.vdb GRID
 *
 * In: two RGBA OpenEXR images of the same size (formats/exr.h reads them).
 * Out: one JSON line on stdout,
 *   {"rel_rms": e, "rms": d, "ref_rms": r, "width": w, "height": h,
 *    "nonfinite": k, "max_abs": m, "differ": f, "rel_mae": a}
 * with the relative RMS error over the R, G, B values of every pixel
 *   e = sqrt( sum (test - ref)^2 / sum ref^2 ),
 * its absolute kin a = sum |test - ref| / sum |ref| (less ruled by the few
 * pixels whose rays graze a refracting surface and go elsewhere),
 * d = sqrt(mean (test - ref)^2), r = sqrt(mean ref^2), k the number of
 * non-finite values in TEST (the writer turns NaN into 0 and clamps inf to the
 * half range, so k counts what reached the file), m the largest |test-ref|
 * and f the fraction of pixels where some channel differs by more than the
 * rounding of two half-float writes (2e-3 relative, plus 1e-4 of the
 * reference's RMS red for black pixels).
 * Alpha is left out: it is coverage, not radiance. A reference that is black
 * everywhere gives e = null (the ratio is undefined).
 *
 * vdbdiff reads GRID (float or Vec3f) of both files densely over their
 * active boxes and prints one JSON line,
 *   {"max_rel": m, "rel_l2": e, "voxels": n, "max_abs": a, "nonfinite": k}
 * m = max |test - ref| / max |ref| over voxels and channels (1e30 when k
 * values of either file are NaN or infinite), e the relative L2
 * sqrt(sum (test - ref)^2 / sum ref^2) over the finite ones; the boxes and
 * transforms must be equal.
 * Exit status: 0 success, 2 bad input (unreadable files, sizes differ). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/common.h"
#include "formats/exr.h"
#include "formats/vdbio.h"

static void usage(FILE *out) {
  fprintf(out,
          "usage: bench_tool exrdiff TEST.exr REF.exr\n"
          "  prints {\"rel_rms\": ..., \"rms\": ..., \"ref_rms\": ..., \"width\": ..., "
          "\"height\": ..., \"nonfinite\": ..., \"max_abs\": ..., \"differ\": ..., \"rel_mae\": ...}\n"
          "  rel_rms = sqrt(sum (TEST-REF)^2 / sum REF^2) over R, G, B of all pixels\n"
          "usage: bench_tool vdbdiff TEST.vdb REF.vdb GRID\n"
          "  prints {\"max_rel\": ..., \"rel_l2\": ..., \"voxels\": ..., \"max_abs\": ...}\n"
          "  max_rel = max |TEST-REF| / max |REF| over the voxels and channels of GRID\n");
}

static int exrdiff(const char *test_path, const char *ref_path) {
  bk_error_t err = {0, ""};
  float *test = NULL, *ref = NULL;
  int tw = 0, th = 0, rw = 0, rh = 0;
  int rc = exr_read_rgba(test_path, &tw, &th, &test, &err);
  if (rc) goto error;
  rc = exr_read_rgba(ref_path, &rw, &rh, &ref, &err);
  if (rc) goto error;
  if (tw != rw || th != rh) {
    rc = bk_fail(&err, BK_ERR_INPUT, "%s is %dx%d but the reference %s is %dx%d: render both "
                 "at the same --resolution", test_path, tw, th, ref_path, rw, rh);
    goto error;
  }
  /* double sums: a 800x600 image has 1.4 M values, float would lose digits */
  double sum_d2 = 0.0, sum_r2 = 0.0, max_abs = 0.0, sum_ad = 0.0, sum_ar = 0.0;
  long long nonfinite = 0, differ = 0;
  size_t pixels = (size_t)tw * (size_t)th;
  for (size_t p = 0; p < pixels; p++) sum_r2 += (double)ref[4 * p] * ref[4 * p];
  const double floor_abs = 1e-4 * sqrt(sum_r2 / (double)(pixels ? pixels : 1));
  sum_r2 = 0.0;
  for (size_t p = 0; p < pixels; p++) {
    int pixel_differs = 0;
    for (int c = 0; c < 3; c++) {
      double t = test[4 * p + c], r = ref[4 * p + c];
      if (!isfinite(t)) {
        nonfinite++;
        continue;
      }
      double d = t - r;
      sum_d2 += d * d;
      sum_r2 += r * r;
      sum_ad += fabs(d), sum_ar += fabs(r);
      if (fabs(d) > max_abs) max_abs = fabs(d);
      /* beyond the rounding of two half-float writes (2^-11 each) */
      if (fabs(d) > 2e-3 * fabs(r) + floor_abs) pixel_differs = 1;
    }
    differ += pixel_differs;
  }
  double n = (double)pixels * 3.0;
  printf("{\"rel_rms\": ");
  if (sum_r2 > 0.0) printf("%.9g", sqrt(sum_d2 / sum_r2));
  else printf("null");
  printf(", \"rms\": %.9g, \"ref_rms\": %.9g, \"width\": %d, \"height\": %d, "
         "\"nonfinite\": %lld, \"max_abs\": %.9g, \"differ\": %.9g, \"rel_mae\": ",
         sqrt(sum_d2 / n), sqrt(sum_r2 / n), tw, th, nonfinite, max_abs,
         (double)differ / (double)(pixels ? pixels : 1));
  if (sum_ar > 0.0) printf("%.9g}\n", sum_ad / sum_ar);
  else printf("null}\n");
error:
  if (rc) fprintf(stderr, "bench_tool exrdiff: %s\n", err.msg);
  free(test);
  free(ref);
  return rc;
}

static int same_box(const vdbio_dense_t *a, const vdbio_dense_t *b) {
  return a->nx == b->nx && a->ny == b->ny && a->nz == b->nz && a->channels == b->channels &&
         !memcmp(a->index_to_world, b->index_to_world, sizeof a->index_to_world);
}

static int vdbdiff(const char *test_path, const char *ref_path, const char *grid) {
  bk_error_t err = {0, ""};
  vdbio_dense_t test = {0}, ref = {0};
  int rc = vdbio_read_dense(test_path, grid, 0, &test, &err);
  if (!rc) rc = vdbio_read_dense(ref_path, grid, 0, &ref, &err);
  if (!rc && !same_box(&test, &ref))
    rc = bk_fail(&err, BK_ERR_INPUT, "%s: grid %s covers %dx%dx%d (%d channels), %s %dx%dx%d "
                 "(%d): the active boxes or transforms differ", test_path, grid, test.nx, test.ny,
                 test.nz, test.channels, ref_path, ref.nx, ref.ny, ref.nz, ref.channels);
  if (!rc) {
    size_t n = (size_t)ref.nx * ref.ny * ref.nz * ref.channels;
    double sum_d2 = 0.0, sum_r2 = 0.0, max_d = 0.0, max_r = 0.0;
    size_t nonfinite = 0;
    for (size_t i = 0; i < n; i++) {
      double t = test.data[i], r = ref.data[i], d = fabs(t - r);
      if (!isfinite(d)) { /* NaN or inf in either: never within a tolerance */
        nonfinite++;
        continue;
      }
      sum_d2 += d * d;
      sum_r2 += r * r;
      if (d > max_d) max_d = d;
      if (fabs(r) > max_r) max_r = fabs(r);
    }
    double max_rel = nonfinite ? 1e30 : max_r > 0.0 ? max_d / max_r : (max_d > 0.0);
    printf("{\"max_rel\": %.9g, \"rel_l2\": %.9g, \"voxels\": %zu, \"max_abs\": %.9g, "
           "\"nonfinite\": %zu}\n", max_rel, sum_r2 > 0.0 ? sqrt(sum_d2 / sum_r2) : 0.0,
           n / (size_t)ref.channels, max_d, nonfinite);
  } else {
    fprintf(stderr, "bench_tool vdbdiff: %s\n", err.msg);
  }
  vdbio_dense_free(&test);
  vdbio_dense_free(&ref);
  return rc;
}

int main(int argc, char **argv) {
  if (argc == 4 && !strcmp(argv[1], "exrdiff")) return exrdiff(argv[2], argv[3]);
  if (argc == 5 && !strcmp(argv[1], "vdbdiff")) return vdbdiff(argv[2], argv[3], argv[4]);
  if (argc == 2 && (!strcmp(argv[1], "-h") || !strcmp(argv[1], "--help"))) {
    usage(stdout);
    return BK_OK;
  }
  usage(stderr);
  return BK_ERR_INPUT;
}
