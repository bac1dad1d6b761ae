/* test_clhost.c: the OpenCL host layer and the ∇n kernel on PoCL.
 * Usage: test_clhost errors|gradient|cache DIR|build_error|device_spec|no_platform */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "clhost.h"
#include "ior.h"
#include "iorgrad.h"
#include "test_util.h"

static int init_or_die(clh_context_t *cl, const char *spec) {
  bk_error_t err = {0};
  if (clh_init(cl, spec, &err) != BK_OK) {
    fprintf(stderr, "FAIL clh_init: %s\n", err.msg);
    return 0;
  }
  return 1;
}

/* --- errors: names, CLH_CHECK, include expansion ----------------------------- */

static int check_macro(cl_int code, bk_error_t *err) {
  CLH_CHECK(code, err, error);
  return BK_OK;
error:
  return err->code;
}

static int test_errors(void) {
  EXPECT(strcmp(clh_error_name(CL_OUT_OF_RESOURCES), "CL_OUT_OF_RESOURCES") == 0, "-5");
  EXPECT(strcmp(clh_error_name(CL_BUILD_PROGRAM_FAILURE), "CL_BUILD_PROGRAM_FAILURE") == 0, "-11");
  EXPECT(strcmp(clh_error_name(CL_INVALID_DEVICE_PARTITION_COUNT),
               "CL_INVALID_DEVICE_PARTITION_COUNT") == 0, "-68");
  EXPECT(strcmp(clh_error_name(-1001), "CL_PLATFORM_NOT_FOUND_KHR") == 0, "-1001");
  EXPECT(strcmp(clh_error_name(-9999), "unknown OpenCL error -9999") == 0, "%s",
        clh_error_name(-9999));
  /* every 1.2 code from 0 to -68 that exists has a name */
  int named = 0;
  for (int c = 0; c >= -68; c--) named += strncmp(clh_error_name(c), "CL_", 3) == 0;
  EXPECT(named == 59, "named codes %d, expected 59 (0..-19, -30..-68)", named);

  bk_error_t err = {0};
  EXPECT(check_macro(CL_INVALID_KERNEL_ARGS, &err) == BK_ERR_RUNTIME, "macro code");
  EXPECT(strstr(err.msg, "CL_INVALID_KERNEL_ARGS") && strstr(err.msg, "test_clhost.c:") &&
            strstr(err.msg, "code"), "macro message: %s", err.msg);
  EXPECT(check_macro(CL_SUCCESS, &err) == BK_OK, "success passes");

  const clh_source_t table[] = {
      {"a.h", "#ifndef A\n#define A\n#include \"b.h\"\nint a;\n#endif\n", 0},
      {"b.h", "  #  include \"c.h\"\nint b;", 0},
      {"c.h", "int c;\n", 0},
      {"loop1.h", "#include \"loop2.h\"\n", 0},
      {"loop2.h", "x\n#include \"loop1.h\"\n", 0},
      {"miss.h", "\n\n#include \"nothere.h\"\n", 0},
      {NULL, NULL, 0}};
  char *s = clh_expand_with(table, "kernels/top.cl", "#include \"a.h\"\nint top;\n", &err);
  EXPECT(s != NULL, "expansion failed: %s", err.msg);
  if (s) {
    const char *pa = strstr(s, "int a;"), *pb = strstr(s, "int b;"), *pc = strstr(s, "int c;"),
               *pt = strstr(s, "int top;");
    EXPECT(pa && pb && pc && pt && pc < pb && pb < pa && pa < pt, "order wrong:\n%s", s);
    EXPECT(strstr(s, "#include") == NULL, "include left:\n%s", s);
    EXPECT(strstr(s, "#line 1 \"kernels/c.h\"") && strstr(s, "#line 2 \"kernels/top.cl\""),
          "line markers:\n%s", s);
    free(s);
  }
  s = clh_expand_with(table, "kernels/top.cl", "#include \"loop1.h\"\n", &err);
  EXPECT(s == NULL && err.code == BK_ERR_RUNTIME && strstr(err.msg, "cycle") &&
            strstr(err.msg, "loop1.h -> loop2.h -> loop1.h"), "cycle: %s", err.msg);
  free(s);
  s = clh_expand_with(table, "kernels/top.cl", "#include \"miss.h\"\n", &err);
  EXPECT(s == NULL && err.code == BK_ERR_RUNTIME && strstr(err.msg, "kernels/miss.h:3") &&
            strstr(err.msg, "nothere.h"), "missing: %s", err.msg);
  free(s);

  s = clh_expand_source("ior.cl", &err);
  EXPECT(s && strstr(s, "ior_gradient_at") && strstr(s, "bk_sample_trilinear") &&
            !strstr(s, "#include \""), "ior.cl expansion: %s", s ? "content" : err.msg);
  free(s);
  s = clh_expand_source("nosuch.cl", &err);
  EXPECT(s == NULL && err.code == BK_ERR_RUNTIME && strstr(err.msg, "kernels/nosuch.cl"), "%s",
        err.msg);
  free(s);
  return tu_failures;
}

