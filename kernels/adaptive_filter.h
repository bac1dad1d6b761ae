/* adaptive_filter.h: the reconstruction filter of the adaptive pipeline
 * (DESIGN.md §3 stage 6), shared by the host (baker/adaptive.c) and
 * kernels/filter.cl.
 *
 * Reconstruction filter (kernels/filter.cl; the host path of
 * baker/adaptive.c runs the same functions). Radii come in half voxels,
 * level q = 2 r: the mean at level q, M_q, is the Gaussian of standard
 * deviation r = q/2 voxels (the filter's radius) truncated at 2r = q voxels
 * along each axis (the cube |dx|, |dy|, |dz| <= q, clipped to the grid and
 * renormalised), M_0 the voxel itself. Per voxel:
 *   q_w  = round(2 alpha w_mean): the photon-weight radius alpha * w_mean
 *          to the nearest half voxel, w_mean the voxel's mean of w = 1/pdf
 *          over the photons that entered it (1 for uniform sampling); the
 *          largest level where no photon came (count 0);
 *   q_cs = the centre-surround level: with D(q) the mean over the
 *          (2 AD_FILTER_BOX + 1)^3 voxels around of the squared difference
 *          of luminance between levels q and q-1, grow q while
 *          D(q+1) < D(q), stop at the first increase (the larger mean reached
 *          something the smaller ones did not: an edge, a caustic). The
 *          first step, from the voxel itself to level 1, is taken when D(1)
 *          is within the voxel's noise, D(1) <= (noise_k lum(M_1) / count)^2:
 *          a caustic's peak or a voxel at an edge differs from its
 *          neighbourhood by more than its photons' noise and keeps its own
 *          value (noise_k < 0: always, the slides' rule);
 *   q    = min(q_w, q_cs, max level); output M_q in colour; radius q/2.
 * Why these choices, measured on the sphere scene against a converged bake
 * (scripts/bench_adaptive): the march's Hammersley photons leave a fine,
 * track-shaped noise that the differences of single voxels cannot tell from
 * structure (|M_2 - M_1| exceeded |M_1 - M_0| in 99% of smooth fog voxels,
 * so the rule on single voxels stopped at level 1 everywhere); averaged
 * over 5^3 voxels, the squared differences estimate what they should, noise
 * plus bias, and the rule grows where the noise falls faster than the bias
 * rises. Without the noise test of the first step the filter blurred the
 * caustic (its voxels are a sharp peak: every larger mean differs less from
 * the last one, so the rule alone keeps growing), 4x the error of the
 * unfiltered estimate. The noise scale 1/count, not 1/sqrt(count), because
 * Hammersley points converge about as 1/N. The truncation at 2 sigma cuts
 * off only e^-2 of a tap and e^-6 at the cube's corners, so the cube is as
 * good as a sphere and separable: M_q is computed one axis at a time for
 * every level at once (ad_blur_row_yz, ad_blur_row_x) in loops over whole
 * rows, 3 (2q+1) taps per level instead of (2q+1)^3, and the box means of
 * the differences the same way (ad_select_slice). The 1D weights are a
 * table (baker/adaptive.c) so host and device use the very same numbers. */
#ifndef BAKER_ADAPTIVE_FILTER_H
#define BAKER_ADAPTIVE_FILTER_H

#include "kernels/shared.h"

/* Largest filter level (radius 4 voxels). With the default PDF floor (1/2)
 * and alpha 1 the photon weights ask for radius 2 at most, the default
 * maximum (AD_DEFAULT_MAX_RADIUS, baker/adaptive.h). */
#define AD_FILTER_MAX_LEVEL 8
/* Gaussian of level q: standard deviation SIGMA * q voxels, truncated at q. */
#define AD_FILTER_SIGMA 0.5f
/* Half-width of the box over which the centre-surround differences are
 * averaged (5^3 voxels). */
#define AD_FILTER_BOX 2
/* Row length of the 1D weight table: weights[q * AD_WROW + |d|]. */
#define AD_WROW (AD_FILTER_MAX_LEVEL + 1)

/* Rec. 709 luminance: what the eye (and the centre-surround rule) sees. */
BK_INLINE float ad_luminance(float r, float g, float b) {
  return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}

/* --- the reconstruction filter ---------------------------------------------- */

