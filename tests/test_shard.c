/* test_shard.c: photon shards (`baker bake --shard I/N`) and `baker merge`
 * (issue 14 item 3), through the commands themselves, on the sphere scene at
 * 24^3 with a photon count that no shard count divides and that crosses the
 * march's launch chunks (65536).
 *
 *  reference  1, 2 and 5 shards merged (in reverse order) against the
 *             single bake with the same seed: every grid bit for bit; the
 *             metadata counts all photons and records the shards
 *  adaptive   3 shards: with --no-filter bit for bit against the single
 *             adaptive bake (the sums, counts and weights are exact); with
 *             the filter (the merge filters on the host, the bake on
 *             OpenCL) within 1e-5 relative L2
 *  refuse     shards of another seed, a repeated shard, a missing one, a
 *             file that is no shard, the output among the inputs: exit 2
 *             and no output file
 *  range      shard_range: contiguous, disjoint, complete, balanced
 *  anisotropic medium.g 0.6: 2 shards merged against the single bake,
 *             radiance_flux, radiance_uncollided, radiance_flux_uncollided
 *             and phase_g too, bit for bit
 *  mixed      shards on the host C path and on OpenCL merged against the
 *             single OpenCL bake, bit for bit */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bake.h"
#include "merge.h"
#include "shard.h"
#include "vdbio.h"
#include "test_util.h"

#define PHOTONS "150001"

static const char *scene_dir, *out_dir;
static char scene_path[1024];

static char *path_of(const char *name) {
  static char buf[64][1024]; /* a ring: the callers keep a few at once */
  static int next;
  char *p = buf[next++ % 64];
  snprintf(p, 1024, "%s/%s", out_dir, name);
  return p;
}

/* baker bake SCENE -o OUT --resolution 24 --photons N -q --force [extra...] */
static int bake(const char *out, const char *photons, const char *const *extra, int n_extra) {
  char *argv[32] = {"bake", scene_path, "-o", (char *)out, "--resolution", "24", "--photons",
                    (char *)photons, "-q", "--force"};
  int argc = 10;
  for (int i = 0; i < n_extra; i++) argv[argc++] = (char *)extra[i];
  return bake_main(argc, argv);
}

static int merge(const char *out, char **shards, int n) {
  char *argv[32] = {"merge", "-o", (char *)out, "-q"};
  int argc = 4;
  for (int i = 0; i < n; i++) argv[argc++] = shards[i];
  return merge_main(argc, argv);
}

static grid_dims_t dims_of(const char *path) {
  vdbio_dense_t d;
  bk_error_t err;
  memset(&err, 0, sizeof err);
  REQUIRE(vdbio_read_dense(path, "ior", 0, &d, &err) == BK_OK, "%s", err.msg);
  grid_dims_t g = {d.nx, d.ny, d.nz, 1.0f, {0, 0, 0}};
  vdbio_dense_free(&d);
  return g;
}

static float *read_grid(const char *path, const char *name, const grid_dims_t *d, int ch) {
  bk_error_t err;
  memset(&err, 0, sizeof err);
  float *a = calloc(grid_count(d) * (size_t)ch, sizeof(float));
  REQUIRE(a, "out of memory");
  REQUIRE(vdbio_read_box(path, name, d, ch, a, &err) == BK_OK, "%s", err.msg);
  return a;
}

/* Grid `name` of a and b: bit for bit (tol 0), or within tol relative L2. */
static void compare(const char *a, const char *b, const char *name, int ch, double tol) {
  grid_dims_t d = dims_of(a);
  float *x = read_grid(a, name, &d, ch), *y = read_grid(b, name, &d, ch);
  size_t n = grid_count(&d) * (size_t)ch, differ = 0, nonzero = 0;
  for (size_t i = 0; i < n; i++) {
    differ += memcmp(&x[i], &y[i], sizeof(float)) != 0;
    nonzero += y[i] != 0.0f;
  }
  double e = tu_rel_l2(x, y, n);
  printf("  %-19s %zu of %zu values differ, relative L2 %.3g, %zu non-zero\n", name, differ, n,
         e, nonzero);
  EXPECT(nonzero > 100, "%s: grid %s is almost empty (%zu non-zero): nothing was compared", b,
         name, nonzero);
  if (tol == 0.0)
    EXPECT(differ == 0, "%s vs %s: grid %s differs in %zu values", a, b, name, differ);
  else
    EXPECT(e <= tol, "%s vs %s: grid %s relative L2 %.3g > %.3g", a, b, name, e, tol);
  free(x);
  free(y);
}

static void expect_meta(const char *path, const char *key, const char *want) {
  char got[4096];
  bk_error_t err;
  memset(&err, 0, sizeof err);
  REQUIRE(vdbio_read_meta(path, key, got, sizeof got, &err) == BK_OK, "%s", err.msg);
  EXPECT(!strcmp(got, want), "%s: %s is '%s', expected '%s'", path, key, got, want);
}