/* --- gradient: PoCL vs host vs analytic --------------------------------------- */

/* n = 1 + A exp(-|x - c|^2): smooth, and every derivative is known. */
#define AMP 0.3
static const double centre[3] = {-0.1, 0.2, 0.15};

static double n_exact(const double x[3]) {
  double r2 = 0;
  for (int a = 0; a < 3; a++) r2 += (x[a] - centre[a]) * (x[a] - centre[a]);
  return 1.0 + AMP * exp(-r2);
}
static void grad_exact(const double x[3], double g[3]) {
  double e = n_exact(x) - 1.0;
  for (int a = 0; a < 3; a++) g[a] = -2.0 * (x[a] - centre[a]) * e;
}

static float *make_field(const grid_dims_t *d) {
  float *n = malloc(grid_count(d) * sizeof(float));
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        float c[3];
        grid_voxel_center(d, i, j, k, c);
        double x[3] = {c[0], c[1], c[2]};
        n[grid_index(d, i, j, k)] = (float)n_exact(x);
      }
  return n;
}

/* Bounds on the truncation error, from the 1D factor f(t) = A exp(-t^2)
 * (the other factors are <= 1): central differences err <= h^2/6 max|f'''|,
 * one-sided err <= h/2 max|f''|. max|f'''| = 3.9036 A (at t = 0.5247),
 * max|f''| = 2A (at t = 0), and max|f'| = 0.8578 A (at t = 0.7071). */
#define F3MAX (AMP * 3.9036)
#define F2MAX (AMP * 2.0)

typedef struct grad_err {
  double interior, face, max_grad;
} grad_err_t;

static grad_err_t compare_analytic(const grid_dims_t *d, const float *grad) {
  grad_err_t e = {0, 0, 0};
  for (int k = 0; k < d->nz; k++)
    for (int j = 0; j < d->ny; j++)
      for (int i = 0; i < d->nx; i++) {
        float c[3];
        grid_voxel_center(d, i, j, k, c);
        double x[3] = {c[0], c[1], c[2]}, g[3];
        grad_exact(x, g);
        int idx[3] = {i, j, k}, cnt[3] = {d->nx, d->ny, d->nz};
        for (int a = 0; a < 3; a++) {
          double diff = fabs(grad[3 * grid_index(d, i, j, k) + a] - g[a]);
          int face = idx[a] == 0 || idx[a] == cnt[a] - 1;
          if (face && diff > e.face) e.face = diff;
          if (!face && diff > e.interior) e.interior = diff;
          if (fabs(g[a]) > e.max_grad) e.max_grad = fabs(g[a]);
        }
      }
  return e;
}

