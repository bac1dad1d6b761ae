/* filter.cl: the adaptive pipeline's reconstruction filter (the math is
 * ad_means_slice and ad_select_slice in adaptive.h, shared with the host path
 * of baker/adaptive.c), two launches: ad_means writes the Gaussian means of
 * every level into M, then ad_select (which reads neighbouring slices of M)
 * writes the filtered radiance and, when want_radius is set, the radius used
 * (voxels, as float). Work-item w of W takes the z-slices w, w + W, ... with
 * its own scratch (AD_SLICE_SCRATCH floats at w times that); launched as
 * work-groups of one so they spread over the compute units, and on a CPU
 * with W a few times the compute units, so the scratch is a few slices that
 * stay in the cache. AD_CH (1 or 3 floats per voxel) and AD_QMAX (the
 * largest level, the number of planes of M) are -D flags. */

/* No contraction into fma: the host path (C11, no fma) must produce the same
 * sums, or a near tie in the centre-surround test could pick another radius. */
#pragma OPENCL FP_CONTRACT OFF

#include "kernels/adaptive_filter.h"

#ifndef AD_CH
#define AD_CH 3
#endif
#ifndef AD_QMAX
#define AD_QMAX 4
#endif

/* M holds the means (AD_QMAX levels of AD_CH floats per voxel) followed by
 * the squared differences (AD_QMAX planes of 1 float). */
__kernel void ad_means(__global const float *f, __global const float *weights,
                       __global float *scratch, __global float *M, const bk_grid g) {
  int w = (int)get_global_id(0), items = (int)get_global_size(0);
  __global float *mine = scratch + (bk_long)w * AD_SLICE_SCRATCH(g.nx, g.ny, AD_CH, AD_QMAX);
  __global float *DQ = M + (bk_long)g.nx * g.ny * g.nz * AD_CH * AD_QMAX;
  for (int k = w; k < g.nz; k += items)
    ad_means_slice(f, weights, mine, M, DQ, g, k, AD_QMAX, AD_CH);
}

__kernel void ad_select(__global const float *f, __global const float *M,
                        __global const float *count, __global const float *mean_weight,
                        __global float *scratch, const bk_grid g, const float alpha,
                        const float noise_k, const int want_radius, __global float *out_rgb,
                        __global float *out_radius) {
  int w = (int)get_global_id(0), items = (int)get_global_size(0);
  __global float *mine = scratch + (bk_long)w * AD_SLICE_SCRATCH(g.nx, g.ny, AD_CH, AD_QMAX);
  __global const float *DQ = M + (bk_long)g.nx * g.ny * g.nz * AD_CH * AD_QMAX;
  for (int k = w; k < g.nz; k += items)
    ad_select_slice(f, M, DQ, count, mean_weight, mine, g, k, alpha, noise_k, AD_QMAX, AD_CH,
                    out_rgb, want_radius ? out_radius : 0);
}
