/* test_adaptive.c: the adaptive pipeline's parts that do not need the march.
 * Usage: test_adaptive cells|warp|pdf|thresholds|chain|filter|filter_cl|fixed|device
 *  cells      light-domain cells and origin masks on the host
 *  warp       the PDF warp: histogram, normalisation, E[f/pdf] = ∫f, inverse
 *  pdf        ad_build_pdf: floor, importance spreading, uniform fallback
 *  thresholds automatic thresholds select edges and shadows, not the smooth part
 *  chain      pilot origins -> selection -> PDF -> weighted phase 2 on a toy
 *             light: unbiased, photons where the PDF points
 *  filter     the reconstruction filter on a noisy fog with a caustic step,
 *             against a brute-force evaluation of its definition
 *  filter_cl  kernels/filter.cl against the host path and the brute force
 *  fixed      the error estimate's filter at given radii on the even lattice
 *             (ad_filter_fixed_lattice) against its definition, odd sizes
 *  device     the warp and origin marking of kernels/adaptive_filter.h on OpenCL */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "adaptive.h"
#include "clhost.h"
#include "error_est.h"
#include "kernels/light_sample.h" /* ph_radical_inverse2: the march's own Hammersley */
#include "scene.h"
#include "test_util.h"

/* Fixed-seed generator: xorshift64*, and Gaussians by Box–Muller. */
static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double rng_uniform(void) {
  rng_state ^= rng_state >> 12;
  rng_state ^= rng_state << 25;
  rng_state ^= rng_state >> 27;
  return (double)((rng_state * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}
static double rng_gauss(void) {
  double u = rng_uniform(), v = rng_uniform();
  if (u < 1e-300) u = 1e-300;
  return sqrt(-2.0 * log(u)) * cos(6.283185307179586 * v);
}

static grid_dims_t cube_dims(int n) {
  grid_dims_t d;
  d.nx = d.ny = d.nz = n;
  d.voxel_size = 1.0f / (float)n;
  d.origin[0] = d.origin[1] = d.origin[2] = 0.0f;
  return d;
}

/* --- cells ------------------------------------------------------------------- */

static int test_cells(void) {
  EXPECT(ld_cell_of(0.0f, 0.0f) == 0, "origin");
  EXPECT(ld_cell_of(0.125f, 0.0f) == 1, "%d", ld_cell_of(0.125f, 0.0f));
  EXPECT(ld_cell_of(0.12499999f, 0.0f) == 0, "just below an edge");
  EXPECT(ld_cell_of(0.0f, 0.125f) == LD_CELLS_X, "%d", ld_cell_of(0.0f, 0.125f));
  EXPECT(ld_cell_of(LD_ONE_BELOW, LD_ONE_BELOW) == LD_CELLS - 1, "top corner");
  EXPECT(ld_cell_of(1.0f, 1.0f) == LD_CELLS - 1 && ld_cell_of(-0.5f, -1e-9f) == 0, "clamped");
  EXPECT(ld_cell_of(0.3f, 0.6f) == 2 + 8 * 4, "%d", ld_cell_of(0.3f, 0.6f));
  /* every cell is hit by exactly 1/64 of a 64x64 lattice of cell centres */
  int hits[LD_CELLS] = {0};
  for (int j = 0; j < 64; j++)
    for (int i = 0; i < 64; i++) hits[ld_cell_of((i + 0.5f) / 64.0f, (j + 0.5f) / 64.0f)]++;
  for (int c = 0; c < LD_CELLS; c++) EXPECT(hits[c] == 64, "cell %d hit %d times", c, hits[c]);
  EXPECT(ld_cell_bit(63) == 0x8000000000000000ull && ld_cell_bit(0) == 1ull, "bits");
  /* origin masks: light-major blocks, bits OR-ed, idempotent */
  uint64_t masks[2 * 10] = {0};
  ld_origin_mark(masks, ld_origin_index(3, 1, 10), 5);
  ld_origin_mark(masks, ld_origin_index(3, 1, 10), 5);
  ld_origin_mark(masks, ld_origin_index(3, 1, 10), 63);
  ld_origin_mark(masks, ld_origin_index(3, 0, 10), 0);
  EXPECT(masks[13] == ((1ull << 5) | (1ull << 63)) && masks[3] == 1ull, "%llx %llx",
        (unsigned long long)masks[13], (unsigned long long)masks[3]);
  int other = 0;
  for (int i = 0; i < 20; i++) other += i != 3 && i != 13 && masks[i] != 0;
  EXPECT(other == 0, "stray bits in %d masks", other);
  printf("cells: ok\n");
  return tu_failures;
}

/* --- warp -------------------------------------------------------------------- */

/* Checks one table: monotone CDFs, normalisation, histogram of warped
 * Hammersley points, E[f/pdf] = ∫f and the inverse. `expect` holds the
 * analytic cell densities. */
static void check_table(const char *name, const float *table, int nx, int ny,
                        const double *expect) {
  int cells = nx * ny;
  for (int r = 0; r < ny; r++) EXPECT(table[r + 1] >= table[r], "%s: marginal not monotone", name);
  EXPECT(table[0] == 0.0f && table[ny] == 1.0f, "%s: marginal ends", name);
  for (int r = 0; r < ny; r++) {
    const float *c = table + (ny + 1) + r * (nx + 1);
    EXPECT(c[0] == 0.0f && c[nx] == 1.0f, "%s: row %d ends", name, r);
    for (int i = 0; i < nx; i++) EXPECT(c[i + 1] >= c[i], "%s: row %d not monotone", name, r);
  }
  /* the density integrates to 1 and matches the analytic one */
  double integral = 0.0, worst = 0.0;
  for (int r = 0; r < ny; r++)
    for (int c = 0; c < nx; c++) {
      float p = ld_pdf_eval(table, nx, ny, (c + 0.5f) / nx, (r + 0.5f) / ny);
      integral += p / cells;
      double e = fabs(p - expect[c + nx * r]) / expect[c + nx * r];
      if (e > worst) worst = e;
    }
  EXPECT(fabs(integral - 1.0) < 1e-5, "%s: pdf integrates to %.8f", name, integral);
  EXPECT(worst < 1e-5, "%s: cell density off by %.2e relative", name, worst);

  enum { N = 65536 };
  int *hist = calloc((size_t)cells, sizeof(int));
  double est_a = 0.0, est_b = 0.0, worst_inv = 0.0;
  int outside = 0, wrong_cell = 0, wrong_pdf = 0;
  for (uint32_t i = 0; i < N; i++) {
    float ua = (float)i / (float)N, ub = ph_radical_inverse2(i);
    ld_sample s = ld_pdf_warp(table, nx, ny, ua, ub);
    if (!(s.x >= 0.0f && s.x < 1.0f && s.y >= 0.0f && s.y < 1.0f)) outside++;
    int col = (int)floorf(s.x * nx), row = (int)floorf(s.y * ny);
    if (col + nx * row != s.cell) wrong_cell++;
    if (s.pdf != ld_pdf_eval(table, nx, ny, s.x, s.y)) wrong_pdf++;
    hist[s.cell]++;
    /* two test functions with known integrals over [0,1)^2 */
    est_a += exp(s.x) * (1.0 + s.y * s.y) / s.pdf;            /* (e - 1) 4/3 */
    est_b += (1.0 + cos(6.283185307179586 * s.x) * s.y) / s.pdf; /* 1 */
    float ia, ib;
    ld_pdf_unwarp(table, nx, ny, s.x, s.y, &ia, &ib);
    double e = fmax(fabs(ia - ua), fabs(ib - ub));
    if (e > worst_inv) worst_inv = e;
  }
  est_a /= N;
  est_b /= N;
  EXPECT(outside == 0, "%s: %d warped points outside [0,1)^2", name, outside);
  EXPECT(wrong_cell == 0, "%s: %d points outside the cell the warp reports", name, wrong_cell);
  EXPECT(wrong_pdf == 0, "%s: %d pdfs differ from ld_pdf_eval", name, wrong_pdf);
  double worst_hist = 0.0;
  for (int c = 0; c < cells; c++) {
    double want = expect[c] / cells * N;
    double dev = fabs(hist[c] - want);
    if (dev / want > worst_hist) worst_hist = dev / want;
    EXPECT(dev <= 0.01 * want + 2.0, "%s: cell %d holds %d points, expected %.1f", name, c,
          hist[c], want);
  }
  double ia = (exp(1.0) - 1.0) * 4.0 / 3.0;
  EXPECT(fabs(est_a - ia) / ia < 1e-3, "%s: E[f/pdf] = %.6f, integral %.6f", name, est_a, ia);
  EXPECT(fabs(est_b - 1.0) < 1e-3, "%s: E[g/pdf] = %.6f, integral 1", name, est_b);
  EXPECT(worst_inv < 2e-6, "%s: unwarp(warp(u)) - u up to %.2e", name, worst_inv);
  printf("warp %s: histogram within %.3f%%, E[f/pdf] rel err %.2e and %.2e, inverse %.1e\n", name,
         100.0 * worst_hist, fabs(est_a - ia) / ia, fabs(est_b - 1.0), worst_inv);
  free(hist);
}

static int test_warp(void) {
  bk_error_t err = {0};
  /* 8x8: a hot spot, a stripe, and cells with no weight (they keep the floor) */
  double w[LD_CELLS];
  for (int c = 0; c < LD_CELLS; c++) {
    int cx = c % 8, cy = c / 8;
    w[c] = (cy % 3 == 0) ? 0.0 : (double)(cx + 1);
  }
  w[2 + 8 * 5] += 200.0;
  const float floor_f = 0.1f;
  float table[LD_TABLE_FLOATS(8, 8)], cell_pdf[LD_CELLS];
  EXPECT(ad_pdf_from_weights(w, 8, 8, floor_f, table, cell_pdf, &err) == BK_OK, "%s", err.msg);
  double total = 0.0, expect[LD_CELLS];
  for (int c = 0; c < LD_CELLS; c++) total += w[c];
  for (int c = 0; c < LD_CELLS; c++) expect[c] = floor_f + (1.0 - floor_f) * LD_CELLS * w[c] / total;
  check_table("8x8", table, 8, 8, expect);
  for (int c = 0; c < LD_CELLS; c++)
    EXPECT(cell_pdf[c] >= floor_f * (1.0f - 1e-5f), "cell %d pdf %g below the floor", c,
          (double)cell_pdf[c]);

  /* another shape: 5 x 3 cells, smooth weights */
  double w2[15], e2[15], t2 = 0.0;
  for (int c = 0; c < 15; c++) t2 += (w2[c] = 1.0 + (c % 5) * (c / 5) + (c == 7 ? 9.0 : 0.0));
  for (int c = 0; c < 15; c++) e2[c] = 0.3 + 0.7 * 15.0 * w2[c] / t2;
  float table2[LD_TABLE_FLOATS(5, 3)];
  EXPECT(ad_pdf_from_weights(w2, 5, 3, 0.3f, table2, NULL, &err) == BK_OK, "%s", err.msg);
  check_table("5x3", table2, 5, 3, e2);

  /* no weight anywhere: uniform, and the warp is the identity */
  double zero[LD_CELLS] = {0}, ones[LD_CELLS];
  for (int c = 0; c < LD_CELLS; c++) ones[c] = 1.0;
  EXPECT(ad_pdf_from_weights(zero, 8, 8, 0.5f, table, NULL, &err) == BK_OK, "%s", err.msg);
  check_table("uniform", table, 8, 8, ones);
  double worst = 0.0;
  for (uint32_t i = 0; i < 4096; i++) {
    float ua = i / 4096.0f, ub = ph_radical_inverse2(i);
    ld_sample s = ld_pdf_warp(table, 8, 8, ua, ub);
    worst = fmax(worst, fmax(fabs(s.x - ua), fabs(s.y - ub)));
    EXPECT(s.pdf == 1.0f, "uniform pdf %g", (double)s.pdf);
  }
  EXPECT(worst < 1e-6, "uniform warp moves points by %.2e", worst);
  /* monotone in each coordinate */
  EXPECT(ad_pdf_from_weights(w, 8, 8, floor_f, table, NULL, &err) == BK_OK, "%s", err.msg);
  int bad = 0;
  for (int a = 0; a < 16; a++) {
    float prev = -1.0f;
    for (int b = 0; b < 1000; b++) {
      ld_sample s = ld_pdf_warp(table, 8, 8, (a + 0.5f) / 16.0f, b / 1000.0f);
      bad += s.y < prev;
      prev = s.y;
    }
  }
  EXPECT(bad == 0, "warp not monotone in b (%d)", bad);
  /* extremes stay inside */
  ld_sample s = ld_pdf_warp(table, 8, 8, 1.0f, 1.0f);
  EXPECT(s.x < 1.0f && s.y < 1.0f && s.cell == LD_CELLS - 1, "u = 1 gives (%g, %g) cell %d",
        (double)s.x, (double)s.y, s.cell);
  s = ld_pdf_warp(table, 8, 8, 0.0f, 0.0f);
  EXPECT(s.x == 0.0f && s.y == 0.0f && s.cell == 0, "u = 0 gives (%g, %g)", (double)s.x,
        (double)s.y);
  /* bad input */
  EXPECT(ad_pdf_from_weights(w, 8, 8, 0.0f, table, NULL, &err) == BK_ERR_INPUT &&
            strstr(err.msg, "floor"), "floor 0: %s", err.msg);
  w[3] = -1.0;
  EXPECT(ad_pdf_from_weights(w, 8, 8, 0.5f, table, NULL, &err) == BK_ERR_RUNTIME &&
            strstr(err.msg, "cell 3"), "negative weight: %s", err.msg);
  return tu_failures;
}

/* --- pdf from origin masks --------------------------------------------------- */

static int test_pdf(void) {
  bk_error_t err = {0};
  enum { V = 960 }; /* 192 selected voxels: each left cell used 12 times */
  uint64_t *masks = calloc(V, sizeof(uint64_t));
  uint8_t *sel = calloc(V, 1);
  ad_pdf_t pdf;
  /* selected voxels reached only from the left half of the domain (cx < 4),
   * each from two cells; unselected voxels reached from everywhere */
  uint64_t left = 0;
  for (int c = 0; c < LD_CELLS; c++)
    if (c % 8 < 4) left |= ld_cell_bit(c);
  int nsel = 0;
  for (int v = 0; v < V; v++) {
    if (v % 5 == 0) {
      int a = (v / 5) % 32, b = (v / 5 + 7) % 32; /* two left cells */
      int ca = (a % 4) + 8 * (a / 4), cb = (b % 4) + 8 * (b / 4);
      masks[v] = ld_cell_bit(ca) | ld_cell_bit(cb);
      sel[v] = AD_SEL_GRADIENT;
      nsel++;
    } else {
      masks[v] = ~0ull;
    }
  }
  const float f = 0.25f;
  EXPECT(ad_build_pdf(masks, sel, NULL, NULL, V, f, &pdf, &err) == BK_OK, "%s", err.msg);
  EXPECT(pdf.selected_reached == (size_t)nsel, "%zu selected with origins, expected %d",
        pdf.selected_reached, nsel);
  double imp = 0.0, integral = 0.0, lo = 1e9, hi = 0.0;
  for (int c = 0; c < LD_CELLS; c++) {
    imp += pdf.importance[c];
    integral += pdf.cell_pdf[c] / LD_CELLS;
    EXPECT(pdf.cell_pdf[c] >= f * (1.0f - 1e-5f), "cell %d pdf %g below the floor %g", c,
          (double)pdf.cell_pdf[c], (double)f);
    if (c % 8 >= 4) {
      EXPECT(fabs(pdf.cell_pdf[c] - f) < 1e-5, "right cell %d: pdf %g, expected the floor", c,
            (double)pdf.cell_pdf[c]);
    } else {
      lo = fmin(lo, pdf.cell_pdf[c]);
      hi = fmax(hi, pdf.cell_pdf[c]);
    }
  }
  /* each selected voxel spreads exactly 1; the 32 left cells share evenly
   * (every left cell is used the same number of times by construction) */
  EXPECT(fabs(imp - nsel) < 1e-9, "importance sums to %g, expected %d", imp, nsel);
  EXPECT(fabs(integral - 1.0) < 1e-5, "pdf integrates to %.7f", integral);
  double left_expect = f + (1.0 - f) * 2.0;
  EXPECT(fabs(lo - left_expect) < 1e-4 && fabs(hi - left_expect) < 1e-4,
        "left cells %g..%g, expected %g", lo, hi, left_expect);
  printf("pdf: left cells %.4f (expected %.4f), right cells at the floor %.2f\n", lo, left_expect,
         (double)f);

  /* a single cell reaching the only selected voxel: that cell gets the rest */
  memset(sel, 0, V);
  memset(masks, 0, V * sizeof(uint64_t));
  masks[17] = ld_cell_bit(42);
  sel[17] = AD_SEL_SHADOW;
  sel[18] = AD_SEL_SHADOW; /* selected but never reached: no origin, no effect */
  EXPECT(ad_build_pdf(masks, sel, NULL, NULL, V, f, &pdf, &err) == BK_OK, "%s", err.msg);
  EXPECT(fabs(pdf.cell_pdf[42] - (f + (1.0f - f) * LD_CELLS)) < 1e-3, "hot cell %g",
        (double)pdf.cell_pdf[42]);
  EXPECT(fabs(pdf.cell_pdf[0] - f) < 1e-6, "cold cell %g", (double)pdf.cell_pdf[0]);
  EXPECT(pdf.selected_reached == 1, "%zu", pdf.selected_reached);
  ld_sample s = ld_pdf_warp(pdf.table, pdf.nx, pdf.ny, 0.5f, 0.5f);
  EXPECT(s.cell == 42, "the middle of the domain warps into the hot cell, got %d", s.cell);

  /* costs: two cells of equal importance, one whose photons do 4x the march
   * work: importance / sqrt(cost) gives it half the other's share above the
   * floor. ad_cell_costs: the mean work per photon; a cell without photons
   * gets the light's mean; at least 1. */
  uint64_t work[2 * LD_CELLS] = {0};
  work[3] = 10, work[LD_CELLS + 3] = 400; /* 40 per photon */
  work[9] = 30, work[LD_CELLS + 9] = 300; /* 10 per photon */
  work[11] = 5, work[LD_CELLS + 11] = 0;  /* photons that missed the grid */
  double cost[LD_CELLS];
  ad_cell_costs(work, cost);
  EXPECT(cost[3] == 40.0 && cost[9] == 10.0 && cost[11] == 1.0 && cost[0] == 700.0 / 45.0,
        "cell costs %g %g %g %g, expected 40 10 1 %g", cost[3], cost[9], cost[11], cost[0],
        700.0 / 45.0);
  masks[17] = ld_cell_bit(3) | ld_cell_bit(9);
  EXPECT(ad_build_pdf(masks, sel, NULL, cost, V, f, &pdf, &err) == BK_OK, "%s", err.msg);
  double above3 = pdf.cell_pdf[3] - f, above9 = pdf.cell_pdf[9] - f;
  EXPECT(fabs(above3 / above9 - 0.5) < 1e-3 && fabs(pdf.importance[3] - 0.5) < 1e-12,
        "costly cell's share %g of the cheap one's, expected 0.5 (importance %g)",
        above3 / above9, pdf.importance[3]);
  printf("pdf: a cell of 4x the work gets %.3f of the share of a cheap one (expected 0.5)\n",
         above3 / above9);

  /* a voxel reached from every cell favours none; nothing selected: uniform */
  masks[17] = ~0ull;
  EXPECT(ad_build_pdf(masks, sel, NULL, NULL, V, f, &pdf, &err) == BK_OK, "%s", err.msg);
  for (int c = 0; c < LD_CELLS; c++)
    EXPECT(fabs(pdf.cell_pdf[c] - 1.0f) < 1e-5, "cell %d pdf %g, expected uniform", c,
          (double)pdf.cell_pdf[c]);
  memset(sel, 0, V);
  EXPECT(ad_build_pdf(masks, sel, NULL, NULL, V, f, &pdf, &err) == BK_OK, "%s", err.msg);
  EXPECT(pdf.selected_reached == 0 && fabs(pdf.cell_pdf[5] - 1.0f) < 1e-6, "no selection");
  EXPECT(ad_build_pdf(masks, sel, NULL, NULL, V, 1.5f, &pdf, &err) == BK_ERR_INPUT,
         "floor 1.5 accepted");
  free(masks);
  free(sel);
  return tu_failures;
}

/* --- automatic thresholds ---------------------------------------------------- */

/* Synthetic pilot on a 48^3 grid (voxel coordinates): fog 0.2 plus a broad
 * blob, a bright cone with sharp sides (a spot's caustic) and a spherical
 * shadow hole where everything is 2% of its value. */
enum { TN = 48 };
static const double cone_apex[3] = {14.0, 58.0, 24.0}, cone_tan = 0.2126; /* 12 degrees */
static const double hole_c[3] = {34.0, 20.0, 24.0}, hole_r = 5.0;

static double cone_distance(const double p[3]) { /* > 0 outside, voxels */
  double vx = p[0] - cone_apex[0], vy = p[1] - cone_apex[1], vz = p[2] - cone_apex[2];
  double along = -vy, radial = sqrt(vx * vx + vz * vz);
  if (along <= 0.0) return sqrt(vx * vx + vy * vy + vz * vz);
  return (radial - along * cone_tan) / sqrt(1.0 + cone_tan * cone_tan);
}
static double hole_distance(const double p[3]) { /* > 0 outside */
  double dx = p[0] - hole_c[0], dy = p[1] - hole_c[1], dz = p[2] - hole_c[2];
  return sqrt(dx * dx + dy * dy + dz * dz) - hole_r;
}

static void make_pilot(float *rgb, double noise, double scale) {
  for (int k = 0; k < TN; k++)
    for (int j = 0; j < TN; j++)
      for (int i = 0; i < TN; i++) {
        double p[3] = {i + 0.5, j + 0.5, k + 0.5};
        double r2 = (p[0] - 24) * (p[0] - 24) + (p[1] - 24) * (p[1] - 24) + (p[2] - 24) * (p[2] - 24);
        double y = 0.2 + exp(-r2 / (2.0 * 14.0 * 14.0));
        if (cone_distance(p) < 0.0) y += 3.0;
        if (hole_distance(p) < 0.0) y *= 0.02;
        if (noise > 0.0) y *= 1.0 + noise * rng_gauss();
        if (y < 0.0) y = 0.0;
        size_t v = (size_t)i + TN * ((size_t)j + TN * (size_t)k);
        rgb[3 * v] = (float)(y * scale);
        rgb[3 * v + 1] = (float)(y * scale);
        rgb[3 * v + 2] = (float)(y * scale);
      }
}

/* Fractions of edge, shadow and smooth voxels selected. */
static void classify(const uint8_t *sel, double *edge, double *shadow, double *smooth) {
  size_t ne = 0, se = 0, nh = 0, sh = 0, ns = 0, ss = 0;
  for (int k = 0; k < TN; k++)
    for (int j = 0; j < TN; j++)
      for (int i = 0; i < TN; i++) {
        double p[3] = {i + 0.5, j + 0.5, k + 0.5};
        size_t v = (size_t)i + TN * ((size_t)j + TN * (size_t)k);
        double dc = cone_distance(p), dh = hole_distance(p);
        if (fabs(dc) < 1.0 && dh > 3.0) {
          ne++;
          se += sel[v] != 0;
        } else if (dh < -2.0) {
          nh++;
          sh += (sel[v] & AD_SEL_SHADOW) != 0;
        } else if (fabs(dc) > 4.0 && fabs(dh) > 4.0) {
          ns++;
          ss += sel[v] != 0;
        }
      }
  *edge = (double)se / ne;
  *shadow = (double)sh / nh;
  *smooth = (double)ss / ns;
}

static int test_thresholds(void) {
  bk_error_t err = {0};
  grid_dims_t d = cube_dims(TN);
  size_t V = grid_count(&d);
  float *rgb = calloc(3 * V, sizeof(float));
  uint8_t *sel = calloc(V, 1), *sel2 = calloc(V, 1);
  float *sig = calloc(V, sizeof(float));
  ad_select_opts_t opt = {SCENE_AUTO, SCENE_AUTO, AD_DEFAULT_SMOOTH_RADIUS};
  ad_select_stats_t st, st2;
  double edge, shadow, smooth;

  make_pilot(rgb, 0.0, 1.0);
  EXPECT(ad_select_voxels(&d, rgb, NULL, &opt, sel, &st, &err) == BK_OK, "%s", err.msg);
  classify(sel, &edge, &shadow, &smooth);
  printf("thresholds (clean): gradient %.4g /m (median %.4g), luminance %.4g (median %.4g); "
         "selected %zu of %zu; edge %.1f%%, shadow %.1f%%, smooth %.2f%%\n",
         (double)st.gradient_threshold, (double)st.median_gradient,
         (double)st.luminance_threshold, (double)st.median_luminance, st.selected, st.considered,
         100 * edge, 100 * shadow, 100 * smooth);
  EXPECT(edge >= 0.95, "only %.1f%% of the cone's edge voxels selected", 100 * edge);
  EXPECT(shadow >= 0.99, "only %.1f%% of the shadow voxels selected", 100 * shadow);
  EXPECT(smooth <= 0.01, "%.2f%% of the smooth voxels selected", 100 * smooth);
  EXPECT(st.reached == V && st.considered == V, "reached %zu considered %zu", st.reached,
        st.considered);

  /* scale invariance: 1000x the light gives 1000x the thresholds, the same voxels */
  make_pilot(rgb, 0.0, 1000.0);
  EXPECT(ad_select_voxels(&d, rgb, NULL, &opt, sel2, &st2, &err) == BK_OK, "%s", err.msg);
  EXPECT(fabs(st2.gradient_threshold / st.gradient_threshold - 1000.0) < 1.0 &&
            fabs(st2.luminance_threshold / st.luminance_threshold - 1000.0) < 1.0,
        "thresholds scale by %g and %g", st2.gradient_threshold / st.gradient_threshold,
        st2.luminance_threshold / st.luminance_threshold);
  size_t differ = 0;
  for (size_t v = 0; v < V; v++) differ += sel[v] != sel2[v];
  EXPECT(differ <= V / 10000, "%zu voxels change selection with the light's scale", differ);

  /* a noisy pilot (10% per voxel) still finds edges and shadows */
  rng_state = 12345;
  make_pilot(rgb, 0.10, 1.0);
  EXPECT(ad_select_voxels(&d, rgb, NULL, &opt, sel, &st, &err) == BK_OK, "%s", err.msg);
  classify(sel, &edge, &shadow, &smooth);
  printf("thresholds (10%% noise): gradient %.4g /m (median %.4g), luminance %.4g; edge %.1f%%, "
         "shadow %.1f%%, smooth %.2f%%\n",
         (double)st.gradient_threshold, (double)st.median_gradient,
         (double)st.luminance_threshold, 100 * edge, 100 * shadow, 100 * smooth);
  EXPECT(edge >= 0.90, "noisy: only %.1f%% of the edge voxels selected", 100 * edge);
  EXPECT(shadow >= 0.99, "noisy: only %.1f%% of the shadow voxels selected", 100 * shadow);
  EXPECT(smooth <= 0.02, "noisy: %.2f%% of the smooth voxels selected", 100 * smooth);

  /* pure noise on a flat fog: next to nothing is an edge */
  for (size_t v = 0; v < V; v++) rgb[3 * v] = rgb[3 * v + 1] = rgb[3 * v + 2] =
      (float)(1.0 + 0.1 * rng_gauss());
  EXPECT(ad_select_voxels(&d, rgb, NULL, &opt, sel, &st, &err) == BK_OK, "%s", err.msg);
  EXPECT(st.by_gradient <= V / 1000 && st.by_shadow == 0,
        "flat noisy fog: %zu by gradient, %zu by shadow", st.by_gradient, st.by_shadow);
  printf("thresholds (flat fog, 10%% noise): %zu of %zu by gradient\n", st.by_gradient, V);

  /* explicit thresholds are used as given; voxels that scatter nothing are
   * neither selected nor counted */
  make_pilot(rgb, 0.0, 1.0);
  ad_select_opts_t fixed = {1e30f, 0.0f, 1};
  EXPECT(ad_select_voxels(&d, rgb, NULL, &fixed, sel, &st, &err) == BK_OK, "%s", err.msg);
  EXPECT(st.selected == 0 && st.gradient_threshold == 1e30f && st.luminance_threshold == 0.0f,
        "explicit thresholds: %zu selected", st.selected);
  fixed.luminance_threshold = 0.5f;
  fixed.gradient_threshold = 1e30f;
  for (size_t v = 0; v < V; v++) sig[v] = (v % 2) ? 1.0f : 0.0f;
  EXPECT(ad_select_voxels(&d, rgb, sig, &fixed, sel, &st, &err) == BK_OK, "%s", err.msg);
  size_t even = 0, dark = 0;
  float *lum = calloc(V, sizeof(float)), *grad = calloc(V, sizeof(float));
  EXPECT(ad_pilot_fields(&d, rgb, 1, lum, grad, &err) == BK_OK, "%s", err.msg);
  for (size_t v = 0; v < V; v++) {
    even += (v % 2 == 0) && sel[v];
    dark += (v % 2 == 1) && lum[v] < 0.5f;
  }
  EXPECT(even == 0 && st.selected == dark && st.considered == V / 2,
        "scattering mask: %zu masked voxels selected, %zu selected of %zu dark", even,
        st.selected, dark);
  /* bad input names the key */
  fixed.gradient_threshold = NAN;
  EXPECT(ad_select_voxels(&d, rgb, NULL, &fixed, sel, &st, &err) == BK_ERR_INPUT &&
            strstr(err.msg, "gradient_threshold"), "NaN threshold: %s", err.msg);
  rgb[3 * 5] = -1.0f;
  EXPECT(ad_select_voxels(&d, rgb, NULL, &opt, sel, &st, &err) == BK_ERR_RUNTIME &&
            strstr(err.msg, "(5,0,0)"), "negative radiance: %s", err.msg);
  free(lum);
  free(grad);
  free(rgb);
  free(sel);
  free(sel2);
  free(sig);
  return tu_failures;
}

/* --- phase 1 -> phase 2 on a toy light ---------------------------------------- */

/* Without the march: a toy light whose photon from domain point (a, b) lands
 * in voxel (floor(32 a), floor(32 b), 0) of a 32x32x1 grid and deposits
 * f(a, b) there. f is 1, with a bright square (5: a caustic) and a dark square
 * (0.02: a shadow), both on voxel boundaries, so each voxel's exact energy is
 * f / 1024. The pilot records origins, the selection and PDF steer phase 2,
 * whose weighted estimate must stay unbiased. */
enum { CN = 32 };
static double toy_f(int i, int j) {
  if (i >= 10 && i < 15 && j >= 18 && j < 22) return 5.0;
  if (i >= 22 && i < 28 && j >= 4 && j < 10) return 0.02;
  return 1.0;
}

static int test_chain(void) {
  bk_error_t err = {0};
  grid_dims_t d = cube_dims(CN);
  d.nz = 1;
  size_t V = grid_count(&d);
  float *pilot = calloc(3 * V, sizeof(float)), *wsum = calloc(V, sizeof(float));
  double *energy = calloc(V, sizeof(double));
  uint64_t *masks = calloc(V, sizeof(uint64_t));
  uint32_t *count = calloc(V, sizeof(uint32_t));
  uint8_t *sel = calloc(V, 1);
  enum { PILOT = 4096, N = 65536 };
  for (uint32_t p = 0; p < PILOT; p++) {
    float a = (float)p / PILOT, b = ph_radical_inverse2(p);
    int i = (int)(a * CN), j = (int)(b * CN);
    size_t v = (size_t)i + CN * (size_t)j;
    for (int c = 0; c < 3; c++) pilot[3 * v + c] += (float)(toy_f(i, j) / PILOT);
    ld_origin_mark(masks, ld_origin_index((bk_long)v, 0, (bk_long)V), ld_cell_of(a, b));
  }
  ad_select_opts_t opt = {SCENE_AUTO, SCENE_AUTO, AD_DEFAULT_SMOOTH_RADIUS};
  ad_select_stats_t st;
  ad_pdf_t pdf;
  EXPECT(ad_select_voxels(&d, pilot, NULL, &opt, sel, &st, &err) == BK_OK, "%s", err.msg);
  EXPECT(ad_build_pdf(masks, sel, NULL, NULL, V, AD_DEFAULT_FLOOR, &pdf, &err) == BK_OK, "%s",
         err.msg);
  /* the cells over the two squares are the favoured ones */
  int hot = 0, hot_feature = 0;
  for (int c = 0; c < LD_CELLS; c++) {
    if (pdf.cell_pdf[c] <= 1.0f) continue;
    hot++;
    /* cell c covers voxels 4 cx .. 4 cx + 3; the smoothed pilot's gradient
     * reaches 2 voxels beyond a square's edge */
    int cx = c % 8, cy = c / 8;
    int near_bright = 4 * cx + 3 >= 8 && 4 * cx <= 16 && 4 * cy + 3 >= 16 && 4 * cy <= 23;
    int near_dark = 4 * cx + 3 >= 20 && 4 * cx <= 29 && 4 * cy + 3 >= 2 && 4 * cy <= 11;
    if (near_bright || near_dark) hot_feature++;
    else fprintf(stderr, "favoured cell %d (%d, %d) pdf %g is far from both squares\n", c, cx, cy,
                 (double)pdf.cell_pdf[c]);
  }
  EXPECT(hot > 0 && hot_feature == hot, "%d favoured cells, %d of them over the squares", hot,
        hot_feature);
  /* phase 2: warped Hammersley points, weight 1/pdf */
  double total = 0.0;
  for (uint32_t p = 0; p < N; p++) {
    ld_sample s = ld_pdf_warp(pdf.table, pdf.nx, pdf.ny, (float)p / N, ph_radical_inverse2(p));
    int i = (int)(s.x * CN), j = (int)(s.y * CN);
    size_t v = (size_t)i + CN * (size_t)j;
    double w = 1.0 / s.pdf;
    energy[v] += toy_f(i, j) * w / N;
    total += toy_f(i, j) * w / N;
    count[v]++;
    wsum[v] += (float)w;
  }
  double exact = 0.0, worst = 0.0, hot_w = 0.0, cold_w = 0.0;
  size_t hot_n = 0, cold_n = 0, empty = 0;
  for (int j = 0; j < CN; j++)
    for (int i = 0; i < CN; i++) {
      size_t v = (size_t)i + CN * (size_t)j;
      double e = toy_f(i, j) / (CN * CN);
      float cp = pdf.cell_pdf[ld_cell_of((i + 0.5f) / CN, (j + 0.5f) / CN)];
      exact += e;
      /* a voxel expects N pdf / 1024 points; the preimage of a voxel is a
       * rectangle, where the Hammersley set's count stays within a few
       * points (O(log N)) of its area: allow 3 points' worth */
      double rel = fabs(energy[v] - e) / e, allowed = 3.0 / ((double)N * cp / (CN * CN));
      worst = fmax(worst, rel / allowed);
      if (!count[v]) {
        empty++;
        continue;
      }
      double mean_w = wsum[v] / count[v];
      if (cp > 1.0f) {
        hot_w += mean_w;
        hot_n++;
      } else if (fabsf(cp - AD_DEFAULT_FLOOR) < 1e-5f) {
        cold_w += mean_w;
        cold_n++;
      }
    }
  float pmin = 1e30f, pmax = 0.0f;
  for (int c = 0; c < LD_CELLS; c++) {
    pmin = fminf(pmin, pdf.cell_pdf[c]);
    pmax = fmaxf(pmax, pdf.cell_pdf[c]);
  }
  printf("chain: %zu voxels selected (gradient %zu, shadow %zu), %d favoured cells, pdf "
         "%.2f..%.2f; total energy %.6f (exact %.6f), worst voxel error %.2f of its allowance; mean "
         "weight %.2f in favoured cells, %.2f in cells at the floor\n",
         st.selected, st.by_gradient, st.by_shadow, hot, (double)pmin, (double)pmax, total, exact,
         worst, hot_n ? hot_w / hot_n : 0.0, cold_n ? cold_w / cold_n : 0.0);
  EXPECT(fabs(total - exact) / exact < 1e-3, "weighted total %.6f, exact %.6f", total, exact);
  EXPECT(worst <= 1.0, "a voxel's weighted energy is off by %.2f times its allowance", worst);
  EXPECT(empty == 0, "%zu voxels got no photon", empty);
  EXPECT(hot_n > 0 && hot_w / hot_n < 1.0, "favoured cells: mean weight %.2f", hot_w / hot_n);
  EXPECT(cold_n > 0 && fabs(cold_w / cold_n - 1.0 / AD_DEFAULT_FLOOR) < 1e-3,
        "other cells: mean weight %.4f, expected 1/floor", cold_w / cold_n);
  free(pilot);
  free(wsum);
  free(energy);
  free(masks);
  free(count);
  free(sel);
  return tu_failures;
}

/* --- filter ------------------------------------------------------------------ */

/* Fog with a smooth variation along y and z, and a caustic step at x = 16:
 * four times brighter beyond. Colour (1, 0.9, 0.8). The noise is relative,
 * like a photon estimate's, and the count says how much: 1/count is the
 * filter's noise scale (kernels/adaptive_filter.h), so 10 photons for 10%. */
enum { FN = 32, STEP_X = 16 };
static double fog_truth(int i, int j, int k) {
  double y = 1.0 + 0.2 * sin(6.283185307179586 * (j + 0.5) / FN) * cos(3.14159 * (k + 0.5) / FN);
  return i >= STEP_X ? 4.0 * y : y;
}
static const float fog_colour[3] = {1.0f, 0.9f, 0.8f};

static void make_fog(float *truth, float *noisy, float *count, float *wmean, double sigma,
                     float w) {
  for (int k = 0; k < FN; k++)
    for (int j = 0; j < FN; j++)
      for (int i = 0; i < FN; i++) {
        size_t v = (size_t)i + FN * ((size_t)j + FN * (size_t)k);
        double t = fog_truth(i, j, k);
        for (int c = 0; c < 3; c++) {
          truth[3 * v + c] = (float)(t * fog_colour[c]);
        }
        double n = 1.0 + sigma * rng_gauss();
        for (int c = 0; c < 3; c++) noisy[3 * v + c] = (float)(t * n * fog_colour[c]);
        count[v] = (float)(1.0 / sigma);
        wmean[v] = w;
      }
}

/* Independent reference: the filter of kernels/adaptive_filter.h's header comment
 * by brute force in double, on a grid of FN x ny x nz with C floats per
 * voxel: 3D Gaussian means M_q over the cube |d| <= q (standard deviation
 * q/2), the box means D(q) of the squared luminance differences over 5^3,
 * the choice of level. Writes the output and the radius (q/2) of every
 * voxel. */
static double ref_lum(const double *p, int C) {
  return C == 3 ? 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2] : p[0];
}
static void reference_filter(const float *in, int ny, int nz, int C, const float *count,
                             const float *wmean, float alpha, float noise_k, int Q, float *out,
                             float *radius) {
  const size_t V = (size_t)FN * ny * nz;
  double *M = calloc((size_t)(Q + 1) * V * C, sizeof(double));
  double *L = calloc((size_t)(Q + 1) * V, sizeof(double)), *D = calloc((size_t)(Q + 1) * V, sizeof(double));
  for (int q = 0; q <= Q; q++)
    for (int k = 0; k < nz; k++)
      for (int j = 0; j < ny; j++)
        for (int i = 0; i < FN; i++) {
          size_t v0 = (size_t)i + FN * ((size_t)j + ny * (size_t)k);
          double acc[3] = {0, 0, 0}, wsum = 0.0, sig = 0.5 * q;
          for (int z = -q; z <= q; z++)
            for (int y = -q; y <= q; y++)
              for (int x = -q; x <= q; x++) {
                int a = i + x, b = j + y, c = k + z;
                if (a < 0 || b < 0 || c < 0 || a >= FN || b >= ny || c >= nz) continue;
                size_t v = (size_t)a + FN * ((size_t)b + ny * (size_t)c);
                double w = q == 0 ? 1.0 : exp(-(x * x + y * y + z * z) / (2.0 * sig * sig));
                for (int ch = 0; ch < C; ch++) acc[ch] += w * in[C * v + ch];
                wsum += w;
              }
          for (int ch = 0; ch < C; ch++) M[((size_t)q * V + v0) * C + ch] = acc[ch] / wsum;
          L[(size_t)q * V + v0] = ref_lum(&M[((size_t)q * V + v0) * C], C);
        }
  for (int q = 1; q <= Q; q++)
    for (int k = 0; k < nz; k++)
      for (int j = 0; j < ny; j++)
        for (int i = 0; i < FN; i++) {
          double sum = 0.0;
          int n = 0;
          for (int z = -2; z <= 2; z++)
            for (int y = -2; y <= 2; y++)
              for (int x = -2; x <= 2; x++) {
                int a = i + x, b = j + y, c = k + z;
                if (a < 0 || b < 0 || c < 0 || a >= FN || b >= ny || c >= nz) continue;
                size_t v = (size_t)a + FN * ((size_t)b + ny * (size_t)c);
                double dd = L[(size_t)q * V + v] - L[(size_t)(q - 1) * V + v];
                sum += dd * dd;
                n++;
              }
          D[(size_t)q * V + (size_t)i + FN * ((size_t)j + ny * (size_t)k)] = sum / n;
        }
  for (size_t v = 0; v < V; v++) {
    int qw = count[v] > 0.0f ? (int)floor(2.0 * alpha * wmean[v] + 0.5) : Q;
    if (qw > Q) qw = Q;
    int q = 0;
    double m1 = L[V + v], n = count[v];
    if (qw >= 1 && (noise_k < 0.0f || D[V + v] * n * n <= (double)noise_k * noise_k * m1 * m1)) {
      q = 1;
      while (q < qw && D[(size_t)(q + 1) * V + v] < D[(size_t)q * V + v]) q++;
    }
    for (int ch = 0; ch < C; ch++) out[C * v + ch] = (float)M[((size_t)q * V + v) * C + ch];
    radius[v] = 0.5f * q;
  }
  free(M);
  free(L);
  free(D);
}

/* Voxels where two filter results differ: radius, or colour beyond a
 * relative 1e-4 (float sums against double). A radius may flip where two
 * box means tie to float precision: at most `ties` such. */
static size_t compare_filters(const float *a, const float *ra, const float *b, const float *rb,
                              size_t V, int C, size_t *radius_diff) {
  size_t bad = 0;
  *radius_diff = 0;
  for (size_t v = 0; v < V; v++) {
    if (ra[v] != rb[v]) {
      (*radius_diff)++;
      continue;
    }
    for (int c = 0; c < C; c++)
      if (fabs(a[C * v + c] - b[C * v + c]) > 1e-4 * fmax(1.0, fabs(b[C * v + c]))) {
        bad++;
        break;
      }
  }
  return bad;
}

static int test_filter(void) {
  bk_error_t err = {0};
  grid_dims_t d = cube_dims(FN);
  size_t V = grid_count(&d);
  float *truth = calloc(3 * V, sizeof(float)), *noisy = calloc(3 * V, sizeof(float));
  float *out = calloc(3 * V, sizeof(float)), *rad = calloc(V, sizeof(float));
  float *ref = calloc(3 * V, sizeof(float)), *rref = calloc(V, sizeof(float));
  float *wmean = calloc(V, sizeof(float));
  float *count = calloc(V, sizeof(float));
  const int Q = 4; /* radius up to 2 voxels */

  /* a sparsely sampled region: mean weight 2 -> photon-weight radius 2 */
  rng_state = 777;
  make_fog(truth, noisy, count, wmean, 0.1, 2.0f);
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, Q, out, rad, &err) ==
            BK_OK, "%s", err.msg);
  reference_filter(noisy, FN, FN, 3, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, Q, ref, rref);
  size_t rdiff, ref_bad = compare_filters(out, rad, ref, rref, V, 3, &rdiff);
  double se_in = 0, se_out = 0, r_smooth = 0, r_step = 0, step_bias = 0.0;
  size_t n_smooth = 0, n_step = 0, step_small = 0, above = 0;
  for (int k = 0; k < FN; k++)
    for (int j = 0; j < FN; j++)
      for (int i = 0; i < FN; i++) {
        size_t v = (size_t)i + FN * ((size_t)j + FN * (size_t)k);
        above += rad[v] > 2.0f;
        int interior = j >= 4 && j < FN - 4 && k >= 4 && k < FN - 4;
        if (interior && (i <= STEP_X - 6 || i >= STEP_X + 5)) {
          for (int c = 0; c < 3; c++) {
            double rel = truth[3 * v + c];
            se_in += pow((noisy[3 * v + c] - truth[3 * v + c]) / rel, 2);
            se_out += pow((out[3 * v + c] - truth[3 * v + c]) / rel, 2);
          }
          r_smooth += rad[v];
          n_smooth++;
        }
        if (interior && (i == STEP_X - 1 || i == STEP_X)) {
          r_step += rad[v];
          n_step++;
          step_small += rad[v] <= 0.5f;
          step_bias += fabs(out[3 * v + 1] - truth[3 * v + 1]) /
                       (3.0 * 0.9 * fog_truth(STEP_X - 1, j, k));
        }
      }
  double rms_in = sqrt(se_in / (3.0 * n_smooth)), rms_out = sqrt(se_out / (3.0 * n_smooth));
  r_smooth /= n_smooth;
  r_step /= n_step;
  step_bias /= n_step;
  printf("filter: smooth part mean radius %.2f, relative RMS noise %.4f -> %.4f (x%.2f); step "
         "voxels mean radius %.2f, %.1f%% with radius <= 0.5, mean error %.1f%% of the step; "
         "%zu/%zu voxels differ from the brute-force reference (%zu radii)\n",
         r_smooth, rms_in, rms_out, rms_in / rms_out, r_step, 100.0 * step_small / n_step,
         100.0 * step_bias, ref_bad + rdiff, V, rdiff);
  EXPECT(above == 0, "%zu voxels exceed the photon-weight radius 2", above);
  EXPECT(ref_bad == 0 && rdiff <= V / 1000, "%zu voxels (%zu radii) differ from the brute-force filter",
        ref_bad + rdiff, rdiff);
  EXPECT(r_smooth >= 1.2, "smooth part: mean radius %.2f, expected large (>= 1.2 of 2)", r_smooth);
  EXPECT(rms_out <= 0.4 * rms_in, "smooth part: RMS noise %.4f -> %.4f, expected below 40%%",
        rms_in, rms_out);
  EXPECT(step_small >= 0.9 * n_step, "only %zu of %zu step voxels have radius <= 0.5", step_small,
        n_step);
  /* radius 1/2 takes 11% from across the step (e^-2 / (1 + 2 e^-2) of one
   * neighbour); radius 1 would take 28% */
  EXPECT(step_bias <= 0.13, "step voxels blurred by %.1f%% of the step", 100.0 * step_bias);

  /* the slides' rule (no noise test for the first step) blurs the step */
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 1.0f, -1.0f, Q, out, rad, &err) == BK_OK, "%s",
        err.msg);
  reference_filter(noisy, FN, FN, 3, count, wmean, 1.0f, -1.0f, Q, ref, rref);
  ref_bad = compare_filters(out, rad, ref, rref, V, 3, &rdiff);
  EXPECT(ref_bad == 0 && rdiff <= V / 1000, "noise_k < 0: %zu voxels differ from the brute-force "
        "filter", ref_bad + rdiff);

  /* densely sampled (w = 0.2 -> radius 0) or alpha = 0: no filtering at all */
  for (size_t v = 0; v < V; v++) wmean[v] = 0.2f;
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, Q, out, rad, &err) ==
            BK_OK, "%s", err.msg);
  EXPECT(memcmp(out, noisy, 3 * V * sizeof(float)) == 0, "radius 0 must keep the input");
  for (size_t v = 0; v < V; v++) wmean[v] = 3.0f;
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 0.0f, AD_DEFAULT_NOISE_K, Q, out, NULL, &err) ==
            BK_OK, "%s", err.msg);
  EXPECT(memcmp(out, noisy, 3 * V * sizeof(float)) == 0, "alpha 0 must keep the input");
  /* voxels no photon reached may take the largest level (3 voxels here), the
   * others at most round(2 * 1 * 0.5) / 2 = 1/2 */
  for (size_t v = 0; v < V; v++) {
    count[v] = v % 3 == 0 ? 0.0f : 5.0f;
    wmean[v] = 0.5f;
    for (int c = 0; c < 3; c++) noisy[3 * v + c] = (float)(0.5 + 0.05 * rng_gauss());
  }
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, 6, out, rad, &err) ==
            BK_OK, "%s", err.msg);
  size_t reached_big = 0, n0 = 0;
  double r0 = 0.0;
  float r0max = 0.0f;
  for (size_t v = 0; v < V; v++) {
    if (count[v] > 0.0f) {
      reached_big += rad[v] > 0.5f;
    } else {
      r0 += rad[v];
      r0max = fmaxf(r0max, rad[v]);
      n0++;
    }
  }
  r0 /= n0;
  EXPECT(reached_big == 0, "%zu voxels with photons exceed the photon-weight radius 1/2",
        reached_big);
  EXPECT(r0 > 1.0 && r0max == 3.0f, "unreached voxels: mean radius %.2f, largest %g", r0,
        (double)r0max);
  /* a constant field stays as it is (up to the rounding of the weighted sums) */
  for (size_t v = 0; v < 3 * V; v++) noisy[v] = 0.5f;
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, 6, out, rad, &err) ==
            BK_OK, "%s", err.msg);
  double cdev = 0.0;
  for (size_t v = 0; v < 3 * V; v++) cdev = fmax(cdev, fabs(out[v] - 0.5));
  EXPECT(cdev < 1e-6, "constant field changed by %.2e", cdev);
  /* bad arguments */
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, -1.0f, 1.0f, 8, out, NULL, &err) ==
                BK_ERR_INPUT && strstr(err.msg, "alpha"), "alpha -1: %s", err.msg);
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 1.0f, 1.0f, AD_FILTER_MAX_LEVEL + 1, out, NULL,
                       &err) == BK_ERR_INPUT, "level %d accepted", AD_FILTER_MAX_LEVEL + 1);
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 1.0f, 1.0f, 8, noisy, NULL, &err) ==
            BK_ERR_RUNTIME, "aliasing accepted");
  EXPECT(ad_filter_host(&d, 2, noisy, count, wmean, 1.0f, 1.0f, 8, out, NULL, &err) ==
            BK_ERR_RUNTIME, "2 channels accepted");
  free(truth);
  free(noisy);
  free(out);
  free(rad);
  free(ref);
  free(rref);
  free(wmean);
  free(count);
  return tu_failures;
}