static int test_gradient(void) {
  clh_context_t cl;
  bk_error_t err = {0};
  if (!init_or_die(&cl, NULL)) return 1;
  /* 32^3 with an off-centre origin, and a lopsided grid to catch axis mix-ups */
  grid_dims_t dims[2] = {{32, 32, 32, 0.14f, {-2.3f, -1.7f, -2.1f}},
                         {20, 28, 12, 0.19f, {-1.9f, -2.6f, -1.05f}}};
  double interior_err[2] = {0, 0};
  for (int t = 0; t < 2; t++) {
    const grid_dims_t *d = &dims[t];
    size_t n3 = 3 * grid_count(d);
    float *n = make_field(d), *gh = calloc(n3, sizeof(float)), *gd = calloc(n3, sizeof(float));
    EXPECT(ig_compute_host(d, n, gh, &err) == BK_OK, "host: %s", err.msg);
    EXPECT(ig_compute_cl(&cl, d, n, gd, &err) == BK_OK, "device: %s", err.msg);
    double gmax = 0, worst = 0;
    for (size_t q = 0; q < n3; q++) gmax = fmax(gmax, fabs(gh[q]));
    for (size_t q = 0; q < n3; q++) {
      /* relative, with a floor of 1e-5 of the largest gradient where ∇n ~ 0 */
      double rel = fabs(gd[q] - gh[q]) / fmax(fabs(gh[q]), 1e-2 * gmax);
      worst = fmax(worst, rel);
    }
    EXPECT(worst <= 1e-5, "grid %d: device vs host relative difference %.3g", t, worst);
    double h = d->voxel_size;
    double cd_bound = h * h / 6.0 * F3MAX + 1e-5, face_bound = h / 2.0 * F2MAX + 1e-5;
    grad_err_t eh = compare_analytic(d, gh), ed = compare_analytic(d, gd);
    EXPECT(eh.interior <= cd_bound && ed.interior <= cd_bound,
          "grid %d: interior error host %.3g device %.3g > bound %.3g", t, eh.interior,
          ed.interior, cd_bound);
    EXPECT(eh.face <= face_bound && ed.face <= face_bound,
          "grid %d: face error host %.3g device %.3g > bound %.3g", t, eh.face, ed.face,
          face_bound);
    printf("grid %dx%dx%d h=%.3f: max |grad n| %.4f /m; device vs host max rel diff %.2g; "
           "interior error %.3g (bound %.3g), face error %.3g (bound %.3g)\n",
           d->nx, d->ny, d->nz, h, eh.max_grad, worst, eh.interior, cd_bound, eh.face,
           face_bound);
    interior_err[t] = eh.interior;

    /* Between voxel centres: the sampled gradient grid and the on-the-fly
     * interpolation agree, equal ior_gradient_at on centres, and are within
     * the difference error plus the trilinear error h^2/8 sum|d2 g/dx_a^2|. */
    bk_grid g = ig_kernel_grid(d);
    double interp_bound = cd_bound + h * h / 8.0 * (F3MAX + 2 * AMP * 0.8578 * 2.0);
    double worst_interp = 0, worst_pair = 0;
    unsigned seed = 12345;
    for (int s = 0; s < 2000; s++) {
      float u[3];
      int cnt[3] = {d->nx, d->ny, d->nz};
      for (int a = 0; a < 3; a++) {
        seed = seed * 1103515245u + 12345u;
        u[a] = 1.5f + (float)((seed >> 8) & 0xffff) / 65536.0f * (float)(cnt[a] - 3);
      }
      bk_v3 uv = v3(u[0], u[1], u[2]);
      bk_v3 a = ior_gradient_sample(gh, g, uv), b = ior_gradient_trilinear(n, g, uv);
      double x[3] = {d->origin[0] + u[0] * h, d->origin[1] + u[1] * h, d->origin[2] + u[2] * h};
      double ge[3];
      grad_exact(x, ge);
      worst_pair = fmax(worst_pair, v3_length(v3_sub(a, b)));
      worst_interp = fmax(worst_interp, fmax(fabs(a.x - ge[0]), fmax(fabs(a.y - ge[1]),
                                                                      fabs(a.z - ge[2]))));
    }
    EXPECT(worst_pair <= 1e-6, "sample vs trilinear %.3g", worst_pair);
    EXPECT(worst_interp <= interp_bound, "interpolated error %.3g > %.3g", worst_interp,
          interp_bound);
    bk_v3 at = ior_gradient_at(n, g, 7, 5, 3);
    bk_v3 cs = ior_gradient_trilinear(n, g, v3(7.5f, 5.5f, 3.5f));
    EXPECT(v3_length(v3_sub(at, cs)) <= 1e-7, "centre sample differs");
    bk_v3 w = ior_voxel_coord(g, v3(d->origin[0] + 2.5f * d->voxel_size, d->origin[1],
                                    d->origin[2] + d->voxel_size));
    EXPECT(fabsf(w.x - 2.5f) < 1e-4f && fabsf(w.y) < 1e-4f && fabsf(w.z - 1.0f) < 1e-4f,
          "voxel coord %g %g %g", w.x, w.y, w.z);
    free(n);
    free(gh);
    free(gd);
  }
  /* second order: halving h on the 32^3 field divides the interior error by ~4 */
  {
    grid_dims_t fine = {64, 64, 64, 0.07f, {-2.3f, -1.7f, -2.1f}};
    float *n = make_field(&fine), *gh = calloc(3 * grid_count(&fine), sizeof(float));
    EXPECT(ig_compute_host(&fine, n, gh, &err) == BK_OK, "%s", err.msg);
    double e = compare_analytic(&fine, gh).interior;
    printf("interior error h=0.14: %.3g, h=0.07: %.3g, ratio %.2f\n", interior_err[0], e,
           interior_err[0] / e);
    EXPECT(interior_err[0] / e > 3.5, "convergence ratio %.2f, expected ~4", interior_err[0] / e);
    free(n);
    free(gh);
  }
  /* a one-voxel-thick axis has no gradient along it */
  {
    grid_dims_t flat = {4, 1, 3, 0.5f, {0, 0, 0}};
    float n[12], gr[36];
    for (int q = 0; q < 12; q++) n[q] = 1.0f + 0.1f * (float)q;
    EXPECT(ig_compute_host(&flat, n, gr, &err) == BK_OK, "%s", err.msg);
    EXPECT(gr[1] == 0.0f && fabsf(gr[0] - 0.2f) < 1e-6f && fabsf(gr[2] - 0.8f) < 1e-6f,
          "flat grid %g %g %g", gr[0], gr[1], gr[2]);
    grid_dims_t empty = {0, 4, 4, 0.5f, {0, 0, 0}};
    EXPECT(ig_compute_host(&empty, n, gr, &err) == BK_ERR_INPUT, "empty grid accepted");
  }
  clh_release(&cl);
  return tu_failures;
}

