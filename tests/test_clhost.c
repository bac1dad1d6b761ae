/* test_clhost.c: the OpenCL host layer on PoCL.
 * Usage: test_clhost errors|cache DIR|build_error|device_spec|no_platform|copy */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "clcopy.h"
#include "clhost.h"
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

  s = clh_expand_source("view.cl", &err);
  EXPECT(s && strstr(s, "rc_field") && strstr(s, "view_march_pixel") &&
            !strstr(s, "#include \""), "view.cl expansion: %s", s ? "content" : err.msg);
  free(s);
  s = clh_expand_source("nosuch.cl", &err);
  EXPECT(s == NULL && err.code == BK_ERR_RUNTIME && strstr(err.msg, "kernels/nosuch.cl"), "%s",
        err.msg);
  free(s);
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
  int rc = clh_build(cl, "filter.cl", opts, &p, &err);
  EXPECT(rc == BK_OK, "build with '%s': %s", opts, err.msg);
  if (p) {
    /* a cached program must still give a working kernel */
    cl_int e;
    cl_kernel k = clCreateKernel(p, "ad_means", &e);
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

  build_once(&cl, "-DCACHE_TEST_VARIANT=1");
  EXPECT(cl.stats.cache_misses == 1 && cl.stats.source_builds == 1 && !cl.stats.last_hit,
        "first build: misses %u builds %u", cl.stats.cache_misses, cl.stats.source_builds);
  double cold = cl.stats.last_ms;
  uint64_t key1 = cl.stats.last_key;
  EXPECT(count_cache_files(dir, file, sizeof file) == 1, "no cache file in %s", dir);
  build_once(&cl, "-DCACHE_TEST_VARIANT=1");
  EXPECT(cl.stats.cache_hits == 1 && cl.stats.last_hit && cl.stats.source_builds == 1,
        "second build should hit: hits %u", cl.stats.cache_hits);
  double warm = cl.stats.last_ms;
  build_once(&cl, "-DCACHE_TEST_VARIANT=2");
  EXPECT(cl.stats.cache_misses == 2 && !cl.stats.last_hit && cl.stats.source_builds == 2,
        "changed -D should miss: misses %u", cl.stats.cache_misses);
  EXPECT(count_cache_files(dir, NULL, 0) == 2, "expected 2 cache files");
  printf("filter.cl build: %.1f ms from source, %.1f ms from the baker cache\n", cold, warm);

  /* a corrupt entry is ignored and rewritten, never fatal */
  snprintf(file, sizeof file, "%s/%016llx.clbin", dir, (unsigned long long)key1);
  FILE *f = fopen(file, "wb");
  EXPECT(f != NULL, "cannot open %s", file);
  if (f) {
    fputs("garbage", f);
    fclose(f);
  }
  unsigned builds = cl.stats.source_builds;
  build_once(&cl, "-DCACHE_TEST_VARIANT=1");
  EXPECT(!cl.stats.last_hit && cl.stats.source_builds == builds + 1, "corrupt entry was used");
  build_once(&cl, "-DCACHE_TEST_VARIANT=1");
  EXPECT(cl.stats.last_hit, "rewritten entry should hit");

  /* BAKER_NO_CACHE and an unusable directory: builds still succeed */
  setenv("BAKER_NO_CACHE", "1", 1);
  unsigned hits = cl.stats.cache_hits;
  build_once(&cl, "-DCACHE_TEST_VARIANT=1");
  EXPECT(cl.stats.cache_hits == hits && !cl.stats.last_hit, "BAKER_NO_CACHE ignored");
  unsetenv("BAKER_NO_CACHE");
  setenv("BAKER_CACHE_DIR", "/proc/self/no/such/dir", 1);
  EXPECT(build_once(&cl, "-DCACHE_TEST_VARIANT=3") == BK_OK, "unwritable cache made the build fail");

  /* a context that keeps its programs (a batch of frames, baker/frame_reuse.h)
   * builds each once: the second build touches neither compiler nor cache */
  setenv("BAKER_CACHE_DIR", dir, 1);
  cl.keep_programs = 1;
  build_once(&cl, "-DCACHE_TEST_VARIANT=4");
  unsigned misses = cl.stats.cache_misses, hits2 = cl.stats.cache_hits;
  builds = cl.stats.source_builds;
  build_once(&cl, "-DCACHE_TEST_VARIANT=4");
  EXPECT(cl.stats.kept_hits == 1 && cl.stats.last_hit == 2 && cl.stats.cache_misses == misses &&
             cl.stats.cache_hits == hits2 && cl.stats.source_builds == builds,
         "kept program: kept hits %u, last_hit %d", cl.stats.kept_hits, cl.stats.last_hit);
  build_once(&cl, "-DCACHE_TEST_VARIANT=5"); /* other options: another program */
  EXPECT(cl.stats.kept_hits == 1 && cl.stats.last_hit != 2, "other -D options took a kept program");

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

/* --- copy: large copies through the pinned stages (run with BAKER_CL_DISCRETE=1) */

/* One size: a patterned upload read back, then an upload of zeros (a fill)
 * over it read back. */
static void copy_round(clh_context_t *cl, size_t n) {
  bk_error_t err = {0};
  unsigned char *src = malloc(n), *dst = malloc(n);
  cl_int cerr = CL_SUCCESS;
  cl_mem b = clCreateBuffer(cl->context, CL_MEM_READ_WRITE, n, NULL, &cerr);
  REQUIRE(src && dst && cerr == CL_SUCCESS, "%zu bytes: allocations", n);
  for (size_t i = 0; i < n; i++) src[i] = (unsigned char)((i * 2654435761u) >> 13 | 1);
  memset(dst, 0xab, n);
  EXPECT(clc_upload(cl, b, n, src, &err) == BK_OK, "%zu: upload: %s", n, err.msg);
  EXPECT(clc_read(cl, b, n, dst, &err) == BK_OK, "%zu: read: %s", n, err.msg);
  EXPECT(memcmp(src, dst, n) == 0, "%zu bytes: read back differs", n);
  memset(src, 0, n);
  EXPECT(clc_upload(cl, b, n, src, &err) == BK_OK, "%zu: zero upload: %s", n, err.msg);
  EXPECT(clc_read(cl, b, n, dst, &err) == BK_OK, "%zu: read: %s", n, err.msg);
  EXPECT(memcmp(src, dst, n) == 0, "%zu bytes: zeros read back differ", n);
  clReleaseMemObject(b);
  free(src);
  free(dst);
}

static int test_copy(void) {
  clh_context_t cl;
  memset(&cl, 0, sizeof cl);
  if (!init_or_die(&cl, NULL)) return 1;
  EXPECT(!cl.is_cpu, "BAKER_CL_DISCRETE=1 should make the device a discrete one");
  /* straight; 3 stages with a byte tail (fill of 1-byte pattern); 4 with a half one */
  const size_t sizes[] = {((size_t)1 << 20) + 8, 2 * CLC_STAGE + 13, 3 * CLC_STAGE + CLC_STAGE / 2};
  for (int i = 0; i < 3; i++) copy_round(&cl, sizes[i]);
  EXPECT(cl.stage_map[0] && cl.stage_map[1], "the staged copies made no stages");
  clh_release(&cl);
  return tu_failures;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: %s errors|cache DIR|build_error|device_spec|no_platform|copy\n",
            argv[0]);
    return 2;
  }
  const char *t = argv[1];
  int f;
  if (!strcmp(t, "errors")) f = test_errors();
  else if (!strcmp(t, "cache") && argc > 2) f = test_cache(argv[2]);
  else if (!strcmp(t, "build_error")) f = test_build_error();
  else if (!strcmp(t, "device_spec")) f = test_device_spec();
  else if (!strcmp(t, "no_platform")) f = test_no_platform();
  else if (!strcmp(t, "copy")) f = test_copy();
  else {
    fprintf(stderr, "unknown test %s\n", t);
    return 2;
  }
  if (f) fprintf(stderr, "%s: %d check(s) failed\n", t, f);
  else printf("%s: ok\n", t);
  return f ? 1 : 0;
}