static int init_cl(clh_context_t *cl) {
  bk_error_t err = {0};
  if (clh_init(cl, NULL, &err) != BK_OK) {
    fprintf(stderr, "FAIL clh_init: %s\n", err.msg);
    return 0;
  }
  return 1;
}

static int test_filter_cl(void) {
  bk_error_t err = {0};
  clh_context_t cl;
  if (!init_cl(&cl)) return 1;
  /* a non-cubic grid, the noisy fog step, unreached voxels and mixed weights */
  grid_dims_t d = cube_dims(FN);
  d.nx = FN;
  d.ny = FN - 5;
  d.nz = FN - 9;
  size_t V = grid_count(&d), full = (size_t)FN * FN * FN;
  float *truth = calloc(3 * full, sizeof(float)), *noisy = calloc(3 * full, sizeof(float));
  float *wmean = calloc(full, sizeof(float));
  float *count = calloc(full, sizeof(float));
  float *oh = calloc(3 * V, sizeof(float)), *oc = calloc(3 * V, sizeof(float));
  float *rh = calloc(V, sizeof(float)), *rc = calloc(V, sizeof(float));
  rng_state = 4242;
  make_fog(truth, noisy, count, wmean, 0.1, 2.0f);
  for (size_t v = 0; v < V; v++) {
    wmean[v] = (float)(0.2 + 5.0 * rng_uniform());
    if (v % 17 == 0) count[v] = 0.0f;
  }
  const int Q = AD_FILTER_MAX_LEVEL;
  EXPECT(ad_filter_host(&d, 3, noisy, count, wmean, 0.7f, 1.0f, Q, oh, rh, &err) == BK_OK, "%s",
        err.msg);
  int rcode = ad_filter_cl(&cl, &d, 3, noisy, count, wmean, 0.7f, 1.0f, Q, oc, rc, &err);
  EXPECT(rcode == BK_OK, "%s", err.msg);
  double worst = 0.0;
  size_t rdiff = 0, hist[AD_FILTER_MAX_LEVEL + 1] = {0};
  for (size_t v = 0; v < V; v++) {
    for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(oh[3 * v + c] - oc[3 * v + c]));
    rdiff += rh[v] != rc[v];
    hist[(int)(2.0f * rh[v])]++;
  }
  printf("filter_cl on %s: %dx%dx%d, max |host - OpenCL| = %.3g, %zu radii differ; radii",
         cl.device_name, d.nx, d.ny, d.nz, worst, rdiff);
  for (int q = 0; q <= Q; q++) printf(" %g:%zu", 0.5 * q, hist[q]);
  printf("\n");
  EXPECT(worst <= 1e-5, "host and OpenCL differ by %.3g", worst);
  EXPECT(rdiff == 0, "%zu radii differ", rdiff);
  EXPECT(hist[0] > 0 && hist[1] > 0 && hist[2] > 0 && hist[Q] > 0, "a level is never used");
  /* without the radius grid */
  memset(oc, 0, 3 * V * sizeof(float));
  EXPECT(ad_filter_cl(&cl, &d, 3, noisy, count, wmean, 0.7f, 1.0f, Q, oc, NULL, &err) == BK_OK,
        "%s", err.msg);
  worst = 0.0;
  for (size_t v = 0; v < 3 * V; v++) worst = fmax(worst, fabs(oh[v] - oc[v]));
  EXPECT(worst <= 1e-5, "without the radius grid: differ by %.3g", worst);
  EXPECT(ad_filter_cl(&cl, &d, 3, noisy, count, wmean, NAN, 1.0f, 8, oc, NULL, &err) ==
            BK_ERR_INPUT, "NaN alpha accepted");
  /* one channel (a grey march), at the default largest radius: host, OpenCL
   * and the brute-force reference */
  const int Qd = 2 * (int)AD_DEFAULT_MAX_RADIUS;
  float *grey = calloc(V, sizeof(float)), *gh = calloc(V, sizeof(float)),
        *gc = calloc(V, sizeof(float)), *gr = calloc(V, sizeof(float)), *rr = calloc(V, sizeof(float));
  for (size_t v = 0; v < V; v++)
    grey[v] = ad_luminance(noisy[3 * v], noisy[3 * v + 1], noisy[3 * v + 2]);
  EXPECT(ad_filter_host(&d, 1, grey, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, Qd, gh, rh, &err) ==
            BK_OK, "%s", err.msg);
  EXPECT(ad_filter_cl(&cl, &d, 1, grey, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, Qd, gc, rc, &err) ==
            BK_OK, "%s", err.msg);
  reference_filter(grey, d.ny, d.nz, 1, count, wmean, 1.0f, AD_DEFAULT_NOISE_K, Qd, gr, rr);
  double gworst = 0.0;
  size_t grdiff = 0, gref_rdiff;
  for (size_t v = 0; v < V; v++) {
    gworst = fmax(gworst, fabs(gh[v] - gc[v]));
    grdiff += rh[v] != rc[v];
  }
  size_t gref_bad = compare_filters(gh, rh, gr, rr, V, 1, &gref_rdiff);
  printf("filter_cl grey: max |host - OpenCL| = %.3g, %zu radii differ, %zu/%zu voxels differ "
         "from the brute-force reference (%zu radii)\n",
         gworst, grdiff, gref_bad + gref_rdiff, V, gref_rdiff);
  EXPECT(gworst <= 1e-5 && grdiff == 0, "grey: host and OpenCL differ");
  EXPECT(gref_bad == 0 && gref_rdiff <= V / 1000, "grey: %zu voxels differ from the brute-force "
        "filter", gref_bad + gref_rdiff);
  free(grey);
  free(gh);
  free(gc);
  free(gr);
  free(rr);
  clh_release(&cl);
  free(truth);
  free(noisy);
  free(wmean);
  free(count);
  free(oh);
  free(oc);
  free(rh);
  free(rc);
  return tu_failures;
}