/* --- cache -------------------------------------------------------------------- */

static int count_cache_files(const char *dir, char *one, size_t len) {
  DIR *dp = opendir(dir);
  int n = 0;
  if (!dp) return 0;
  for (struct dirent *e; (e = readdir(dp));) {
    if (strstr(e->d_name, ".clbin") && e->d_name[0] != '.') {
      n++;
      if (one) snprintf(one, len, "%s/%s", dir, e->d_name);
    }
  }
  closedir(dp);
  return n;
}

static void clean_dir(const char *dir) {
  DIR *dp = opendir(dir);
  if (!dp) return;
  char p[4600];
  for (struct dirent *e; (e = readdir(dp));) {
    if (e->d_name[0] == '.' && (!e->d_name[1] || (e->d_name[1] == '.' && !e->d_name[2])))
      continue;
    snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
    remove(p);
  }
  closedir(dp);
  rmdir(dir);
}

static int build_once(clh_context_t *cl, const char *opts) {
  bk_error_t err = {0};
  cl_program p = NULL;
  int rc = clh_build(cl, "ior.cl", opts, &p, &err);
  EXPECT(rc == BK_OK, "build with '%s': %s", opts, err.msg);
  if (p) {
    /* a cached program must still give a working kernel */
    cl_int e;
    cl_kernel k = clCreateKernel(p, "ior_gradient", &e);
    EXPECT(e == CL_SUCCESS, "kernel from %s program: %s", cl->stats.last_hit ? "cached" : "fresh",
          clh_error_name(e));
    if (k) clReleaseKernel(k);
    clReleaseProgram(p);
  }
  return rc;
}

