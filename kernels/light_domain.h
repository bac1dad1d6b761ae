/* light_domain.h: where photons come from in their light's 2D sampling
 * domain, and what the march can record about it; host and device.
 *
 * The march takes two optional inputs from here, neither of which it
 * interprets: a sampling table per light (photons drawn from a PDF over the
 * domain instead of uniformly, each carrying w = 1/pdf) and an origin
 * recorder (per cell of a coarse grid, which domain cells reached it). The
 * adaptive pipeline (baker/adaptive.h) builds the first from the second.
 *
 *
 * Light domain. Every light maps a 2D point (a, b) in [0,1)^2 to a photon
 * origin and direction (kernels/light_sample.h; (a, b) is the point after the
 * Cranley–Patterson rotation, the one the generator actually uses). The
 * domain is split into LD_CELLS_X x LD_CELLS_Y = 64 cells; cell
 * c = cx + LD_CELLS_X * cy with cx = floor(a * LD_CELLS_X), cy = floor(b *
 * LD_CELLS_Y) (ld_cell_of). 64 cells so that the origin data fits one 64-bit
 * mask per pilot cell per light.
 *
 * Origin data (phase 1, pilot photons). An array of bk_ulong masks, light
 * major: masks[ld_origin_index(cell, light, cells)], cell = the x-fastest
 * index of the pilot's coarse grid (blocks of 2^s voxels, baker/adaptive.h;
 * s = 0 makes them voxels). A pilot photon from light-domain cell c sets
 * bit c of every coarse cell it crosses (ld_origin_mark: atom_or on the
 * device, an atomic fetch-or on the host; kernels/photon_march.h, PM_MODE_ORIGINS).
 *
 * PDF (phase 2). A piecewise-constant density over nx x ny cells, stored as a
 * table of LD_TABLE_FLOATS(nx, ny) floats:
 *   table[0 .. ny]                              marginal CDF over rows (b),
 *                                               table[0] = 0, table[ny] = 1
 *   table[ny+1 + r*(nx+1) + 0 .. nx]            conditional CDF over the
 *                                               columns (a) of row r
 * ld_pdf_warp maps a uniform point u (a Hammersley point) to x: it inverts the
 * marginal CDF for the row, then the row's conditional CDF for the column, and
 * places x linearly (so uniformly) inside the cell. The map is monotone in each
 * coordinate and piecewise linear, a bijection of [0,1)^2 up to float
 * rounding (ld_pdf_unwarp is its inverse), and the density of x is
 *   pdf(x) = P(row) * P(col | row) * nx * ny
 * with respect to the uniform measure on [0,1)^2 (so the uniform density is 1).
 * A photon drawn this way carries the weight 1/(N pdf(x)) in place of 1/N:
 * its power is the light's power/N times w = 1/pdf(x), and the estimate is
 * unbiased wherever pdf > 0 (baker/adaptive.c puts a floor under it).
 *
 */
#ifndef BAKER_LIGHT_DOMAIN_H
#define BAKER_LIGHT_DOMAIN_H

#include "kernels/shared.h"

#define LD_CELLS_X 8
#define LD_CELLS_Y 8
#define LD_CELLS (LD_CELLS_X * LD_CELLS_Y) /* 64: one 64-bit origin mask */
/* Floats in a PDF table of nx x ny cells (see the header comment). */
#define LD_TABLE_FLOATS(nx, ny) ((ny) + 1 + (ny) * ((nx) + 1))
/* The largest float below 1: warped points stay in [0,1). */
#define LD_ONE_BELOW 0.99999994f
/* --- origin data ------------------------------------------------------------ */

/* Cell of the light-domain point (a, b); points outside [0,1) are clamped to
 * the edge cells. a * 8 is exact in float, so cells have exact edges. */
BK_INLINE int ld_cell_of(float a, float b) {
  int cx = bk_clampi((int)floor(a * (float)LD_CELLS_X), 0, LD_CELLS_X - 1);
  int cy = bk_clampi((int)floor(b * (float)LD_CELLS_Y), 0, LD_CELLS_Y - 1);
  return cx + LD_CELLS_X * cy;
}

BK_INLINE bk_ulong ld_cell_bit(int cell) { return ((bk_ulong)1) << cell; }

/* Index of (voxel, light) in the origin-mask array: light major, so the masks
 * of one light are one contiguous block of `voxels` entries. */
BK_INLINE bk_long ld_origin_index(bk_long voxel, int light, bk_long voxels) {
  return (bk_long)light * voxels + voxel;
}

/* Sets the bit of `cell` in masks[index]. Bits are only ever set, so a plain
 * read that finds the bit already set is final and saves the atomic (most
 * voxels are crossed by many photons of the same cell). */