/* --- device math --------------------------------------------------------------- */

static const char *device_src =
    "#include \"kernels/light_domain.h\"\n"
    "__kernel void warp(__global const float *table, int nx, int ny, __global const float *u,\n"
    "                   int n, __global float *out) {\n"
    "  int i = get_global_id(0);\n"
    "  if (i >= n) return;\n"
    "  ld_sample s = ld_pdf_warp(table, nx, ny, u[2 * i], u[2 * i + 1]);\n"
    "  out[4 * i] = s.x; out[4 * i + 1] = s.y; out[4 * i + 2] = s.pdf;\n"
    "  out[4 * i + 3] = (float)s.cell;\n"
    "}\n"
    "__kernel void mark(__global ulong *masks, int voxels, int lights, int n) {\n"
    "  int i = get_global_id(0);\n"
    "  if (i >= n) return;\n"
    "  /* many work-items hit the same voxel from different cells */\n"
    "  int v = (i * 7) % voxels, light = i % lights;\n"
    "  float a = (float)((i * 13) % 97) / 97.0f, b = (float)((i * 5) % 89) / 89.0f;\n"
    "  ld_origin_mark(masks, ld_origin_index(v, light, voxels), ld_cell_of(a, b));\n"
    "}\n";

static int test_device(void) {
  bk_error_t err = {0};
  clh_context_t cl;
  cl_program prog = NULL;
  cl_kernel kw = NULL, km = NULL;
  cl_mem tb = NULL, ub = NULL, ob = NULL, mb = NULL;
  cl_int cerr = CL_SUCCESS;
  enum { N = 8192, VOX = 101, LIGHTS = 3, MARKS = 4000 }; /* ~13 marks per mask */
  if (!init_cl(&cl)) return 1;
  float *u = calloc(2 * N, sizeof(float)), *o = calloc(4 * N, sizeof(float));
  uint64_t *masks = calloc(VOX * LIGHTS, sizeof(uint64_t));
  uint64_t *host = calloc(VOX * LIGHTS, sizeof(uint64_t));
  EXPECT(cl.has_int64_atomics, "%s lacks cl_khr_int64_base_atomics", cl.device_name);
  double w[LD_CELLS];
  for (int c = 0; c < LD_CELLS; c++) w[c] = (c * 37) % 11;
  float table[LD_TABLE_FLOATS(8, 8)];
  EXPECT(ad_pdf_from_weights(w, 8, 8, 0.2f, table, NULL, &err) == BK_OK, "%s", err.msg);
  for (int i = 0; i < N; i++) {
    u[2 * i] = (float)i / N;
    u[2 * i + 1] = ph_radical_inverse2((uint32_t)i);
  }
  if (clh_build_source(&cl, "tests/adaptive_device.cl", device_src, "", &prog, &err) != BK_OK) {
    fprintf(stderr, "FAIL build: %s\n", err.msg);
    tu_failures++;
    goto error;
  }
  kw = clCreateKernel(prog, "warp", &cerr);
  CLH_CHECK(cerr, &err, error);
  km = clCreateKernel(prog, "mark", &cerr);
  CLH_CHECK(cerr, &err, error);
  tb = clCreateBuffer(cl.context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof table, table,
                      &cerr);
  CLH_CHECK(cerr, &err, error);
  ub = clCreateBuffer(cl.context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, 2 * N * sizeof(float),
                      u, &cerr);
  CLH_CHECK(cerr, &err, error);
  ob = clCreateBuffer(cl.context, CL_MEM_WRITE_ONLY, 4 * N * sizeof(float), NULL, &cerr);
  CLH_CHECK(cerr, &err, error);
  mb = clCreateBuffer(cl.context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                      VOX * LIGHTS * sizeof(uint64_t), masks, &cerr);
  CLH_CHECK(cerr, &err, error);
  cl_int nx = 8, ny = 8, n = N, vox = VOX, lights = LIGHTS, marks = MARKS;
  CLH_CHECK(clSetKernelArg(kw, 0, sizeof(cl_mem), &tb), &err, error);
  CLH_CHECK(clSetKernelArg(kw, 1, sizeof(cl_int), &nx), &err, error);
  CLH_CHECK(clSetKernelArg(kw, 2, sizeof(cl_int), &ny), &err, error);
  CLH_CHECK(clSetKernelArg(kw, 3, sizeof(cl_mem), &ub), &err, error);
  CLH_CHECK(clSetKernelArg(kw, 4, sizeof(cl_int), &n), &err, error);
  CLH_CHECK(clSetKernelArg(kw, 5, sizeof(cl_mem), &ob), &err, error);
  size_t gw = N;
  CLH_CHECK(clEnqueueNDRangeKernel(cl.queue, kw, 1, NULL, &gw, NULL, 0, NULL, NULL), &err, error);
  CLH_CHECK(clSetKernelArg(km, 0, sizeof(cl_mem), &mb), &err, error);
  CLH_CHECK(clSetKernelArg(km, 1, sizeof(cl_int), &vox), &err, error);
  CLH_CHECK(clSetKernelArg(km, 2, sizeof(cl_int), &lights), &err, error);
  CLH_CHECK(clSetKernelArg(km, 3, sizeof(cl_int), &marks), &err, error);
  size_t gm = MARKS;
  CLH_CHECK(clEnqueueNDRangeKernel(cl.queue, km, 1, NULL, &gm, NULL, 0, NULL, NULL), &err, error);
  CLH_CHECK(clEnqueueReadBuffer(cl.queue, ob, CL_TRUE, 0, 4 * N * sizeof(float), o, 0, NULL, NULL),
            &err, error);
  CLH_CHECK(clEnqueueReadBuffer(cl.queue, mb, CL_TRUE, 0, VOX * LIGHTS * sizeof(uint64_t), masks,
                                0, NULL, NULL), &err, error);
  double worst = 0.0, worst_pdf = 0.0;
  int cells = 0;
  for (int i = 0; i < N; i++) {
    ld_sample s = ld_pdf_warp(table, 8, 8, u[2 * i], u[2 * i + 1]);
    worst = fmax(worst, fmax(fabs(s.x - o[4 * i]), fabs(s.y - o[4 * i + 1])));
    worst_pdf = fmax(worst_pdf, fabs(s.pdf - o[4 * i + 2]) / s.pdf);
    cells += (int)o[4 * i + 3] != s.cell;
  }
  for (int i = 0; i < MARKS; i++) {
    int v = (i * 7) % VOX, light = i % LIGHTS;
    float a = (float)((i * 13) % 97) / 97.0f, b = (float)((i * 5) % 89) / 89.0f;
    ld_origin_mark(host, ld_origin_index(v, light, VOX), ld_cell_of(a, b));
  }
  int mask_diff = 0, bits = 0;
  for (int i = 0; i < VOX * LIGHTS; i++) {
    mask_diff += masks[i] != host[i];
    bits += __builtin_popcountll(host[i]);
  }
  printf("device: warp of %d points, max |host - OpenCL| %.2e (pdf %.2e), %d cells differ; "
         "origin masks %d of %d differ (%d bits set by %d atomic marks)\n",
         N, worst, worst_pdf, cells, mask_diff, VOX * LIGHTS, bits, MARKS);
  EXPECT(worst <= 1e-6 && worst_pdf <= 1e-6 && cells == 0, "device warp differs");
  EXPECT(mask_diff == 0 && bits > VOX * LIGHTS && bits < VOX * LIGHTS * 64,
        "device origin masks differ (or are trivially empty or full)");
error:
  if (err.msg[0] && err.code) {
    fprintf(stderr, "FAIL %s\n", err.msg);
    tu_failures++;
  }
  if (kw) clReleaseKernel(kw);
  if (km) clReleaseKernel(km);
  if (tb) clReleaseMemObject(tb);
  if (ub) clReleaseMemObject(ub);
  if (ob) clReleaseMemObject(ob);
  if (mb) clReleaseMemObject(mb);
  if (prog) clReleaseProgram(prog);
  clh_release(&cl);
  free(u);
  free(o);
  free(masks);
  free(host);
  return tu_failures;
}

