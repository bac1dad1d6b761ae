/* adaptive.h: math of the adaptive pipeline (DESIGN.md §3 stage 6), shared by
 * the host C code and the OpenCL kernels.
 *
 * Light domain. Every light maps a 2D point (a, b) in [0,1)^2 to a photon
 * origin and direction (kernels/photons.h; (a, b) is the point after the
 * Cranley–Patterson rotation, the one the generator actually uses). The
 * domain is split into AD_CELLS_X x AD_CELLS_Y = 64 cells; cell
 * c = cx + AD_CELLS_X * cy with cx = floor(a * AD_CELLS_X), cy = floor(b *
 * AD_CELLS_Y) (ad_cell_of). 64 cells so that the origin data fits one 64-bit
 * mask per voxel per light.
 *
 * Origin data (phase 1, pilot photons). An array of bk_ulong masks, light
 * major: masks[ad_origin_index(voxel, light, voxels)], voxel = the grid's
 * x-fastest index. A pilot photon from cell c sets bit c of every voxel it
 * crosses (ad_origin_mark: atom_or on the device, an atomic fetch-or on the
 * host).
 *
 * PDF (phase 2). A piecewise-constant density over nx x ny cells, stored as a
 * table of AD_TABLE_FLOATS(nx, ny) floats:
 *   table[0 .. ny]                              marginal CDF over rows (b),
 *                                               table[0] = 0, table[ny] = 1
 *   table[ny+1 + r*(nx+1) + 0 .. nx]            conditional CDF over the
 *                                               columns (a) of row r
 * ad_pdf_warp maps a uniform point u (a Hammersley point) to x: it inverts the
 * marginal CDF for the row, then the row's conditional CDF for the column, and
 * places x linearly (so uniformly) inside the cell. The map is monotone in each
 * coordinate and piecewise linear, a bijection of [0,1)^2 up to float
 * rounding (ad_pdf_unwarp is its inverse), and the density of x is
 *   pdf(x) = P(row) * P(col | row) * nx * ny
 * with respect to the uniform measure on [0,1)^2 (so the uniform density is 1).
 * A photon drawn this way carries the weight 1/(N pdf(x)) in place of 1/N:
 * its power is the light's power/N times w = 1/pdf(x), and the estimate is
 * unbiased wherever pdf > 0 (baker/adaptive.c puts a floor under it).
 *
 * Reconstruction filter (ad_filter_voxel, kernels/filter.cl). Per voxel:
 *   r_w  = round(alpha * w_mean), w_mean the voxel's mean of w = 1/pdf over
 *          the photons that crossed it (1 for uniform sampling), the maximum
 *          radius where no photon came (count 0);
 *   r_cs = centre-surround radius: with m(r) the (Gaussian-weighted, below)
 *          mean luminance over the sphere |d| <= r (in voxels, clipped to
 *          the grid), start at r = 1
 *          and grow r while |m(r+1) - m(r)| < |m(r) - m(r-1)|; stop at the
 *          first increase (the sphere r+1 reached something the smaller ones
 *          did not: an edge);
 *   R    = min(r_w, r_cs, max radius); output = m(R) in colour.
 * R = 0 keeps the voxel's own value. The means are Gaussian-weighted over the
 * sphere, weight exp(-|d|^2 / (2 (AD_FILTER_SIGMA r)^2)), for two reasons a
 * box mean lacks (measured on tests/test_adaptive.c's caustic step, sparsely
 * sampled, 10% noise): at r = 1 a voxel next to an edge takes 11% of its
 * value from across the edge instead of 1/7, and the first comparison
 * |m(2) - m(1)| < |m(1) - m(0)| then tells an edge from noise (with box means
 * it is nearly a coin toss there: mean error 21% of the step against 11%),
 * for 10% less noise reduction in smooth regions. The offsets come from a
 * table ordered by shell (shell 0 the centre, shell r >= 1 the offsets with
 * (r-1)^2 < |d|^2 <= r^2), so the sphere of radius r is a prefix of it; the
 * weights are a table too, per radius and squared length (baker/adaptive.c
 * builds both), so host and device use the very same numbers. */
#ifndef BAKER_AD_KERNEL_H
#define BAKER_AD_KERNEL_H

#include "shared.h"

