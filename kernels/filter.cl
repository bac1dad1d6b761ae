/* filter.cl: the adaptive pipeline's reconstruction filter, one work-item per
 * voxel (the math is ad_filter_voxel in adaptive.h, shared with the host path
 * of baker/adaptive.c). Inputs: radiance (3 floats per voxel), photon count
 * and mean photon weight per voxel, the shell and weight tables. Outputs: the filtered
 * radiance and, when want_radius is set, the radius used (voxels, as float). */

/* No contraction into fma: the host path (C11, no fma) must produce the same
 * sums, or a near tie in the centre-surround test could pick another radius. */
#pragma OPENCL FP_CONTRACT OFF

#include "adaptive.h"

__kernel void ad_filter(__global const float *rgb, __global const uint *count,
                        __global const float *mean_weight, __global const int *shell_offsets,
                        __global const int *shell_start, __global const float *weights,
                        const bk_grid g, const float alpha,
                        const int rmax, const int want_radius, __global float *out_rgb,
                        __global float *out_radius) {
  int i = (int)get_global_id(0), j = (int)get_global_id(1), k = (int)get_global_id(2);
  if (i >= g.nx || j >= g.ny || k >= g.nz) return;
  float o[3];
  int r = ad_filter_voxel(rgb, count, mean_weight, shell_offsets, shell_start, weights, g, alpha,
                          rmax, i, j, k, o);
  bk_long v = (bk_long)i + (bk_long)g.nx * ((bk_long)j + (bk_long)g.ny * (bk_long)k);
  out_rgb[3 * v] = o[0];
  out_rgb[3 * v + 1] = o[1];
  out_rgb[3 * v + 2] = o[2];
  if (want_radius) out_radius[v] = (float)r;
}