/* Bakes shards 1..n of n (with extra options) and merges them in reverse. */
static void shard_and_merge(const char *tag, int n, const char *photons, const char *const *extra,
                            int n_extra, const char *merged) {
  char *shards[16], spec[32], name[64];
  const char *opts[16];
  for (int i = 0; i < n_extra; i++) opts[i] = extra[i];
  opts[n_extra] = "--shard";
  opts[n_extra + 1] = spec;
  for (int i = 1; i <= n; i++) {
    snprintf(spec, sizeof spec, "%d/%d", i, n);
    snprintf(name, sizeof name, "%s_%d_of_%d.vdb", tag, i, n);
    shards[n - i] = strdup(path_of(name));
    REQUIRE(bake(shards[n - i], photons, opts, n_extra + 2) == 0, "bake --shard %s failed", spec);
  }
  REQUIRE(merge(merged, shards, n) == 0, "merge of %d shards failed", n);
  for (int i = 0; i < n; i++) free(shards[i]);
}

static int test_reference(void) {
  const char *single = path_of("ref_single.vdb");
  REQUIRE(bake(single, PHOTONS, NULL, 0) == 0, "single bake failed");
  const char *grids[] = {"radiance", "emission", "ior", "extinction", "scattering", "density"};
  const int ch[] = {3, 3, 1, 1, 1, 1};
  const int counts[] = {1, 2, 5};
  for (int c = 0; c < 3; c++) {
    char name[64], want[16], settings[600];
    snprintf(name, sizeof name, "ref_merged_%d.vdb", counts[c]);
    const char *merged = path_of(name);
    shard_and_merge("ref", counts[c], PHOTONS, NULL, 0, merged);
    printf("reference, %d shard(s) merged vs the single bake:\n", counts[c]);
    for (int g = 0; g < 6; g++) compare(merged, single, grids[g], ch[g], 0.0);
    snprintf(want, sizeof want, "%d", counts[c]);
    expect_meta(merged, "merged_shard_count", want);
    expect_meta(merged, "photon_count", PHOTONS);
    bk_error_t err;
    memset(&err, 0, sizeof err);
    REQUIRE(vdbio_read_meta(single, "bake_settings", settings, sizeof settings, &err) == 0, "%s",
            err.msg);
    expect_meta(merged, "bake_settings", settings);
  }
  return tu_failures ? 1 : 0;
}

static int test_anisotropic(void) {
  const char *single = path_of("aniso_single.vdb"), *merged = path_of("aniso_merged_2.vdb");
  const char *const g[] = {"--set", "medium.g=0.6"};
  REQUIRE(bake(single, PHOTONS, g, 2) == 0, "single bake failed");
  shard_and_merge("aniso", 2, PHOTONS, g, 2, merged);
  printf("anisotropic (g 0.6), 2 shards merged vs the single bake:\n");
  compare(merged, single, "radiance", 3, 0.0);
  compare(merged, single, "radiance_flux", 3, 0.0);
  compare(merged, single, "radiance_uncollided", 1, 0.0);
  compare(merged, single, "radiance_flux_uncollided", 3, 0.0);
  compare(merged, single, "phase_g", 1, 0.0);
  return tu_failures ? 1 : 0;
}

/* Shards 1 and 3 of 3 on the host C path, 2 on OpenCL, against the single
 * OpenCL bake: a farm may mix CPU and GPU nodes (the paths round alike,
 * docs/gpu.md, and slot i traces the same photon on each). */
static int test_mixed(void) {
  const char *single = path_of("mixed_single.vdb"), *merged = path_of("mixed_merged.vdb");
  REQUIRE(bake(single, PHOTONS, NULL, 0) == 0, "single bake failed");
  char *shards[3];
  for (int i = 1; i <= 3; i++) {
    char spec[8], name[64];
    snprintf(spec, sizeof spec, "%d/3", i);
    snprintf(name, sizeof name, "mixed_%d_of_3.vdb", i);
    shards[i - 1] = strdup(path_of(name));
    const char *opts[] = {"--shard", spec, "--host"};
    REQUIRE(bake(shards[i - 1], PHOTONS, opts, i == 2 ? 2 : 3) == 0, "bake --shard %s failed",
            spec);
  }
  REQUIRE(merge(merged, shards, 3) == 0, "merge of host and OpenCL shards failed");
  printf("shards 1, 3 on the host and 2 on OpenCL, merged vs the single OpenCL bake:\n");
  compare(merged, single, "radiance", 3, 0.0);
  compare(merged, single, "emission", 3, 0.0);
  for (int i = 0; i < 3; i++) free(shards[i]);
  return tu_failures ? 1 : 0;
}