#define AD_CELLS_X 8
#define AD_CELLS_Y 8
#define AD_CELLS (AD_CELLS_X * AD_CELLS_Y) /* 64: one 64-bit origin mask */
/* Floats in a PDF table of nx x ny cells (see the header comment). */
#define AD_TABLE_FLOATS(nx, ny) ((ny) + 1 + (ny) * ((nx) + 1))
/* The largest float below 1: warped points stay in [0,1). */
#define AD_ONE_BELOW 0.99999994f
/* Largest filter radius, in voxels: a sphere of 2109 voxels. Beyond it one
 * voxel's filter costs more than the march spent on it; with the default PDF
 * floor (1/4) and alpha 1 the photon weights ask for 4 at most. */
#define AD_FILTER_MAX_RADIUS 8
/* Gaussian weights of the filter's means: standard deviation SIGMA * r over
 * the sphere of radius r (see the header comment). */
#define AD_FILTER_SIGMA 0.7f

/* Rec. 709 luminance: what the eye (and the centre-surround rule) sees. */
BK_INLINE float ad_luminance(float r, float g, float b) {
  return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}

/* --- origin data ------------------------------------------------------------ */

/* Cell of the light-domain point (a, b); points outside [0,1) are clamped to
 * the edge cells. a * 8 is exact in float, so cells have exact edges. */
BK_INLINE int ad_cell_of(float a, float b) {
  int cx = bk_clampi((int)floor(a * (float)AD_CELLS_X), 0, AD_CELLS_X - 1);
  int cy = bk_clampi((int)floor(b * (float)AD_CELLS_Y), 0, AD_CELLS_Y - 1);
  return cx + AD_CELLS_X * cy;
}

BK_INLINE bk_ulong ad_cell_bit(int cell) { return ((bk_ulong)1) << cell; }

/* Index of (voxel, light) in the origin-mask array: light major, so the masks
 * of one light are one contiguous block of `voxels` entries. */
BK_INLINE bk_long ad_origin_index(bk_long voxel, int light, bk_long voxels) {
  return (bk_long)light * voxels + voxel;
}

/* Sets the bit of `cell` in masks[index]. Bits are only ever set, so a plain
 * read that finds the bit already set is final and saves the atomic (most
 * voxels are crossed by many photons of the same cell). */
#ifdef __OPENCL_VERSION__
#if defined(cl_khr_int64_extended_atomics)
#pragma OPENCL EXTENSION cl_khr_int64_extended_atomics : enable
#define AD_HAS_ORIGIN_MARK 1
BK_INLINE void ad_origin_mark(volatile __global ulong *masks, bk_long index, int cell) {
  ulong bit = ad_cell_bit(cell);
  if ((masks[index] & bit) == 0) atom_or(&masks[index], bit);
}
#endif
#else
#define AD_HAS_ORIGIN_MARK 1
BK_INLINE void ad_origin_mark(bk_ulong *masks, bk_long index, int cell) {
  bk_ulong bit = ad_cell_bit(cell);
  if ((__atomic_load_n(&masks[index], __ATOMIC_RELAXED) & bit) == 0)
    __atomic_fetch_or(&masks[index], bit, __ATOMIC_RELAXED);
}
#endif

/* --- the PDF warp ----------------------------------------------------------- */

typedef struct ad_sample {
  float x, y;  /* the warped point in [0,1)^2 */
  float pdf;   /* its density w.r.t. the uniform measure (uniform = 1) */
  int cell;    /* col + nx * row of the cell x lies in */
} ad_sample;

/* The interval i in [0, n) with cdf[i] <= u < cdf[i+1], for a CDF of n+1
 * entries from 0 to 1 and u in [0,1). Zero-width intervals are never chosen. */