static int test_cache(const char *base) {
  clh_context_t cl;
  char dir[4200], parent[4096], file[4400];
  if (!init_or_die(&cl, NULL)) return 1;
  /* a nested, not yet existing directory: the cache makes it (mkdir -p) */
  snprintf(parent, sizeof parent, "%s/clhost_cache_%ld", base, (long)getpid());
  snprintf(dir, sizeof dir, "%s/nested", parent);
  setenv("BAKER_CACHE_DIR", dir, 1);
  unsetenv("BAKER_NO_CACHE");

  build_once(&cl, "-DIOR_TEST_VARIANT=1");
  EXPECT(cl.stats.cache_misses == 1 && cl.stats.source_builds == 1 && !cl.stats.last_hit,
        "first build: misses %u builds %u", cl.stats.cache_misses, cl.stats.source_builds);
  double cold = cl.stats.last_ms;
  uint64_t key1 = cl.stats.last_key;
  EXPECT(count_cache_files(dir, file, sizeof file) == 1, "no cache file in %s", dir);
  build_once(&cl, "-DIOR_TEST_VARIANT=1");
  EXPECT(cl.stats.cache_hits == 1 && cl.stats.last_hit && cl.stats.source_builds == 1,
        "second build should hit: hits %u", cl.stats.cache_hits);
  double warm = cl.stats.last_ms;
  build_once(&cl, "-DIOR_TEST_VARIANT=2");
  EXPECT(cl.stats.cache_misses == 2 && !cl.stats.last_hit && cl.stats.source_builds == 2,
        "changed -D should miss: misses %u", cl.stats.cache_misses);
  EXPECT(count_cache_files(dir, NULL, 0) == 2, "expected 2 cache files");
  printf("ior.cl build: %.1f ms from source, %.1f ms from the baker cache\n", cold, warm);

  /* a corrupt entry is ignored and rewritten, never fatal */
  snprintf(file, sizeof file, "%s/%016llx.clbin", dir, (unsigned long long)key1);
  FILE *f = fopen(file, "wb");
  EXPECT(f != NULL, "cannot open %s", file);
  if (f) {
    fputs("garbage", f);
    fclose(f);
  }
  unsigned builds = cl.stats.source_builds;
  build_once(&cl, "-DIOR_TEST_VARIANT=1");
  EXPECT(!cl.stats.last_hit && cl.stats.source_builds == builds + 1, "corrupt entry was used");
  build_once(&cl, "-DIOR_TEST_VARIANT=1");
  EXPECT(cl.stats.last_hit, "rewritten entry should hit");

  /* BAKER_NO_CACHE and an unusable directory: builds still succeed */
  setenv("BAKER_NO_CACHE", "1", 1);
  unsigned hits = cl.stats.cache_hits;
  build_once(&cl, "-DIOR_TEST_VARIANT=1");
  EXPECT(cl.stats.cache_hits == hits && !cl.stats.last_hit, "BAKER_NO_CACHE ignored");
  unsetenv("BAKER_NO_CACHE");
  setenv("BAKER_CACHE_DIR", "/proc/self/no/such/dir", 1);
  EXPECT(build_once(&cl, "-DIOR_TEST_VARIANT=3") == BK_OK, "unwritable cache made the build fail");

  clean_dir(dir);
  rmdir(parent);
  clh_release(&cl);
  return tu_failures;
}

/* --- build errors, device specs, no platform ---------------------------------- */

