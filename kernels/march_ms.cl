/* march_ms.cl: the photon march with multiple scattering, one work-item per
 * photon and its chain of legs (kernels/scatter_march.h). Built only for
 * scenes whose photons.bounces is above 0, with march.cl's -D flags and
 * -DMULTIPLE_SCATTERING=1, MS_SIGMA_GRID, MS_G_GRID, MS_HG; single-scattering
 * scenes build march.cl as before. Each work-item also writes its photon's
 * energy accounting (ms_tally) for the host to sum. */
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
#pragma OPENCL FP_CONTRACT OFF

/* The build always sets it; a default for the compile check alone. */
#ifndef MULTIPLE_SCATTERING
#define MULTIPLE_SCATTERING 1
#endif

#include "kernels/scatter_march.h"

__kernel void pm_march_ms(__constant pm_params *P, __constant ph_light *lights,
                          __global const float *ng, __global const uchar *pyr,
                          __global const float *sigma, __global ulong *acc, uint first,
                          uint count, __global pm_result *out, __global ulong *masks,
                          __global const float *tables, __constant ms_params *M,
                          __global const float *sigma_s, __global const float *g,
                          __global ms_tally *tally) {
  uint i = (uint)get_global_id(0);
  if (i >= count) return;
  pm_result r;
  ms_tally t;
  ms_medium med = {sigma_s, g};
  pm_march_scattered(P, M, lights, ng, pyr, sigma, med, acc, masks, tables,
                  ph_photon_of_slot(lights, P->light_count, first + i), &r, &t);
  out[i] = r;
  tally[i] = t;
}
