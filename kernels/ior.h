/* ior.h: the gradient of the refractive index field, for host and device.
 *
 * In: n(x), one float per voxel (cell-centred, x-fastest, bk_grid layout).
 * Out: ∇n in 1/m (world units), the force term of the ray equation
 * d/ds(n dx/ds) = ∇n. At a voxel it is the central difference
 * (n[i+1] - n[i-1]) / (2h), second-order accurate (error h²/6 n'''); on the
 * grid's faces it is one-sided, (n[1] - n[0]) / h, first order; an axis one
 * voxel thick has no gradient along it. Between voxel centres the gradient is
 * interpolated trilinearly, either from a precomputed gradient grid (3 floats
 * per voxel, what ior_gradient in ior.cl writes) or straight from n. Both give
 * the same numbers, so the photon march may trade memory for lookups.
 *
 * Indices are 64-bit here: a grid past 2^31 voxels fits in memory on big
 * machines and int indices would wrap. */
#ifndef BAKER_IOR_H
#define BAKER_IOR_H

#include "shared.h"

BK_INLINE bk_long ior_index(const bk_grid g, int i, int j, int k) {
  return (bk_long)i + (bk_long)g.nx * ((bk_long)j + (bk_long)g.ny * (bk_long)k);
}

/* Voxel coordinate of a world point (voxel i spans [i, i+1)). */
BK_INLINE bk_v3 ior_voxel_coord(const bk_grid g, bk_v3 x) {
  float s = 1.0f / g.voxel_size;
  return v3((x.x - g.origin_x) * s, (x.y - g.origin_y) * s, (x.z - g.origin_z) * s);
}

/* d n / d(axis) at index c of an axis of `count` voxels whose stride is
 * `stride` floats: central inside, one-sided on the faces. */
BK_INLINE float ior_diff_axis(const BK_GLOBAL float *n, bk_long base, bk_long stride, int c,
                              int count, float inv_h) {
  if (count < 2) return 0.0f;
  if (c == 0) return (n[base + stride] - n[base]) * inv_h;
  if (c == count - 1) return (n[base] - n[base - stride]) * inv_h;
  return (n[base + stride] - n[base - stride]) * (0.5f * inv_h);
}

/* ∇n at the centre of voxel (i,j,k), in 1/m. (i,j,k) must be inside the grid. */
BK_INLINE bk_v3 ior_gradient_at(const BK_GLOBAL float *n, const bk_grid g, int i, int j, int k) {
  float inv_h = 1.0f / g.voxel_size;
  bk_long base = ior_index(g, i, j, k);
  bk_long sy = (bk_long)g.nx, sz = (bk_long)g.nx * (bk_long)g.ny;
  return v3(ior_diff_axis(n, base, 1, i, g.nx, inv_h), ior_diff_axis(n, base, sy, j, g.ny, inv_h),
            ior_diff_axis(n, base, sz, k, g.nz, inv_h));
}

/* The eight voxels around voxel coordinate u and their trilinear weights,
 * clamped to the edge voxels like bk_sample_trilinear. */
typedef struct ior_corners {
  int i[2], j[2], k[2];
  float tx, ty, tz;
} ior_corners;

BK_INLINE ior_corners ior_corners_at(const bk_grid g, bk_v3 u) {
  ior_corners c;
  float fx = u.x - 0.5f, fy = u.y - 0.5f, fz = u.z - 0.5f;
  float flx = floor(fx), fly = floor(fy), flz = floor(fz);
  int i0 = (int)flx, j0 = (int)fly, k0 = (int)flz;
  c.tx = fx - flx;
  c.ty = fy - fly;
  c.tz = fz - flz;
  c.i[0] = bk_clampi(i0, 0, g.nx - 1); c.i[1] = bk_clampi(i0 + 1, 0, g.nx - 1);
  c.j[0] = bk_clampi(j0, 0, g.ny - 1); c.j[1] = bk_clampi(j0 + 1, 0, g.ny - 1);
  c.k[0] = bk_clampi(k0, 0, g.nz - 1); c.k[1] = bk_clampi(k0 + 1, 0, g.nz - 1);
  return c;
}

BK_INLINE float ior_corner_weight(const ior_corners c, int a, int b, int d) {
  return (a ? c.tx : 1.0f - c.tx) * (b ? c.ty : 1.0f - c.ty) * (d ? c.tz : 1.0f - c.tz);
}

/* ∇n at voxel coordinate u from a precomputed gradient grid (3 floats per
 * voxel, x y z), trilinear between voxel centres. */
BK_INLINE bk_v3 ior_gradient_sample(const BK_GLOBAL float *grad, const bk_grid g, bk_v3 u) {
  ior_corners c = ior_corners_at(g, u);
  bk_v3 r = v3(0.0f, 0.0f, 0.0f);
  for (int d = 0; d < 2; d++)
    for (int b = 0; b < 2; b++)
      for (int a = 0; a < 2; a++) {
        bk_long idx = 3 * ior_index(g, c.i[a], c.j[b], c.k[d]);
        r = v3_madd(r, v3(grad[idx], grad[idx + 1], grad[idx + 2]), ior_corner_weight(c, a, b, d));
      }
  return r;
}

/* The same interpolation computed straight from n (no gradient grid, six
 * more lookups per corner). */
BK_INLINE bk_v3 ior_gradient_trilinear(const BK_GLOBAL float *n, const bk_grid g, bk_v3 u) {
  ior_corners c = ior_corners_at(g, u);
  bk_v3 r = v3(0.0f, 0.0f, 0.0f);
  for (int d = 0; d < 2; d++)
    for (int b = 0; b < 2; b++)
      for (int a = 0; a < 2; a++)
        r = v3_madd(r, ior_gradient_at(n, g, c.i[a], c.j[b], c.k[d]), ior_corner_weight(c, a, b, d));
  return r;
}

#endif