static int test_build_error(void) {
  clh_context_t cl;
  bk_error_t err = {0};
  cl_program p = NULL;
  if (!init_or_die(&cl, NULL)) return 1;
  setenv("BAKER_NO_CACHE", "1", 1);
  const char *bad = "#include \"shared.h\"\n"
                    "__kernel void broken(__global float *x) {\n"
                    "  x[0] = undeclared_thing + 1.0f;\n"
                    "}\n";
  int rc = clh_build_source(&cl, "kernels/broken_test.cl", bad, "-DBROKEN_OPT=7", &p, &err);
  EXPECT(rc == BK_ERR_RUNTIME && err.code == BK_ERR_RUNTIME && p == NULL, "rc %d", rc);
  EXPECT(strstr(err.msg, "kernels/broken_test.cl") && strstr(err.msg, "undeclared_thing") &&
            strstr(err.msg, "-DBROKEN_OPT=7") && strstr(err.msg, "build log"),
        "message lacks file, log or options:\n%s", err.msg);
  /* #line markers make the log point at the real line of the real file */
  EXPECT(strstr(err.msg, "broken_test.cl:3:"), "log does not cite broken_test.cl:3:\n%s", err.msg);
  printf("build error message:\n%s\n", err.msg);
  rc = clh_build(&cl, "nosuch.cl", "", &p, &err);
  EXPECT(rc == BK_ERR_RUNTIME && strstr(err.msg, "kernels/nosuch.cl"), "%s", err.msg);
  clh_release(&cl);
  return tu_failures;
}

static int test_device_spec(void) {
  clh_context_t cl;
  bk_error_t err = {0};
  int rc = clh_init(&cl, "no-such-device-xyz", &err);
  EXPECT(rc == BK_ERR_INPUT && err.code == BK_ERR_INPUT, "rc %d", rc);
  EXPECT(strstr(err.msg, "no-such-device-xyz") && strstr(err.msg, "0:0") &&
            strstr(err.msg, "Portable Computing Language"), "no device list:\n%s", err.msg);
  printf("%s\n", err.msg);
  EXPECT(clh_init(&cl, "7:3", &err) == BK_ERR_INPUT, "7:3 accepted");
  clh_release(&cl);
  const char *good[] = {NULL, "", "0:0", "pocl", "PORTABLE computing", "cpu"};
  for (int i = 0; i < 6; i++) {
    rc = clh_init(&cl, good[i], &err);
    EXPECT(rc == BK_OK, "spec '%s': %s", good[i] ? good[i] : "(null)", err.msg);
    if (rc == BK_OK) {
      EXPECT(strstr(cl.platform_name, "Portable Computing Language") && cl.is_cpu &&
                cl.compute_units > 0 && cl.global_mem > 0 && cl.max_alloc > 0 &&
                cl.has_int64_atomics && cl.driver_version[0] && cl.context && cl.queue,
            "context fields for '%s'", good[i] ? good[i] : "(null)");
    }
    clh_release(&cl);
    clh_release(&cl); /* twice is harmless */
  }
  clh_release(NULL);
  clh_list_devices(stdout);
  return tu_failures;
}

static int test_no_platform(void) {
  clh_context_t cl;
  bk_error_t err = {0};
  int rc = clh_init(&cl, NULL, &err);
  EXPECT(rc == BK_ERR_RUNTIME, "rc %d (%s)", rc, err.msg);
  EXPECT(strstr(err.msg, "no OpenCL platform found") && strstr(err.msg, "pocl-opencl-icd") &&
            strstr(err.msg, "clinfo"), "message: %s", err.msg);
  printf("%s\n", err.msg);
  clh_release(&cl);
  return tu_failures;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: %s errors|gradient|cache DIR|build_error|device_spec|no_platform\n",
            argv[0]);
    return 2;
  }
  const char *t = argv[1];
  int f;
  if (!strcmp(t, "errors")) f = test_errors();
  else if (!strcmp(t, "gradient")) f = test_gradient();
  else if (!strcmp(t, "cache") && argc > 2) f = test_cache(argv[2]);
  else if (!strcmp(t, "build_error")) f = test_build_error();
  else if (!strcmp(t, "device_spec")) f = test_device_spec();
  else if (!strcmp(t, "no_platform")) f = test_no_platform();
  else {
    fprintf(stderr, "unknown test %s\n", t);
    return 2;
  }
  if (f) fprintf(stderr, "%s: %d check(s) failed\n", t, f);
  else printf("%s: ok\n", t);
  return f ? 1 : 0;
}
