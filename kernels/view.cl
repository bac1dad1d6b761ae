/* view.cl: the viewing pass, one work-item per pixel (see view_march.h for the math).
 *
 * Specialised by the host with -D flags so that only what the file contains
 * is computed: HAS_REFRACTION (n varies: curved rays, else straight),
 * INTEGRATOR (0 Euler, 1 RK4), GREY (grey σt, packed with S = σs L̄ in one
 * float4), HOMOGENEOUS (RGB σt constant, passed in the parameters),
 * DISPERSION (n per channel: three rays per pixel, one per field), ANISO
 * (an anisotropic phase: the `aniso` and `aniso_s` fields, absent otherwise),
 * GREY_LIGHT (GREY, and grey light: the medium is {S, σt}, a float2). The
 * defaults below only serve the device-less compile check. */
#include "kernels/view_march.h"

#ifndef HAS_REFRACTION
#define HAS_REFRACTION 1
#endif
#ifndef INTEGRATOR
#define INTEGRATOR VIEW_EULER
#endif
#ifndef GREY
#define GREY 0
#endif
#ifndef HOMOGENEOUS
#define HOMOGENEOUS 0
#endif
#ifndef DISPERSION
#define DISPERSION 0
#endif
#ifndef ANISO
#define ANISO 0
#endif
#ifndef GREY_LIGHT
#define GREY_LIGHT 0
#endif

__kernel void view_render(const view_params_t p, __global const float *medium,
                          __global const float *sigma_t, __global const float *ng,
                          __global const uchar *npyr, __global const uchar *mpyr,
                          __global float *rgba, __global uint *steps,
                          __global const float *aniso, __global const float *aniso_s) {
  int px = (int)get_global_id(0), py = (int)get_global_id(1);
  if (px >= p.width || py >= p.height) return;
  view_fields f;
  f.medium = medium;
  f.sigma_t = sigma_t;
  f.ng = ng;
  f.npyr = npyr;
  f.mpyr = mpyr;
  f.aniso = aniso;
  f.aniso_s = aniso_s;
  view_flags fl;
  fl.refraction = HAS_REFRACTION;
  fl.grey = GREY;
  fl.integrator = INTEGRATOR;
  fl.homogeneous = HOMOGENEOUS;
  fl.dispersion = DISPERSION;
  fl.aniso = ANISO;
  fl.grey_light = GREY_LIGHT;
  float out[4];
  uint n;
  view_march_pixel(&p, f, fl, px, py, out, &n);
  size_t o = (size_t)py * (size_t)p.width + (size_t)px;
  vstore4((float4)(out[0], out[1], out[2], out[3]), o, rgba);
  steps[o] = n;
}