/* The filter's passes work on rows: the nx voxels (nx * C floats) of one
 * (j, k), contiguous, so every loop below streams through memory and the
 * innermost one runs over the row with no branch (vectorised on both
 * sides). A pass computes every level r = 1..R: its input for level r is
 * in + (r-1) * in_plane (in_plane 0: one input for all), its output
 * out + (r-1) * out_plane (floats). Sums run over d in ascending order and
 * end with a multiply by the reciprocal of the clipped weight sum, the same
 * operations on host and device. */

/* 1 / (sum of the weights of radius r over offsets lo..hi). */
BK_INLINE float ad_inv_weight(const BK_GLOBAL float *weights, int r, int lo, int hi) {
  float ws = 0.0f;
  for (int d = lo; d <= hi; d++) ws += weights[r * AD_WROW + (d < 0 ? -d : d)];
  return 1.0f / ws;
}

/* The x means of one row of n voxels. */
BK_INLINE void ad_blur_row_x(const BK_GLOBAL float *in, bk_long in_plane, BK_GLOBAL float *out,
                             bk_long out_plane, const BK_GLOBAL float *weights, int n, int R,
                             int C) {
  for (int r = 1; r <= R; r++) {
    const BK_GLOBAL float *src = in + (bk_long)(r - 1) * in_plane;
    BK_GLOBAL float *o = out + (bk_long)(r - 1) * out_plane;
    /* the ends, clipped voxel by voxel */
    int ends = r < n ? r : n;
    for (int e = 0; e < 2 * ends; e++) {
      int i = e < ends ? e : n - 2 * ends + e;
      if (e >= ends && i < ends) continue; /* a row shorter than 2r: done by the first end */
      int lo = i - r < 0 ? -i : -r, hi = i + r > n - 1 ? n - 1 - i : r;
      float inv = ad_inv_weight(weights, r, lo, hi);
      for (int c = 0; c < C; c++) {
        float s = 0.0f;
        for (int d = lo; d <= hi; d++)
          s += weights[r * AD_WROW + (d < 0 ? -d : d)] * src[(i + d) * C + c];
        o[i * C + c] = s * inv;
      }
    }
    /* the interior: every offset -r..r */
    int q0 = r * C, q1 = (n - r) * C;
    if (q1 <= q0) continue;
    float inv = ad_inv_weight(weights, r, -r, r);
    for (int q = q0; q < q1; q++) o[q] = 0.0f;
    for (int d = -r; d <= r; d++) {
      float w = weights[r * AD_WROW + (d < 0 ? -d : d)];
      const BK_GLOBAL float *sv = src + d * C;
      for (int q = q0; q < q1; q++) o[q] += w * sv[q];
    }
    for (int q = q0; q < q1; q++) o[q] *= inv;
  }
}

/* The means along y or z of one row at coordinate pos (of n along that
 * axis), whose neighbours lie `stride` floats apart; rowlen = nx * C. */
BK_INLINE void ad_blur_row_yz(const BK_GLOBAL float *in, bk_long in_plane, BK_GLOBAL float *out,
                              bk_long out_plane, const BK_GLOBAL float *weights, int pos, int n,
                              bk_long stride, int rowlen, int R) {
  for (int r = 1; r <= R; r++) {
    const BK_GLOBAL float *src = in + (bk_long)(r - 1) * in_plane;
    BK_GLOBAL float *o = out + (bk_long)(r - 1) * out_plane;
    int lo = pos - r < 0 ? -pos : -r, hi = pos + r > n - 1 ? n - 1 - pos : r;
    float inv = ad_inv_weight(weights, r, lo, hi);
    for (int q = 0; q < rowlen; q++) o[q] = 0.0f;
    for (int d = lo; d <= hi; d++) {
      float w = weights[r * AD_WROW + (d < 0 ? -d : d)];
      const BK_GLOBAL float *sv = src + (bk_long)d * stride;
      for (int q = 0; q < rowlen; q++) o[q] += w * sv[q];
    }
    for (int q = 0; q < rowlen; q++) o[q] *= inv;
  }
}

/* Photon-weight level: alpha * mean weight in half voxels, rounded
 * (round(2 alpha w_mean)), the largest level where no photon came; NaN or
 * negative weights count as 0 (no filtering). */
BK_INLINE int ad_weight_level(float alpha, float mean_weight, float count, int qmax) {
  if (!(count > 0.0f)) return qmax;
  float q = 2.0f * alpha * mean_weight;
  if (!(q >= 0.0f)) return 0;
  if (q >= (float)qmax) return qmax;
  return (int)(q + 0.5f);
}

