/* test_vdbio.c: vdbio round trips and refusals.
 *
 *   test_vdbio roundtrip DIR   write float + Vec3 grids of known linear functions
 *                              (trilinear sampling reproduces them exactly), read
 *                              them back densely, resampled and by name; half float
 *                              and the other compressions
 *   test_vdbio errors DIR      truncated/foreign/missing files, missing grids,
 *                              wrong types, unwritable outputs, no stray temp files
 *   test_vdbio write DIR       DIR/known.vdb, for the vdb_print and pyopenvdb checks
 *   test_vdbio foreign FILE    tests/data/vdbio_foreign.vdb: double, Vec3d, int
 *                              grids, rotated and frustum transforms
 *   test_vdbio bench DIR       a 256^3 write/read timing (not a test)
 *
 * The known grids (tests/vdbio_python_check.py repeats these numbers):
 * dims 12x10x8, voxel 0.25, origin (-1.5, 0.75, 2.0), cell-centred;
 * "density" (float) = 1 + 0.5x - 0.25y + 2z at voxel centres with i >= 2, 0
 * (inactive) for i < 2; "radiance" (Vec3f, invariant) = (x, 2y, 3 + z). */
#define _POSIX_C_SOURCE 200809L
#include "vdbio.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "test_util.h"

static const grid_dims_t KNOWN = {12, 10, 8, 0.25f, {-1.5f, 0.75f, 2.0f}};

static double known_density(const double w[3]) {
  return 1.0 + 0.5 * w[0] - 0.25 * w[1] + 2.0 * w[2];
}
static void known_radiance(const double w[3], double out[3]) {
  out[0] = w[0];
  out[1] = 2.0 * w[1];
  out[2] = 3.0 + w[2];
}
static void centre_d(const grid_dims_t *d, double i, double j, double k, double w[3]) {
  w[0] = d->origin[0] + (i + 0.5) * d->voxel_size;
  w[1] = d->origin[1] + (j + 0.5) * d->voxel_size;
  w[2] = d->origin[2] + (k + 0.5) * d->voxel_size;
}

static float *known_density_data(void) {
  const grid_dims_t *d = &KNOWN;
  float *f = calloc(grid_count(d), sizeof(float));
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        double w[3];
        centre_d(d, i, j, k, w);
        f[grid_index(d, i, j, k)] = i < 2 ? 0.0f : (float)known_density(w);
      }
  return f;
}
static float *known_radiance_data(void) {
  const grid_dims_t *d = &KNOWN;
  float *v = calloc(grid_count(d) * 3, sizeof(float));
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        double w[3], g[3];
        centre_d(d, i, j, k, w);
        known_radiance(w, g);
        for (int c = 0; c < 3; c++)
          v[grid_index(d, i, j, k) * 3 + c] = (float)g[c];
      }
  return v;
}

static int write_known(const char *path, const vdbio_write_opts_t *opts, bk_error_t *err) {
  float *f = known_density_data(), *v = known_radiance_data();
  vdbio_grid_t grids[2] = {{"density", VDBIO_FLOAT, f, 0, 0.0f, NULL, NULL, 0}, {"radiance", VDBIO_VEC3, v, 1, 0.0f, NULL, NULL, 0}};
  vdbio_meta_t meta[3] = {{"mode", VDBIO_META_STRING, "reference", 0, 0.0},
                          {"frame", VDBIO_META_INT, NULL, 7, 0.0},
                          {"scale", VDBIO_META_FLOAT, NULL, 0, 0.5}};
  int rc = vdbio_write(path, &KNOWN, grids, 2, meta, 3, opts, err);
  free(f);
  free(v);
  return rc;
}

