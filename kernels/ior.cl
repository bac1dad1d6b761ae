/* ior.cl: the gradient grid of n, one work-item per voxel (the math is in
 * ior.h, shared with the host). Output: 3 floats per voxel (x y z, 1/m),
 * the layout ior_gradient_sample reads. */
#include "ior.h"

__kernel void ior_gradient(__global const float *n, const bk_grid g, __global float *grad) {
  int i = (int)get_global_id(0), j = (int)get_global_id(1), k = (int)get_global_id(2);
  if (i >= g.nx || j >= g.ny || k >= g.nz) return;
  bk_v3 d = ior_gradient_at(n, g, i, j, k);
  bk_long idx = 3 * ior_index(g, i, j, k);
  grad[idx] = d.x;
  grad[idx + 1] = d.y;
  grad[idx + 2] = d.z;
}