/* The luminance of the C floats at p (C = 1: the value itself, a grey march). */
BK_INLINE float ad_lum_at(const BK_GLOBAL float *p, int C) {
  return C == 3 ? ad_luminance(p[0], p[1], p[2]) : p[0];
}

/* Floats per voxel of scratch a filter work-item needs for its slice: the
 * larger of the means' (two sets of Q planes of C floats) and the
 * differences' (two sets of Q planes of 1 float). */
#define AD_SLICE_SCRATCH(nx, ny, C, Q) ((bk_long)(nx) * (bk_long)(ny) * 2 * (C) * (Q))
/* Floats of pass 1's output per voxel: M (Q levels of C floats) then DQ (Q
 * floats). */
#define AD_MEANS_FLOATS(C, Q) ((C) * (Q) + (Q))

/* Pass 1 of the filter, z-slice k: the Gaussian means of levels 1..Q of f
 * into M (Q planes of the whole grid, C floats per voxel, plane q-1 for level
 * q): z means of f (slices k-Q..k+Q) into scratch A, their y means into
 * scratch B (one slice each, so they stay in the cache), then the x means of
 * each row into M, and the squared luminance differences between levels,
 * (lum M_q - lum M_{q-1})^2 (M_0 = f), into DQ (Q planes of 1 float per
 * voxel) for pass 2's box means. */
BK_INLINE void ad_means_slice(const BK_GLOBAL float *f, const BK_GLOBAL float *weights,
                              BK_GLOBAL float *scratch, BK_GLOBAL float *M, BK_GLOBAL float *DQ,
                              const bk_grid g, int k, int Q, int C) {
  const int rowlen = g.nx * C;
  const bk_long S = (bk_long)g.ny * rowlen; /* floats per slice */
  const bk_long plane = S * g.nz;
  const bk_long base = (bk_long)k * S;
  BK_GLOBAL float *A = scratch, *B = scratch + (bk_long)Q * S;
  for (int j = 0; j < g.ny; j++)
    ad_blur_row_yz(f + base + (bk_long)j * rowlen, 0, A + (bk_long)j * rowlen, S, weights, k,
                   g.nz, S, rowlen, Q);
  for (int j = 0; j < g.ny; j++)
    ad_blur_row_yz(A + (bk_long)j * rowlen, S, B + (bk_long)j * rowlen, S, weights, j, g.ny,
                   rowlen, rowlen, Q);
  const bk_long nxyz = (bk_long)g.nx * g.ny * g.nz;
  for (int j = 0; j < g.ny; j++) {
    const bk_long row = base + (bk_long)j * rowlen, v0 = row / C;
    ad_blur_row_x(B + (bk_long)j * rowlen, S, M + row, plane, weights, g.nx, Q, C);
    for (int q = 1; q <= Q; q++) {
      const BK_GLOBAL float *hi = M + (bk_long)(q - 1) * plane + row;
      const BK_GLOBAL float *lo = q == 1 ? f + row : M + (bk_long)(q - 2) * plane + row;
      BK_GLOBAL float *o = DQ + (bk_long)(q - 1) * nxyz + v0;
      if (C == 1) {
        for (int i = 0; i < g.nx; i++) {
          float d = hi[i] - lo[i];
          o[i] = d * d;
        }
      } else {
        for (int i = 0; i < g.nx; i++) {
          float d = ad_lum_at(hi + 3 * i, 3) - ad_lum_at(lo + 3 * i, 3);
          o[i] = d * d;
        }
      }
    }
  }
}

/* Pass 2 of the filter, z-slice k (every slice of M and DQ complete): for
 * each level q the box mean over (2 AD_FILTER_BOX + 1)^3 voxels (clipped to
 * the grid) of the squared luminance difference between levels q and q-1
 * (level 0: f itself, DQ from pass 1),
 *   D(q) = box[(lum M_q - lum M_{q-1})^2],
 * then per voxel the level (this header's opening comment):
 *   q = 0; if q_w >= 1 and D(1) count^2 <= noise_k^2 lum(M_1)^2: q = 1,
 *   then while q < q_w and D(q+1) < D(q): q++
 * and out = M_q (f for q = 0), radius = q / 2 voxels. */