static int test_adaptive(void) {
  const char *nf[] = {"--mode", "adaptive", "--no-filter"}, *f[] = {"--mode", "adaptive"};
  const char *single_nf = path_of("ad_single_nofilter.vdb"), *single = path_of("ad_single.vdb");
  const char *merged_nf = path_of("ad_merged_nofilter.vdb"), *merged = path_of("ad_merged.vdb");
  REQUIRE(bake(single_nf, "60001", nf, 3) == 0, "single adaptive bake failed");
  REQUIRE(bake(single, "60001", f, 2) == 0, "single adaptive bake failed");
  shard_and_merge("adnf", 3, "60001", nf, 3, merged_nf);
  shard_and_merge("ad", 3, "60001", f, 2, merged);
  printf("adaptive --no-filter, 3 shards merged vs the single bake:\n");
  compare(merged_nf, single_nf, "radiance", 3, 0.0);
  compare(merged_nf, single_nf, "photon_count", 1, 0.0);
  compare(merged_nf, single_nf, "photon_weight", 1, 0.0);
  printf("adaptive with the filter (merge on the host, bake on OpenCL):\n");
  compare(merged, single, "radiance", 3, 1e-5);
  compare(merged, single, "photon_count", 1, 0.0);
  expect_meta(merged, "adaptive_filter", "on");
  expect_meta(merged_nf, "adaptive_filter", "off");
  return tu_failures ? 1 : 0;
}

/* merge of these files must fail with 2 and leave no output */
static void expect_refused(const char *why, char **files, int n) {
  const char *out = path_of("refused.vdb");
  unlink(out);
  int rc = merge(out, files, n);
  printf("refuse %-34s exit %d\n", why, rc);
  EXPECT(rc == 2, "%s: merge exited %d, expected 2", why, rc);
  EXPECT(access(out, F_OK) != 0, "%s: the refused merge left %s", why, out);
}

static int test_refuse(void) {
  const char *s1[] = {"--shard", "1/2"}, *s2[] = {"--shard", "2/2"};
  const char *s2b[] = {"--shard", "2/2", "--seed", "7"}, *s3[] = {"--shard", "2/3"};
  char *a = strdup(path_of("rf_1_of_2.vdb")), *b = strdup(path_of("rf_2_of_2.vdb"));
  char *c = strdup(path_of("rf_2_of_2_seed7.vdb")), *d = strdup(path_of("rf_2_of_3.vdb"));
  char *whole = strdup(path_of("rf_whole.vdb"));
  REQUIRE(bake(a, "20000", s1, 2) == 0 && bake(b, "20000", s2, 2) == 0 &&
              bake(c, "20000", s2b, 4) == 0 && bake(d, "20000", s3, 2) == 0 &&
              bake(whole, "20000", NULL, 0) == 0,
          "bakes failed");
  char *other_seed[] = {a, c}, *twice[] = {a, a}, *missing[] = {a}, *mixed_n[] = {a, d};
  char *not_shard[] = {a, whole};
  expect_refused("another seed", other_seed, 2);
  expect_refused("a shard twice", twice, 2);
  expect_refused("a missing shard", missing, 1);
  expect_refused("shards of 2 and of 3", mixed_n, 2);
  expect_refused("a file that is no shard", not_shard, 2);
  char *pair[] = {a, b};
  int rc = merge(b, pair, 2);
  printf("refuse %-34s exit %d\n", "the output among the shards", rc);
  EXPECT(rc == 2, "merge onto one of its shards exited %d", rc);
  EXPECT(merge(path_of("rf_ok.vdb"), pair, 2) == 0, "the good pair did not merge");
  free(a), free(b), free(c), free(d), free(whole);
  return tu_failures ? 1 : 0;
}

static int test_range(void) {
  const uint64_t totals[] = {0, 1, 7, 150001, 1000000007ull, 5000000000000ull};
  for (size_t t = 0; t < sizeof totals / sizeof totals[0]; t++)
    for (int n = 1; n <= 13; n++) {
      uint64_t next = 0, lo = UINT64_MAX, hi = 0;
      for (int i = 1; i <= n; i++) {
        uint64_t f, l;
        shard_range(totals[t], i, n, &f, &l);
        EXPECT(f == next && l >= f, "%llu photons, shard %d/%d: [%llu, %llu) after %llu",
               (unsigned long long)totals[t], i, n, (unsigned long long)f,
               (unsigned long long)l, (unsigned long long)next);
        next = l;
        lo = l - f < lo ? l - f : lo;
        hi = l - f > hi ? l - f : hi;
      }
      EXPECT(next == totals[t] && hi - lo <= 1, "%llu photons in %d shards: end %llu, sizes "
             "%llu..%llu", (unsigned long long)totals[t], n, (unsigned long long)next,
             (unsigned long long)lo, (unsigned long long)hi);
    }
  printf("range: contiguous, complete, sizes within 1\n");
  return tu_failures ? 1 : 0;
}

int main(int argc, char **argv) {
  if (argc != 4) {
    fprintf(stderr, "usage: test_shard SCENE_DIR OUT_DIR "
                    "reference|adaptive|refuse|range|anisotropic|mixed\n");
    return 2;
  }
  scene_dir = argv[1];
  out_dir = argv[2];
  snprintf(scene_path, sizeof scene_path, "%s/sphere.json", scene_dir);
  const char *t = argv[3];
  if (!strcmp(t, "reference")) return test_reference();
  if (!strcmp(t, "adaptive")) return test_adaptive();
  if (!strcmp(t, "refuse")) return test_refuse();
  if (!strcmp(t, "range")) return test_range();
  if (!strcmp(t, "anisotropic")) return test_anisotropic();
  if (!strcmp(t, "mixed")) return test_mixed();
  fprintf(stderr, "unknown test '%s'\n", t);
  return 2;
}