static long file_size(const char *path) {
  struct stat st;
  return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

/* Names in DIR that look like our temporary files (".NAME.tmpPID"). */
static int count_temp_files(const char *dir) {
  DIR *d = opendir(dir);
  int n = 0;
  if (!d)
    return -1;
  for (struct dirent *e; (e = readdir(d));)
    if (e->d_name[0] == '.' && strstr(e->d_name, ".tmp"))
      n++;
  closedir(d);
  return n;
}

/* Reads FILE back every way and compares with the known functions; `tol` is
 * relative (float or half precision). */
static void check_known(const char *path, double tol) {
  bk_error_t err = {0};
  const grid_dims_t *d = &KNOWN;

  /* dense, padded by one voxel: the active box of "density" starts at i = 2 */
  vdbio_dense_t den;
  int rc = vdbio_read_dense(path, "density", 1, &den, &err);
  EXPECT(rc == BK_OK, "read_dense density: %s", err.msg);
  if (rc == BK_OK) {
    EXPECT(den.nx == d->nx - 2 + 2 && den.ny == d->ny + 2 && den.nz == d->nz + 2 &&
              den.channels == 1,
          "dense box %dx%dx%d ch %d, expected %dx%dx%d ch 1", den.nx, den.ny, den.nz, den.channels,
          d->nx, d->ny + 2, d->nz + 2);
    EXPECT(den.uniform_scale && fabs(den.voxel_size - 0.25) < 1e-9, "uniform %d voxel %g",
          den.uniform_scale, den.voxel_size);
    /* dense (0,0,0) is our voxel (1,-1,-1) */
    double w0[3];
    centre_d(d, 1, -1, -1, w0);
    for (int r = 0; r < 3; r++) {
      EXPECT(fabs(den.index_to_world[r][3] - w0[r]) < 1e-6, "index_to_world t[%d] %g != %g", r,
            den.index_to_world[r][3], w0[r]);
      for (int c = 0; c < 3; c++) {
        EXPECT(fabs(den.index_to_world[r][c] - (r == c ? 0.25 : 0.0)) < 1e-9,
              "index_to_world[%d][%d] = %g", r, c, den.index_to_world[r][c]);
        EXPECT(fabs(den.world_to_index[r][c] - (r == c ? 4.0 : 0.0)) < 1e-9,
              "world_to_index[%d][%d] = %g", r, c, den.world_to_index[r][c]);
      }
      EXPECT(fabs(den.world_to_index[r][3] + 4.0 * w0[r]) < 1e-6, "world_to_index t[%d] %g", r,
            den.world_to_index[r][3]);
    }
    double worst = 0.0;
    for (int c = 0; c < den.nz; c++)
      for (int b = 0; b < den.ny; b++)
        for (int a = 0; a < den.nx; a++) {
          int i = a + 1, j = b - 1, k = c - 1;
          double w[3], want = 0.0;
          for (int r = 0; r < 3; r++)
            w[r] = den.index_to_world[r][0] * a + den.index_to_world[r][1] * b +
                   den.index_to_world[r][2] * c + den.index_to_world[r][3];
          if (i >= 2 && i < d->nx && j >= 0 && j < d->ny && k >= 0 && k < d->nz)
            want = known_density(w);
          double got = den.data[(size_t)a + (size_t)den.nx * ((size_t)b + (size_t)den.ny * c)];
          double e = fabs(got - want) / (1.0 + fabs(want));
          if (e > worst)
            worst = e;
        }
    EXPECT(worst <= tol, "read_dense density: worst relative error %.3g > %.3g", worst, tol);
    printf("  read_dense density %dx%dx%d: worst relative error %.3g\n", den.nx, den.ny, den.nz,
           worst);

    /* "radiance" resampled into the density box: exact (linear) where the
     * box lies on radiance voxels, background where it lies outside */
    vdbio_dense_t rad;
    int found = -1;
    rc = vdbio_read_dense_like(path, "radiance", &den, &rad, &found, &err);
    EXPECT(rc == BK_OK && found == 1, "read_dense_like radiance: rc %d found %d %s", rc, found,
          err.msg);
    if (rc == BK_OK && found) {
      EXPECT(rad.channels == 3 && rad.nx == den.nx && rad.ny == den.ny && rad.nz == den.nz,
            "dense_like box");
      worst = 0.0;
      for (int c = 0; c < rad.nz; c++)
        for (int b = 0; b < rad.ny; b++)
          for (int a = 0; a < rad.nx; a++) {
            int i = a + 1, j = b - 1, k = c - 1;
            double w[3], want[3] = {0, 0, 0};
            centre_d(d, i, j, k, w);
            if (i < d->nx && j >= 0 && j < d->ny && k >= 0 && k < d->nz)
              known_radiance(w, want);
            for (int ch = 0; ch < 3; ch++) {
              double got =
                  rad.data[((size_t)a + (size_t)rad.nx * ((size_t)b + (size_t)rad.ny * c)) * 3 +
                           ch];
              double e = fabs(got - want[ch]) / (1.0 + fabs(want[ch]));
              if (e > worst)
                worst = e;
            }
          }
      EXPECT(worst <= tol, "read_dense_like radiance: worst relative error %.3g", worst);
      printf("  read_dense_like radiance: worst relative error %.3g\n", worst);
      vdbio_dense_free(&rad);
    }
    rc = vdbio_read_dense_like(path, "no_such_grid", &den, &rad, &found, &err);
    EXPECT(rc == BK_OK && found == 0 && rad.data == NULL, "absent grid: rc %d found %d", rc, found);
    vdbio_dense_free(&den);
  }

  /* the Vec3 grid densely: whole grid active, box = our grid */
  vdbio_dense_t vd;
  rc = vdbio_read_dense(path, "radiance", 0, &vd, &err);
  EXPECT(rc == BK_OK, "read_dense radiance: %s", err.msg);
  if (rc == BK_OK) {
    EXPECT(vd.nx == d->nx && vd.ny == d->ny && vd.nz == d->nz && vd.channels == 3,
          "radiance box %dx%dx%d", vd.nx, vd.ny, vd.nz);
    double w[3], g[3];
    centre_d(d, 5, 3, 6, w); /* one voxel by hand: (i,j,k) -> data[i + nx*(j + ny*k)] */
    known_radiance(w, g);
    const float *p = vd.data + grid_index(d, 5, 3, 6) * 3;
    for (int c = 0; c < 3; c++)
      EXPECT(fabs(p[c] - g[c]) <= tol * (1.0 + fabs(g[c])), "radiance(5,3,6)[%d] = %g, want %g", c,
            p[c], g[c]);
    vdbio_dense_free(&vd);
  }

  /* resampled at the voxel centres of the same grid: the stored values */
  float *same = calloc(grid_count(d), sizeof(float)), *ref = known_density_data();
  rc = vdbio_resample_float(path, "density", d, same, "test.same", &err);
  EXPECT(rc == BK_OK, "resample same: %s", err.msg);
  double worst = 0.0;
  for (size_t n = 0; n < grid_count(d); n++) {
    double e = fabs(same[n] - ref[n]) / (1.0 + fabs(ref[n]));
    if (e > worst)
      worst = e;
  }
  EXPECT(worst <= tol, "resample at own centres: worst %.3g", worst);
  printf("  resample_float at own voxel centres: worst relative error %.3g\n", worst);
  free(same);
  free(ref);

  /* resampled on a finer, shifted grid: between voxel centres, exact for a
   * linear function where all 8 neighbours are active; 0 far outside */
  grid_dims_t fine = {30, 30, 30, 0.1f, {-1.93f, 0.41f, 1.57f}};
  float *out = calloc(grid_count(&fine), sizeof(float));
  rc = vdbio_resample_float(path, "density", &fine, out, "test.fine", &err);
  EXPECT(rc == BK_OK, "resample fine: %s", err.msg);
  double lo[3], hi[3];
  centre_d(d, 2, 0, 0, lo);
  centre_d(d, d->nx - 1, d->ny - 1, d->nz - 1, hi);
  int inside = 0, outside = 0;
  worst = 0.0;
  for (int k = 0; k < fine.nz; k++)
    for (int j = 0; j < fine.ny; j++)
      for (int i = 0; i < fine.nx; i++) {
        double w[3];
        centre_d(&fine, i, j, k, w);
        double got = out[grid_index(&fine, i, j, k)], want;
        int in = 1, far = 0;
        for (int r = 0; r < 3; r++) {
          if (w[r] < lo[r] || w[r] > hi[r])
            in = 0;
          if (w[r] < lo[r] - 0.5 - 0.25 || w[r] > hi[r] + 0.25 + 0.25)
            far = 1;
        }
        if (in) {
          want = known_density(w);
          inside++;
        } else if (far) {
          want = 0.0;
          outside++;
        } else {
          continue;
        }
        double e = fabs(got - want) / (1.0 + fabs(want));
        if (e > worst)
          worst = e;
      }
  EXPECT(inside > 1000 && outside > 1000, "fine grid: %d inside, %d outside", inside, outside);
  EXPECT(worst <= tol, "resample fine: worst relative error %.3g", worst);
  printf("  resample_float on a shifted 0.1 grid: %d points inside, %d outside, worst %.3g\n",
         inside, outside, worst);
  free(out);
}

/* The grids read side by side equal the grids read one by one, checksums
 * checked; a missing grid among them is the answer and no array is kept. */
static void check_read_all(const char *path) {
  bk_error_t err = {0};
  const char *names[3] = {"radiance", "density", "radiance"};
  vdbio_dense_t all[3], one;
  int checked[3] = {0, 0, 0};
  int rc = vdbio_read_dense_verified_all(path, 3, names, NULL, all, checked, NULL, NULL, &err);
  EXPECT(rc == BK_OK, "read_dense_verified_all: %s", err.msg);
  for (int i = 0; rc == BK_OK && i < 3; i++) {
    int ck = 0;
    EXPECT(vdbio_read_dense_verified(path, names[i], 0, &one, &ck, &err) == BK_OK, "%s: %s",
           names[i], err.msg);
    size_t n = (size_t)one.nx * one.ny * one.nz * (size_t)one.channels;
    EXPECT(all[i].nx == one.nx && all[i].ny == one.ny && all[i].nz == one.nz &&
               all[i].channels == one.channels && checked[i] == ck && ck == 1 &&
               !memcmp(all[i].data, one.data, n * sizeof(float)) &&
               !memcmp(all[i].index_to_world, one.index_to_world, sizeof one.index_to_world),
           "grid %d (%s) read side by side differs from its single read", i, names[i]);
    vdbio_dense_free(&one);
    vdbio_dense_free(&all[i]);
  }
  const char *missing[3] = {"density", "no_such_grid", "radiance"};
  rc = vdbio_read_dense_verified_all(path, 3, missing, NULL, all, checked, NULL, NULL, &err);
  EXPECT(rc == BK_ERR_INPUT && strstr(err.msg, "no_such_grid"), "missing grid: rc %d %s", rc,
         err.msg);
  for (int i = 0; i < 3; i++)
    EXPECT(all[i].data == NULL, "grid %d kept after the failure", i);
  /* answers are taken as they come (a missing grid's before the radiance),
   * yet the first failure in list order is the one reported */
  const char *two[4] = {"radiance", "no_such_a", "density", "no_such_b"};
  vdbio_dense_t four[4];
  int checked4[4];
  rc = vdbio_read_dense_verified_all(path, 4, two, NULL, four, checked4, NULL, NULL, &err);
  EXPECT(rc == BK_ERR_INPUT && strstr(err.msg, "no_such_a") && !strstr(err.msg, "no_such_b"),
         "two missing grids: rc %d %s", rc, err.msg);
  for (int i = 0; i < 4; i++)
    EXPECT(four[i].data == NULL, "grid %d kept after the failure", i);
  const char *late[3] = {"no_such_c", "radiance", "no_such_d"};
  rc = vdbio_read_dense_verified_all(path, 3, late, NULL, all, checked, NULL, NULL, &err);
  EXPECT(rc == BK_ERR_INPUT && strstr(err.msg, "no_such_c"), "first grid missing: rc %d %s", rc,
         err.msg);
}

static int roundtrip(const char *dir) {
  char path[4096], half[4096], none[4096], blosc[4096];
  bk_error_t err = {0};
  snprintf(path, sizeof path, "%s/vdbio_roundtrip.vdb", dir);
  snprintf(half, sizeof half, "%s/vdbio_roundtrip_half.vdb", dir);
  snprintf(none, sizeof none, "%s/vdbio_roundtrip_none.vdb", dir);
  snprintf(blosc, sizeof blosc, "%s/vdbio_roundtrip_blosc.vdb", dir);

  vdbio_write_opts_t zip = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
  int rc = write_known(path, &zip, &err);
  EXPECT(rc == BK_OK, "write: %s", err.msg);
  if (rc)
    return 1;
  EXPECT(count_temp_files(dir) == 0, "a temporary file survived in %s", dir);
  printf("zip, full float (%ld bytes):\n", file_size(path));
  check_known(path, 1e-6);
  check_read_all(path);

  char **names = NULL, **types = NULL;
  int count = 0;
  rc = vdbio_list_grids(path, &names, &types, &count, &err);
  EXPECT(rc == BK_OK && count == 2, "list_grids: rc %d count %d %s", rc, count, err.msg);
  for (int g = 0; rc == BK_OK && g < count; g++) {
    printf("  grid %s (%s)\n", names[g], types[g]);
    int dens = !strcmp(names[g], "density"), radi = !strcmp(names[g], "radiance");
    EXPECT(dens || radi, "unexpected grid %s", names[g]);
    EXPECT(!strcmp(types[g], dens ? "float" : "vec3s"), "grid %s has type %s", names[g], types[g]);
  }
  if (rc == BK_OK)
    vdbio_free_names(names, types, count);

  char buf[256];
  struct {
    const char *key, *want;
    int prefix;
  } metas[] = {{"creator", "baker ", 1}, {"voxel_centering", "cell-centred", 1},
               {"mode", "reference", 0}, {"frame", "7", 0},
               {"scale", "0.5", 0},      {"absent_key", "", 0}};
  for (size_t m = 0; m < sizeof metas / sizeof metas[0]; m++) {
    rc = vdbio_read_meta(path, metas[m].key, buf, sizeof buf, &err);
    int ok = rc == BK_OK && (metas[m].prefix ? !strncmp(buf, metas[m].want, strlen(metas[m].want))
                                             : !strcmp(buf, metas[m].want));
    EXPECT(ok, "meta %s = \"%s\", want \"%s\"", metas[m].key, buf, metas[m].want);
    printf("  meta %s = \"%s\"\n", metas[m].key, buf);
  }

  /* half float: smaller file on a grid big enough for the payload to dominate */
  grid_dims_t big = {48, 48, 48, 0.05f, {0.3f, -1.0f, 0.7f}};
  float *f = calloc(grid_count(&big), sizeof(float));
  for (int k = 0; k < big.nz; k++)
    for (int j = 0; j < big.ny; j++)
      for (int i = 0; i < big.nx; i++) {
        double w[3];
        centre_d(&big, i, j, k, w);
        f[grid_index(&big, i, j, k)] = (float)(1.5 + sin(3.0 * w[0]) * cos(2.0 * w[1]) + w[2]);
      }
  char bigf[4096], bigh[4096];
  snprintf(bigf, sizeof bigf, "%s/vdbio_big_full.vdb", dir);
  snprintf(bigh, sizeof bigh, "%s/vdbio_big_half.vdb", dir);
  vdbio_grid_t g1 = {"density", VDBIO_FLOAT, f, 0, 0.0f, NULL, NULL, 0};
  vdbio_write_opts_t hopt = {VDBIO_COMPRESS_ZIP, 1, NULL, NULL};
  EXPECT(vdbio_write(bigf, &big, &g1, 1, NULL, 0, &zip, &err) == BK_OK, "big full: %s", err.msg);
  EXPECT(vdbio_write(bigh, &big, &g1, 1, NULL, 0, &hopt, &err) == BK_OK, "big half: %s", err.msg);
  long sf = file_size(bigf), sh = file_size(bigh);
  printf("48^3 smooth float grid, zip: full %ld bytes, half %ld bytes (%.2f)\n", sf, sh,
         (double)sh / (double)sf);
  EXPECT(sh > 0 && sh < 0.75 * sf, "half float file %ld is not smaller than 0.75 x %ld", sh, sf);
  float *back = calloc(grid_count(&big), sizeof(float));
  EXPECT(vdbio_resample_float(bigh, "density", &big, back, "test.half", &err) == BK_OK, "%s",
        err.msg);
  double worst = 0.0;
  for (size_t n = 0; n < grid_count(&big); n++) {
    double e = fabs(back[n] - f[n]) / fabs(f[n]);
    if (e > worst)
      worst = e;
  }
  printf("  half read back: worst relative error %.3g (half ulp 2^-11 = 4.9e-4)\n", worst);
  EXPECT(worst > 0.0 && worst <= 4.9e-4, "half float read back: worst relative error %.3g", worst);
  free(back);
  free(f);

  /* the small file in half, uncompressed and blosc: same values */
  EXPECT(write_known(half, &hopt, &err) == BK_OK, "write half: %s", err.msg);
  printf("zip, half float (%ld bytes):\n", file_size(half));
  check_known(half, 1e-3);
  vdbio_write_opts_t nopt = {VDBIO_COMPRESS_NONE, 0, NULL, NULL};
  vdbio_write_opts_t bopt = {VDBIO_COMPRESS_BLOSC, 0, NULL, NULL};
  EXPECT(write_known(none, &nopt, &err) == BK_OK, "write none: %s", err.msg);
  printf("uncompressed (%ld bytes):\n", file_size(none));
  check_known(none, 1e-6);
  EXPECT(write_known(blosc, &bopt, &err) == BK_OK, "write blosc: %s", err.msg);
  printf("blosc (%ld bytes):\n", file_size(blosc));
  check_known(blosc, 1e-6);
  EXPECT(count_temp_files(dir) == 0, "a temporary file survived in %s", dir);

  /* an empty grid reads as one voxel of background */
  float *zero = calloc(grid_count(&KNOWN), sizeof(float));
  vdbio_grid_t gz = {"empty", VDBIO_FLOAT, zero, 0, 0.0f, NULL, NULL, 0};
  char empty[4096];
  snprintf(empty, sizeof empty, "%s/vdbio_empty.vdb", dir);
  EXPECT(vdbio_write(empty, &KNOWN, &gz, 1, NULL, 0, NULL, &err) == BK_OK, "empty: %s", err.msg);
  vdbio_dense_t ed;
  rc = vdbio_read_dense(empty, "empty", 2, &ed, &err);
  EXPECT(rc == BK_OK && ed.nx == 1 && ed.ny == 1 && ed.nz == 1 && ed.data[0] == 0.0f,
        "empty grid: rc %d %dx%dx%d %s", rc, ed.nx, ed.ny, ed.nz, err.msg);
  if (rc == BK_OK)
    vdbio_dense_free(&ed);
  free(zero);
  return tu_failures != 0;
}

/* Expects rc == BK_ERR_INPUT and the message to name `name`. */
static void expect_input_error(int rc, const bk_error_t *err, const char *name, const char *what,
                               const char *also) {
  EXPECT(rc == BK_ERR_INPUT, "%s: rc %d, expected BK_ERR_INPUT (%s)", what, rc, err->msg);
  EXPECT(strstr(err->msg, name) != NULL, "%s: message does not name %s: %s", what, name, err->msg);
  if (also)
    EXPECT(strstr(err->msg, also) != NULL, "%s: message lacks \"%s\": %s", what, also, err->msg);
  printf("  %s -> %d: %s\n", what, rc, err->msg);
}

static int copy_prefix(const char *from, const char *to, long len) {
  FILE *in = fopen(from, "rb"), *out = fopen(to, "wb");
  if (!in || !out) {
    if (in)
      fclose(in);
    if (out)
      fclose(out);
    return -1;
  }
  for (long n = 0; n < len; n++) {
    int c = fgetc(in);
    if (c == EOF)
      break;
    fputc(c, out);
  }
  fclose(in);
  fclose(out);
  return 0;
}

static int errors(const char *dir) {
  char path[4096], bad[4096];
  bk_error_t err = {0};
  float *out = calloc(grid_count(&KNOWN), sizeof(float));
  vdbio_dense_t dd;
  int rc;

  /* truncated copies of real files, compressed and not, cut at several places */
  const vdbio_compression_t comps[3] = {VDBIO_COMPRESS_ZIP, VDBIO_COMPRESS_NONE,
                                        VDBIO_COMPRESS_BLOSC};
  for (int c = 0; c < 3; c++) {
    vdbio_write_opts_t opt = {comps[c], 0, NULL, NULL};
    snprintf(path, sizeof path, "%s/vdbio_errors_%d.vdb", dir, c);
    EXPECT(write_known(path, &opt, &err) == BK_OK, "write: %s", err.msg);
    long size = file_size(path);
    /* inside the header, inside each grid, one byte short */
    const long cuts[] = {40, size / 50, size * 3 / 10, size * 6 / 10, size * 9 / 10, size - 1};
    for (size_t n = 0; n < sizeof cuts / sizeof cuts[0]; n++) {
      long len = cuts[n];
      snprintf(bad, sizeof bad, "%s/vdbio_truncated_%d_%ld.vdb", dir, c, len);
      EXPECT(copy_prefix(path, bad, len) == 0, "copy %s", bad);
      char what[128];
      snprintf(what, sizeof what, "compression %d truncated to %ld of %ld bytes, resample", c, len,
               size);
      err.msg[0] = 0;
      rc = vdbio_resample_float(bad, "density", &KNOWN, out, "medium.ior_vdb", &err);
      expect_input_error(rc, &err, bad, what, "medium.ior_vdb");
      snprintf(what, sizeof what, "compression %d truncated to %ld of %ld bytes, read_dense", c,
               len, size);
      err.msg[0] = 0;
      rc = vdbio_read_dense(bad, "radiance", 0, &dd, &err);
      expect_input_error(rc, &err, bad, what, NULL);
      EXPECT(dd.data == NULL, "no data after a failed read");
    }
  }
  snprintf(path, sizeof path, "%s/vdbio_errors_0.vdb", dir);

  /* a text file named .vdb */
  snprintf(bad, sizeof bad, "%s/vdbio_text.vdb", dir);
  FILE *t = fopen(bad, "w");
  fputs("this is not a VDB file, just text\n", t);
  fclose(t);
  rc = vdbio_resample_float(bad, "density", &KNOWN, out, "medium.ior_vdb", &err);
  expect_input_error(rc, &err, bad, "text file", "medium.ior_vdb");
  rc = vdbio_read_dense(bad, "density", 0, &dd, &err);
  expect_input_error(rc, &err, bad, "text file, read_dense", NULL);
  char **names, **types;
  int count;
  rc = vdbio_list_grids(bad, &names, &types, &count, &err);
  expect_input_error(rc, &err, bad, "text file, list_grids", NULL);

  /* a missing file */
  snprintf(bad, sizeof bad, "%s/vdbio_no_such_file.vdb", dir);
  rc = vdbio_resample_float(bad, "density", &KNOWN, out, "medium.density_vdb", &err);
  expect_input_error(rc, &err, bad, "missing file", "No such file");
  char buf[64];
  rc = vdbio_read_meta(bad, "creator", buf, sizeof buf, &err);
  expect_input_error(rc, &err, bad, "missing file, read_meta", NULL);

  /* a missing grid lists the ones present; a Vec3 grid is not a float grid */
  rc = vdbio_resample_float(path, "ior", &KNOWN, out, "medium.ior_vdb", &err);
  expect_input_error(rc, &err, path, "missing grid", "\"radiance\" (vec3s)");
  rc = vdbio_read_dense(path, "ior", 0, &dd, &err);
  expect_input_error(rc, &err, path, "missing grid, read_dense", "\"density\" (float)");
  rc = vdbio_resample_float(path, "radiance", &KNOWN, out, "medium.ior_vdb", &err);
  expect_input_error(rc, &err, path, "Vec3 grid as float", "vec3s");

  /* an output directory that does not exist: an error, and no file at all */
  snprintf(bad, sizeof bad, "%s/no_such_dir/out.vdb", dir);
  vdbio_write_opts_t zip = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
  rc = write_known(bad, &zip, &err);
  EXPECT(rc != BK_OK && strstr(err.msg, bad), "missing directory: rc %d %s", rc, err.msg);
  EXPECT(access(bad, F_OK) != 0, "a file appeared at %s", bad);
  printf("  missing output directory -> %d: %s\n", rc, err.msg);

  /* the rename fails (the final name is a directory): error, temp removed */
  snprintf(bad, sizeof bad, "%s/vdbio_is_a_dir.vdb", dir);
  mkdir(bad, 0755);
  rc = write_known(bad, &zip, &err);
  EXPECT(rc == BK_ERR_RUNTIME && strstr(err.msg, bad), "rename onto a directory: rc %d %s", rc,
        err.msg);
  printf("  output path is a directory -> %d: %s\n", rc, err.msg);
  EXPECT(count_temp_files(dir) == 0, "a temporary file survived a failed write in %s", dir);
  rmdir(bad);

  free(out);
  return tu_failures != 0;
}

/* tests/data/vdbio_foreign.vdb (made by tests/data/vdbio_foreign.cpp): grids
 * on [0,3]^3 of types and transforms baker never writes. */
static double foreign_value(double i, double j, double k) { return 1.0 + i + 10.0 * j + 100.0 * k; }

static int foreign(const char *path) {
  bk_error_t err = {0};
  vdbio_dense_t d, r, like;
  int rc, found;

  char **names = NULL, **types = NULL;
  int count = 0;
  rc = vdbio_list_grids(path, &names, &types, &count, &err);
  EXPECT(rc == BK_OK && count == 5, "list_grids: rc %d count %d %s", rc, count, err.msg);
  const char *want_types[][2] = {{"dens_d", "double"},
                                 {"vel_d", "vec3d"},
                                 {"count_i", "int32"},
                                 {"rotated", "float"},
                                 {"frustum", "float"}};
  for (int w = 0; rc == BK_OK && w < 5; w++) {
    int hit = 0;
    for (int g = 0; g < count; g++)
      hit |= !strcmp(names[g], want_types[w][0]) && !strcmp(types[g], want_types[w][1]);
    EXPECT(hit, "grid %s (%s) not listed", want_types[w][0], want_types[w][1]);
  }
  if (rc == BK_OK)
    vdbio_free_names(names, types, count);

  /* double and Vec3d are converted; index (0,0,0) sits at (1,2,3), voxel 0.5 */
  rc = vdbio_read_dense(path, "dens_d", 0, &d, &err);
  EXPECT(rc == BK_OK && d.nx == 4 && d.ny == 4 && d.nz == 4 && d.channels == 1,
        "dens_d: rc %d %dx%dx%d %s", rc, d.nx, d.ny, d.nz, err.msg);
  if (rc == BK_OK) {
    double worst = 0.0;
    for (int k = 0; k < 4; k++)
      for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++)
          worst = fmax(worst, fabs(d.data[i + 4 * (j + 4 * k)] - foreign_value(i, j, k)));
    EXPECT(worst == 0.0, "dens_d values: worst error %g", worst);
    EXPECT(d.uniform_scale && d.voxel_size == 0.5 && d.index_to_world[0][3] == 1.0 &&
              d.index_to_world[1][3] == 2.0 && d.index_to_world[2][3] == 3.0,
          "dens_d transform");
    vdbio_dense_free(&d);
  }
  rc = vdbio_read_dense(path, "vel_d", 1, &d, &err);
  EXPECT(rc == BK_OK && d.nx == 6 && d.channels == 3, "vel_d: rc %d nx %d ch %d %s", rc, d.nx,
        d.channels, err.msg);
  if (rc == BK_OK) {
    const float *p = d.data + (2 + 6 * (3 + 6 * 4)) * 3; /* padded: dense (2,3,4) is (1,2,3) */
    EXPECT(p[0] == 1.5f && p[1] == 2.5f && p[2] == 3.5f, "vel_d(1,2,3) = %g %g %g", p[0], p[1],
          p[2]);
    EXPECT(d.data[0] == 0.0f, "vel_d padding is background");
    vdbio_dense_free(&d);
  }

  /* a rotated, non-uniform affine map: world = (1 - j, 2 + 0.5 i, 3 + 2 k) */
  rc = vdbio_read_dense(path, "rotated", 0, &like, &err);
  EXPECT(rc == BK_OK, "rotated: %s", err.msg);
  if (rc == BK_OK) {
    const double m[3][4] = {{0, -1, 0, 1}, {0.5, 0, 0, 2}, {0, 0, 2, 3}};
    double worst = 0.0;
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 4; b++)
        worst = fmax(worst, fabs(like.index_to_world[a][b] - m[a][b]));
    /* world_to_index inverts index_to_world */
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 4; b++) {
        double v = like.world_to_index[a][3] * (b == 3);
        for (int c = 0; c < 3; c++)
          v += like.world_to_index[a][c] * like.index_to_world[c][b];
        worst = fmax(worst, fabs(v - (a == b)));
      }
    EXPECT(worst < 1e-12, "rotated matrices: worst error %g", worst);
    EXPECT(!like.uniform_scale && like.voxel_size == 0.5, "rotated: uniform %d voxel %g",
          like.uniform_scale, like.voxel_size);
    printf("  rotated: index_to_world rows (%g %g %g %g) (%g %g %g %g) (%g %g %g %g), voxel %g\n",
           like.index_to_world[0][0], like.index_to_world[0][1], like.index_to_world[0][2],
           like.index_to_world[0][3], like.index_to_world[1][0], like.index_to_world[1][1],
           like.index_to_world[1][2], like.index_to_world[1][3], like.index_to_world[2][0],
           like.index_to_world[2][1], like.index_to_world[2][2], like.index_to_world[2][3],
           like.voxel_size);
    /* dens_d through world space into the rotated box: rotated index (i,j,k)
     * is dens_d index (-2j, i, 4k), on dens_d's voxels only for j = k = 0 */
    rc = vdbio_read_dense_like(path, "dens_d", &like, &r, &found, &err);
    EXPECT(rc == BK_OK && found == 1 && r.channels == 1, "dens_d like rotated: %s", err.msg);
    if (rc == BK_OK) {
      worst = 0.0;
      for (int k = 0; k < 4; k++)
        for (int j = 0; j < 4; j++)
          for (int i = 0; i < 4; i++) {
            double want = (j == 0 && k == 0) ? foreign_value(0, i, 0) : 0.0;
            worst = fmax(worst, fabs(r.data[i + 4 * (j + 4 * k)] - want));
          }
      EXPECT(worst < 1e-4, "dens_d like rotated: worst error %g", worst);
      vdbio_dense_free(&r);
    }
    vdbio_dense_free(&like);
  }

  /* resampling the rotated grid: trilinear reproduces its linear values
   * wherever all 8 neighbours lie in [0,3]^3 */
  grid_dims_t g = {20, 20, 40, 0.2f, {-2.5f, 1.5f, 2.5f}};
  float *out = calloc(grid_count(&g), sizeof(float));
  rc = vdbio_resample_float(path, "rotated", &g, out, "test.rotated", &err);
  EXPECT(rc == BK_OK, "resample rotated: %s", err.msg);
  int inside = 0;
  double worst = 0.0;
  for (int k = 0; rc == BK_OK && k < g.nz; k++)
    for (int j = 0; j < g.ny; j++)
      for (int i = 0; i < g.nx; i++) {
        double w[3];
        centre_d(&g, i, j, k, w);
        double ii = 2.0 * (w[1] - 2.0), jj = 1.0 - w[0], kk = 0.5 * (w[2] - 3.0);
        if (ii < 0 || ii > 3 || jj < 0 || jj > 3 || kk < 0 || kk > 3)
          continue;
        inside++;
        double want = foreign_value(ii, jj, kk);
        worst = fmax(worst, fabs(out[grid_index(&g, i, j, k)] - want) / want);
      }
  EXPECT(inside > 500 && worst < 1e-5, "resample rotated: %d inside, worst relative %g", inside,
        worst);
  printf("  resample_float rotated: %d points inside, worst relative error %.3g\n", inside, worst);
  /* a double grid is accepted by resample_float */
  rc = vdbio_resample_float(path, "dens_d", &g, out, "test.double", &err);
  EXPECT(rc == BK_OK, "resample double: %s", err.msg);
  free(out);

  /* refusals: an int grid, a frustum transform */
  rc = vdbio_read_dense(path, "count_i", 0, &d, &err);
  expect_input_error(rc, &err, path, "int32 grid, read_dense", "int32");
  float one;
  grid_dims_t g1 = {1, 1, 1, 0.5f, {1, 2, 3}};
  rc = vdbio_resample_float(path, "count_i", &g1, &one, "medium.ior_vdb", &err);
  expect_input_error(rc, &err, path, "int32 grid, resample", "int32");
  rc = vdbio_read_dense(path, "frustum", 0, &d, &err);
  expect_input_error(rc, &err, path, "frustum grid, read_dense", "unsupported");
  rc = vdbio_read_dense_like(path, "count_i", &like, &r, &found, &err);
  expect_input_error(rc, &err, path, "int32 grid, read_dense_like", "int32");
  return tu_failures != 0;
}