/* --- fixed: the halves' filter on the lattice ---------------------------------- */

/* One axis of the level-q Gaussian at c along n taps, renormalised inside. */
static double axis_weight(int q, int c, int t, int n, double *ws) {
  double sigma = (double)AD_FILTER_SIGMA * q, sum = 0.0;
  for (int u = c - q; u <= c + q; u++)
    if (u >= 0 && u < n) sum += (float)exp(-(double)((u - c) * (u - c)) / (2.0 * sigma * sigma));
  *ws = sum;
  return (float)exp(-(double)((t - c) * (t - c)) / (2.0 * sigma * sigma));
}

/* The separable Gaussian's definition at voxel (x, y, z), level q, in double. */
static double fixed_reference(const grid_dims_t *d, const float *in, int x, int y, int z, int q) {
  double sz = 0.0, ws;
  for (int tz = z - q; tz <= z + q; tz++) {
    if (tz < 0 || tz >= d->nz) continue;
    double wz = axis_weight(q, z, tz, d->nz, &ws) / ws, sy = 0.0;
    for (int ty = y - q; ty <= y + q; ty++) {
      if (ty < 0 || ty >= d->ny) continue;
      double wy = axis_weight(q, y, ty, d->ny, &ws) / ws, sx = 0.0;
      for (int tx = x - q; tx <= x + q; tx++) {
        if (tx < 0 || tx >= d->nx) continue;
        sx += axis_weight(q, x, tx, d->nx, &ws) / ws * in[tx + d->nx * (ty + d->ny * tz)];
      }
      sy += wy * sx;
    }
    sz += wz * sy;
  }
  return sz;
}