BK_INLINE void ad_select_slice(const BK_GLOBAL float *f, const BK_GLOBAL float *M,
                               const BK_GLOBAL float *DQ, const BK_GLOBAL float *count,
                               const BK_GLOBAL float *mean_weight,
                               BK_GLOBAL float *scratch, const bk_grid g, int k, float alpha,
                               float noise_k, int Q, int C, BK_GLOBAL float *out,
                               BK_GLOBAL float *radius) {
  const int h = AD_FILTER_BOX, nx = g.nx;
  const bk_long nxy = (bk_long)nx * g.ny; /* voxels per slice */
  const bk_long plane = nxy * g.nz * C;  /* floats per level of M */
  BK_GLOBAL float *Sa = scratch, *Sb = scratch + (bk_long)Q * nxy;
  /* z: the squared differences of slices k-h..k+h, summed */
  const int z0 = k - h < 0 ? 0 : k - h, z1 = k + h > g.nz - 1 ? g.nz - 1 : k + h;
  const float inv_z = 1.0f / (float)(z1 - z0 + 1);
  const bk_long nxyz = nxy * g.nz;
  for (int q = 1; q <= Q; q++) {
    BK_GLOBAL float *o = Sa + (bk_long)(q - 1) * nxy;
    const BK_GLOBAL float *dq = DQ + (bk_long)(q - 1) * nxyz;
    for (int v = 0; v < (int)nxy; v++) o[v] = 0.0f;
    for (int z = z0; z <= z1; z++) {
      const BK_GLOBAL float *pz = dq + (bk_long)z * nxy;
      for (int v = 0; v < (int)nxy; v++) o[v] += pz[v];
    }
    for (int v = 0; v < (int)nxy; v++) o[v] *= inv_z;
  }
  /* y */
  for (int q = 1; q <= Q; q++)
    for (int j = 0; j < g.ny; j++) {
      const int y0 = j - h < 0 ? 0 : j - h, y1 = j + h > g.ny - 1 ? g.ny - 1 : j + h;
      const float inv_y = 1.0f / (float)(y1 - y0 + 1);
      BK_GLOBAL float *o = Sb + (bk_long)(q - 1) * nxy + (bk_long)j * nx;
      const BK_GLOBAL float *src = Sa + (bk_long)(q - 1) * nxy;
      for (int i = 0; i < nx; i++) o[i] = 0.0f;
      for (int y = y0; y <= y1; y++)
        for (int i = 0; i < nx; i++) o[i] += src[(bk_long)y * nx + i];
      for (int i = 0; i < nx; i++) o[i] *= inv_y;
    }
  /* x, row by row (into the start of Sa, free by now), and the choice */
  for (int j = 0; j < g.ny; j++) {
    const bk_long v0 = (bk_long)k * nxy + (bk_long)j * nx; /* the row's first voxel */
    for (int q = 1; q <= Q; q++) {
      const BK_GLOBAL float *src = Sb + (bk_long)(q - 1) * nxy + (bk_long)j * nx;
      BK_GLOBAL float *o = Sa + (bk_long)(q - 1) * nx;
      /* the ends clipped, the interior as one branch-free loop */
      for (int e = 0; e < 2 * h && e < nx; e++) {
        const int i = e < h ? e : nx - 2 * h + e;
        if (e >= h && i < h) continue; /* a row shorter than 2h */
        const int x0 = i - h < 0 ? 0 : i - h, x1 = i + h > nx - 1 ? nx - 1 : i + h;
        float sum = 0.0f;
        for (int x = x0; x <= x1; x++) sum += src[x];
        o[i] = sum * (1.0f / (float)(x1 - x0 + 1));
      }
      const float inv_x = 1.0f / (float)(2 * h + 1);
      for (int i = h; i < nx - h; i++) {
        float sum = 0.0f;
        for (int d = -h; d <= h; d++) sum += src[i + d];
        o[i] = sum * inv_x;
      }
    }
    for (int i = 0; i < nx; i++) {
      const bk_long v = v0 + i;
      const int q_w = ad_weight_level(alpha, mean_weight[v], count[v], Q);
      int q = 0;
      if (q_w >= 1) {
        const float m1 = ad_lum_at(M + v * C, C), d1 = Sa[i], n = count[v];
        /* the first step against the voxel's noise, compared squared */
        if (noise_k < 0.0f || d1 * n * n <= noise_k * noise_k * m1 * m1) {
          q = 1;
          while (q < q_w && Sa[(bk_long)q * nx + i] < Sa[(bk_long)(q - 1) * nx + i]) q++;
        }
      }
      const BK_GLOBAL float *src = q == 0 ? f + v * C : M + (bk_long)(q - 1) * plane + v * C;
      for (int c = 0; c < C; c++) out[v * C + c] = src[c];
      if (radius) radius[v] = 0.5f * (float)q;
    }
  }
}

#endif