static int bench(const char *dir) {
  grid_dims_t d = {256, 256, 256, 1.0f / 256.0f, {0, 0, 0}};
  bk_error_t err = {0};
  float *f = calloc(grid_count(&d), sizeof(float)), *back = calloc(grid_count(&d), sizeof(float));
  for (int k = 0; k < d.nz; k++)
    for (int j = 0; j < d.ny; j++)
      for (int i = 0; i < d.nx; i++) {
        float w[3];
        grid_voxel_center(&d, i, j, k, w);
        float r2 =
            (w[0] - .5f) * (w[0] - .5f) + (w[1] - .5f) * (w[1] - .5f) + (w[2] - .5f) * (w[2] - .5f);
        f[grid_index(&d, i, j, k)] = r2 < 0.16f ? 1.0f + w[0] : 0.0f; /* a ball, 27% active */
      }
  char path[4096];
  snprintf(path, sizeof path, "%s/vdbio_bench.vdb", dir);
  vdbio_grid_t g = {"density", VDBIO_FLOAT, f, 0, 0.0f, NULL, NULL, 0};
  const vdbio_compression_t comps[3] = {VDBIO_COMPRESS_NONE, VDBIO_COMPRESS_ZIP,
                                        VDBIO_COMPRESS_BLOSC};
  for (int c = 0; c < 3; c++) {
    vdbio_write_opts_t o = {comps[c], 0, NULL, NULL};
    double t0 = bk_now_ms();
    int rc = vdbio_write(path, &d, &g, 1, NULL, 0, &o, &err);
    double t1 = bk_now_ms();
    rc |= vdbio_resample_float(path, "density", &d, back, "bench", &err);
    double t2 = bk_now_ms();
    printf("256^3 ball, compression %d: write %.0f ms (%ld bytes), resample_float %.0f ms, rc %d\n",
           c, t1 - t0, file_size(path), t2 - t1, rc);
  }
  size_t bad = 0;
  for (size_t n = 0; n < grid_count(&d); n++)
    bad += fabsf(back[n] - f[n]) > 1e-6f;
  printf("mismatches %zu\n", bad);
  remove(path);
  free(f);
  free(back);
  return bad != 0;
}