static int test_fixed(void) {
  grid_dims_t d = cube_dims(13);
  d.ny = 10, d.nz = 7;
  const size_t V = (size_t)d.nx * d.ny * d.nz, L = 7 * 5 * 4;
  const float radii[] = {0.0f, 0.25f, 0.5f, 0.75f, 1.0f, 1.5f, 2.0f}; /* levels 0 1 1 2 2 3 4 */
  float *in = malloc(V * sizeof *in), *radius = malloc(V * sizeof *radius);
  float *out = malloc(L * sizeof *out);
  REQUIRE(in && radius && out, "out of memory");
  for (size_t v = 0; v < V; v++) {
    in[v] = (float)(1.0 + rng_gauss());
    radius[v] = radii[(size_t)(rng_uniform() * 7.0) % 7];
  }
  bk_error_t err;
  memset(&err, 0, sizeof err);
  const float *ins[1] = {in};
  float *outs[1] = {out};
  REQUIRE(ad_filter_fixed_lattice(&d, ins, 1, radius, 3, outs, &err) == BK_OK, "%s", err.msg);
  double worst = 0.0;
  size_t k = 0, filtered = 0;
  for (int z = 0; z < d.nz; z += 2)
    for (int y = 0; y < d.ny; y += 2)
      for (int x = 0; x < d.nx; x += 2, k++) {
        size_t v = (size_t)x + (size_t)d.nx * (y + (size_t)d.ny * z);
        int q = (int)(2.0f * radius[v] + 0.5f);
        double want = q >= 1 && q <= 3 ? fixed_reference(&d, in, x, y, z, q) : in[v];
        filtered += q >= 1 && q <= 3;
        worst = fmax(worst, fabs(out[k] - want) / fmax(1e-3, fabs(want)));
        EXPECT(ee_lattice_voxel(&d, k) == v, "lattice voxel %zu is %zu, expected %zu", k,
               ee_lattice_voxel(&d, k), v);
      }
  printf("fixed: %zu lattice voxels (%zu filtered), worst relative difference %.2e\n", k,
         filtered, worst);
  EXPECT(k == L, "lattice of %zu voxels, expected %zu", k, L);
  EXPECT(worst <= 1e-5 && filtered > L / 2, "lattice filter differs from its definition");
  free(in), free(radius), free(out);
  return tu_failures;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: %s cells|warp|pdf|thresholds|chain|filter|filter_cl|fixed|device\n", argv[0]);
    return 2;
  }
  const char *t = argv[1];
  int rc;
  if (!strcmp(t, "cells")) rc = test_cells();
  else if (!strcmp(t, "warp")) rc = test_warp();
  else if (!strcmp(t, "pdf")) rc = test_pdf();
  else if (!strcmp(t, "thresholds")) rc = test_thresholds();
  else if (!strcmp(t, "chain")) rc = test_chain();
  else if (!strcmp(t, "filter")) rc = test_filter();
  else if (!strcmp(t, "filter_cl")) rc = test_filter_cl();
  else if (!strcmp(t, "fixed")) rc = test_fixed();
  else if (!strcmp(t, "device")) rc = test_device();
  else {
    fprintf(stderr, "unknown test '%s'\n", t);
    return 2;
  }
  if (rc) fprintf(stderr, "%d failure(s)\n", tu_failures);
  return rc ? 1 : 0;
}