#ifdef __OPENCL_VERSION__
#if defined(cl_khr_int64_extended_atomics)
#pragma OPENCL EXTENSION cl_khr_int64_extended_atomics : enable
#define LD_HAS_ORIGIN_MARK 1
BK_INLINE void ld_origin_mark(volatile __global ulong *masks, bk_long index, int cell) {
  ulong bit = ld_cell_bit(cell);
  if ((masks[index] & bit) == 0) atom_or(&masks[index], bit);
}
#elif defined(cl_khr_int64_base_atomics)
/* Without atom_or on ulong: a compare-and-swap loop (base atomics). */
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
#define LD_HAS_ORIGIN_MARK 1
BK_INLINE void ld_origin_mark(volatile __global ulong *masks, bk_long index, int cell) {
  ulong bit = ld_cell_bit(cell);
  ulong old = masks[index];
  while ((old & bit) == 0) {
    ulong seen = atom_cmpxchg(&masks[index], old, old | bit);
    if (seen == old) break;
    old = seen;
  }
}
#endif
#else
#define LD_HAS_ORIGIN_MARK 1
BK_INLINE void ld_origin_mark(bk_ulong *masks, bk_long index, int cell) {
  bk_ulong bit = ld_cell_bit(cell);
  if ((__atomic_load_n(&masks[index], __ATOMIC_RELAXED) & bit) == 0)
    __atomic_fetch_or(&masks[index], bit, __ATOMIC_RELAXED);
}
#endif

/* --- the PDF warp ----------------------------------------------------------- */

typedef struct ld_sample {
  float x, y;  /* the warped point in [0,1)^2 */
  float pdf;   /* its density w.r.t. the uniform measure (uniform = 1) */
  int cell;    /* col + nx * row of the cell x lies in */
} ld_sample;

/* The interval i in [0, n) with cdf[i] <= u < cdf[i+1], for a CDF of n+1
 * entries from 0 to 1 and u in [0,1). Zero-width intervals are never chosen. */
BK_INLINE int ld_cdf_find(const BK_GLOBAL float *cdf, int n, float u) {
  int lo = 0, hi = n;
  while (hi - lo > 1) {
    int mid = (lo + hi) >> 1;
    if (cdf[mid] <= u) lo = mid;
    else hi = mid;
  }
  return lo;
}

/* Position inside interval i of a CDF, scaled to cell units: i + t with t in
 * [0,1), kept strictly below i + 1 so that x lies in the cell whose
 * probability the pdf reports ((i+1) * LD_ONE_BELOW rounds below i + 1). */
BK_INLINE float ld_cdf_place(const BK_GLOBAL float *cdf, int i, float u) {
  float w = cdf[i + 1] - cdf[i];
  float t = w > 0.0f ? (u - cdf[i]) / w : 0.0f;
  float s = (float)i + bk_clampf(t, 0.0f, 1.0f);
  return fmin(s, (float)(i + 1) * LD_ONE_BELOW);
}

/* Warps the uniform point (ua, ub) through the PDF table of nx x ny cells. */
BK_INLINE ld_sample ld_pdf_warp(const BK_GLOBAL float *table, int nx, int ny, float ua,
                                float ub) {
  ld_sample s;
  ua = bk_clampf(ua, 0.0f, LD_ONE_BELOW);
  ub = bk_clampf(ub, 0.0f, LD_ONE_BELOW);
  const BK_GLOBAL float *marg = table;
  int row = ld_cdf_find(marg, ny, ub);
  const BK_GLOBAL float *cond = table + (ny + 1) + row * (nx + 1);
  int col = ld_cdf_find(cond, nx, ua);
  s.y = fmin(ld_cdf_place(marg, row, ub) / (float)ny, LD_ONE_BELOW);
  s.x = fmin(ld_cdf_place(cond, col, ua) / (float)nx, LD_ONE_BELOW);
  s.pdf = (marg[row + 1] - marg[row]) * (cond[col + 1] - cond[col]) * (float)(nx * ny);
  s.cell = col + nx * row;
  return s;
}

/* The density at a point of the light domain (the pdf a warp to x reports). */
BK_INLINE float ld_pdf_eval(const BK_GLOBAL float *table, int nx, int ny, float x, float y) {
  int col = bk_clampi((int)floor(x * (float)nx), 0, nx - 1);
  int row = bk_clampi((int)floor(y * (float)ny), 0, ny - 1);
  const BK_GLOBAL float *cond = table + (ny + 1) + row * (nx + 1);
  return (table[row + 1] - table[row]) * (cond[col + 1] - cond[col]) * (float)(nx * ny);
}

/* Inverse of ld_pdf_warp: the uniform point that warps to (x, y). Written
 * into *ua, *ub. */
BK_INLINE void ld_pdf_unwarp(const BK_GLOBAL float *table, int nx, int ny, float x, float y,
                             float *ua, float *ub) {
  float fy = y * (float)ny, fx = x * (float)nx;
  int row = bk_clampi((int)floor(fy), 0, ny - 1);
  int col = bk_clampi((int)floor(fx), 0, nx - 1);
  const BK_GLOBAL float *cond = table + (ny + 1) + row * (nx + 1);
  *ub = table[row] + (fy - (float)row) * (table[row + 1] - table[row]);
  *ua = cond[col] + (fx - (float)col) * (cond[col + 1] - cond[col]);
}

#endif