static void mkdir_p(const char *dir) {
  char buf[4096];
  snprintf(buf, sizeof buf, "%s", dir);
  for (char *p = buf + 1; *p; p++)
    if (*p == '/') {
      *p = 0;
      mkdir(buf, 0755);
      *p = '/';
    }
  mkdir(buf, 0755);
}

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s roundtrip|errors|write|bench DIR | foreign FILE\n", argv[0]);
    return 2;
  }
  bk_verbosity = 1;
  int rc;
  if (!strcmp(argv[1], "foreign")) {
    rc = foreign(argv[2]);
    printf("foreign: %d failure(s)\n", tu_failures);
    return rc;
  }
  mkdir_p(argv[2]);
  if (!strcmp(argv[1], "write")) {
    bk_error_t err = {0};
    vdbio_write_opts_t zip = {VDBIO_COMPRESS_ZIP, 0, NULL, NULL};
    char path[4096];
    snprintf(path, sizeof path, "%s/known.vdb", argv[2]);
    rc = write_known(path, &zip, &err);
    if (rc)
      fprintf(stderr, "%s\n", err.msg);
    return rc;
  }
  if (!strcmp(argv[1], "roundtrip"))
    rc = roundtrip(argv[2]);
  else if (!strcmp(argv[1], "errors"))
    rc = errors(argv[2]);
  else if (!strcmp(argv[1], "bench"))
    rc = bench(argv[2]);
  else
    rc = 2;
  printf("%s: %d failure(s)\n", argv[1], tu_failures);
  return rc;
}
