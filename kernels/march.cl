/* march.cl: photon generation and marching, one work-item per photon (the
 * math is in photon_march.h and light_sample.h, shared with the host path). Launched in
 * chunks of photons [first, first + count); each work-item writes its
 * photon's pm_result for the host to count. Deposits are 64-bit fixed-point
 * integer atomics (cl_khr_int64_base_atomics): exact, order-independent sums,
 * where float compare-and-swap would be slow and lose small deposits. */
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
/* Host and device run the same float math: no fused multiply-adds here, so the
 * two paths round alike. */
#pragma OPENCL FP_CONTRACT OFF

#include "kernels/photon_march.h"

/* sigma: the volume's σt per metre (PM_SIGMA_STRIDE floats per voxel; with
 * PM_SIGMA_CODED the coded σs and σt, kernels/medium_code.h), unread when
 * HOMOGENEOUS. masks and tables serve the adaptive modes
 * (PM_MODE, march.h); the reference march never reads them. */
__kernel void pm_march(__constant pm_params *P, __constant ph_light *lights,
                       __global const float *ng, __global const uchar *pyr,
                       __global const float *sigma, __global ulong *acc, uint first, uint count,
                       __global pm_result *out, __global ulong *masks,
                       __global const float *tables) {
  uint i = (uint)get_global_id(0);
  if (i >= count) return;
  pm_result r;
  pm_march_photon(P, lights, ng, pyr, sigma, acc, masks, tables,
                  ph_photon_of_slot(lights, P->light_count, first + i), &r);
  out[i] = r;
}

/* For the precision test: every work-item adds `value` (already scaled to
 * quanta) `per_item` times to acc[0] through the march's deposit function. */
__kernel void pm_test_deposit(__global ulong *acc, float value, uint per_item) {
  for (uint k = 0; k < per_item; k++) pm_deposit(acc, value);
}