BK_INLINE int ad_cdf_find(const BK_GLOBAL float *cdf, int n, float u) {
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
 * probability the pdf reports ((i+1) * AD_ONE_BELOW rounds below i + 1). */
BK_INLINE float ad_cdf_place(const BK_GLOBAL float *cdf, int i, float u) {
  float w = cdf[i + 1] - cdf[i];
  float t = w > 0.0f ? (u - cdf[i]) / w : 0.0f;
  float s = (float)i + bk_clampf(t, 0.0f, 1.0f);
  return fmin(s, (float)(i + 1) * AD_ONE_BELOW);
}

/* Warps the uniform point (ua, ub) through the PDF table of nx x ny cells. */
BK_INLINE ad_sample ad_pdf_warp(const BK_GLOBAL float *table, int nx, int ny, float ua,
                                float ub) {
  ad_sample s;
  ua = bk_clampf(ua, 0.0f, AD_ONE_BELOW);
  ub = bk_clampf(ub, 0.0f, AD_ONE_BELOW);
  const BK_GLOBAL float *marg = table;
  int row = ad_cdf_find(marg, ny, ub);
  const BK_GLOBAL float *cond = table + (ny + 1) + row * (nx + 1);
  int col = ad_cdf_find(cond, nx, ua);
  s.y = fmin(ad_cdf_place(marg, row, ub) / (float)ny, AD_ONE_BELOW);
  s.x = fmin(ad_cdf_place(cond, col, ua) / (float)nx, AD_ONE_BELOW);
  s.pdf = (marg[row + 1] - marg[row]) * (cond[col + 1] - cond[col]) * (float)(nx * ny);
  s.cell = col + nx * row;
  return s;
}

/* The density at a point of the light domain (the pdf a warp to x reports). */
BK_INLINE float ad_pdf_eval(const BK_GLOBAL float *table, int nx, int ny, float x, float y) {
  int col = bk_clampi((int)floor(x * (float)nx), 0, nx - 1);
  int row = bk_clampi((int)floor(y * (float)ny), 0, ny - 1);
  const BK_GLOBAL float *cond = table + (ny + 1) + row * (nx + 1);
  return (table[row + 1] - table[row]) * (cond[col + 1] - cond[col]) * (float)(nx * ny);
}

/* Inverse of ad_pdf_warp: the uniform point that warps to (x, y). Written
 * into *ua, *ub. */
BK_INLINE void ad_pdf_unwarp(const BK_GLOBAL float *table, int nx, int ny, float x, float y,
                             float *ua, float *ub) {
  float fy = y * (float)ny, fx = x * (float)nx;
  int row = bk_clampi((int)floor(fy), 0, ny - 1);
  int col = bk_clampi((int)floor(fx), 0, nx - 1);
  const BK_GLOBAL float *cond = table + (ny + 1) + row * (nx + 1);
  *ub = table[row] + (fy - (float)row) * (table[row + 1] - table[row]);
  *ua = cond[col] + (fx - (float)col) * (cond[col + 1] - cond[col]);
}

/* --- the reconstruction filter ---------------------------------------------- */

/* Photon-weight radius: round(alpha * mean weight), the maximum where no
 * photon came; NaN or negative weights count as 0 (no filtering). */
BK_INLINE int ad_weight_radius(float alpha, float mean_weight, bk_uint count, int rmax) {
  if (count == 0) return rmax;
  float r = alpha * mean_weight;
  if (!(r >= 0.0f)) return 0;
  if (r >= (float)rmax) return rmax;
  return (int)(r + 0.5f);
}

/* Per-voxel sums of the radiance by squared offset length q = |d|^2: the
 * Gaussian weight depends on q only, so the mean over any sphere r is a short
 * sum over q <= r^2 of these, and growing the sphere only adds its new shell.
 * The cost is then that of the largest sphere visited, not the sum of all. */
#define AD_Q_MAX (AD_FILTER_MAX_RADIUS * AD_FILTER_MAX_RADIUS)
typedef struct ad_qsums {
  float s0[AD_Q_MAX + 1], s1[AD_Q_MAX + 1], s2[AD_Q_MAX + 1]; /* RGB sums */
  float n[AD_Q_MAX + 1];                                      /* in-grid voxels */
  int shells;                                                 /* shells added so far */
} ad_qsums;

/* Adds the in-grid voxels of shells q->shells + 1 .. r to the sums. */
BK_INLINE void ad_qsums_grow(ad_qsums *q, const BK_GLOBAL float *rgb,
                             const BK_GLOBAL int *shell_offsets, const BK_GLOBAL int *shell_start,
                             const bk_grid g, int i, int j, int k, int r) {
  if (r <= q->shells) return;
  for (int s = shell_start[q->shells + 1]; s < shell_start[r + 1]; s++) {
    int dx = shell_offsets[3 * s], dy = shell_offsets[3 * s + 1], dz = shell_offsets[3 * s + 2];
    int x = i + dx, y = j + dy, z = k + dz;
    if (x < 0 || y < 0 || z < 0 || x >= g.nx || y >= g.ny || z >= g.nz) continue;
    bk_long v = (bk_long)x + (bk_long)g.nx * ((bk_long)y + (bk_long)g.ny * (bk_long)z);
    int d2 = dx * dx + dy * dy + dz * dz;
    q->s0[d2] += rgb[3 * v];
    q->s1[d2] += rgb[3 * v + 1];
    q->s2[d2] += rgb[3 * v + 2];
    q->n[d2] += 1.0f;
  }
  q->shells = r;
}

/* Gaussian-weighted mean colour over the sphere of radius r (its shells must
 * be in the sums) into out[0..2]; returns its luminance. weights[r * (AD_Q_MAX
 * + 1) + q] is the weight of squared length q in the sphere of radius r. */
BK_INLINE float ad_qsums_mean(const ad_qsums *q, const BK_GLOBAL float *weights, int r,
                              float *out) {
  const BK_GLOBAL float *w = weights + r * (AD_Q_MAX + 1);
  float s0 = 0.0f, s1 = 0.0f, s2 = 0.0f, sw = 0.0f;
  for (int d2 = 0; d2 <= r * r; d2++) {
    float wq = w[d2];
    s0 += wq * q->s0[d2];
    s1 += wq * q->s1[d2];
    s2 += wq * q->s2[d2];
    sw += wq * q->n[d2];
  }
  float inv = 1.0f / sw; /* the centre is always in the grid, with weight 1 */
  out[0] = s0 * inv;
  out[1] = s1 * inv;
  out[2] = s2 * inv;
  return ad_luminance(out[0], out[1], out[2]);
}

/* Filters voxel (i,j,k): writes the filtered RGB into out[0..2] and returns
 * the radius R used. rgb: 3 floats per voxel; count, mean_weight: one per
 * voxel; the shell and weight tables (baker/adaptive.c) must cover rmax
 * (<= AD_FILTER_MAX_RADIUS). m(r+1) is only computed while r < r_w, so the
 * cost is that of the sphere of radius min(r_w, r_cs + 1). */
BK_INLINE int ad_filter_voxel(const BK_GLOBAL float *rgb, const BK_GLOBAL bk_uint *count,
                              const BK_GLOBAL float *mean_weight,
                              const BK_GLOBAL int *shell_offsets,
                              const BK_GLOBAL int *shell_start, const BK_GLOBAL float *weights,
                              const bk_grid g, float alpha, int rmax, int i, int j, int k,
                              float *out) {
  bk_long v = (bk_long)i + (bk_long)g.nx * ((bk_long)j + (bk_long)g.ny * (bk_long)k);
  int r_w = ad_weight_radius(alpha, mean_weight[v], count[v], rmax);
  out[0] = rgb[3 * v];
  out[1] = rgb[3 * v + 1];
  out[2] = rgb[3 * v + 2];
  if (r_w < 1) return 0;
  ad_qsums q;
  for (int d2 = 0; d2 <= r_w * r_w; d2++) q.s0[d2] = q.s1[d2] = q.s2[d2] = q.n[d2] = 0.0f;
  q.s0[0] = out[0];
  q.s1[0] = out[1];
  q.s2[0] = out[2];
  q.n[0] = 1.0f;
  q.shells = 0;
  float m_prev = ad_luminance(out[0], out[1], out[2]); /* m(0) */
  float next[3];
  ad_qsums_grow(&q, rgb, shell_offsets, shell_start, g, i, j, k, 1);
  float m_cur = ad_qsums_mean(&q, weights, 1, out);
  float d_prev = fabs(m_cur - m_prev);
  int r = 1;
  while (r < r_w) {
    ad_qsums_grow(&q, rgb, shell_offsets, shell_start, g, i, j, k, r + 1);
    float m_next = ad_qsums_mean(&q, weights, r + 1, next);
    float d = fabs(m_next - m_cur);
    if (!(d < d_prev)) break; /* the first increase: stop at r */
    r++;
    out[0] = next[0];
    out[1] = next[1];
    out[2] = next[2];
    m_cur = m_next;
    d_prev = d;
  }
  return r;
}

#endif
