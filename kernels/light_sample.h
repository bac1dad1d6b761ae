/* light_sample.h: photon generation from a photon index, shared by host and device.
 *
 * In: a light prepared on the host (ph_light, in voxel coordinates: u = (x -
 * origin) / voxel_size) and the photon's index k within that light's share of
 * the photons. Out: the photon's origin, unit direction and power. Nothing is
 * stored per photon: the march kernel calls ph_sample with its own index, and
 * the host path calls the very same function.
 *
 * The 2D point is Hammersley, (k / count, radical inverse base 2 of k), with a
 * Cranley–Patterson rotation (a, b) -> fract(a + r_u, b + r_v) derived from
 * the scene seed (ph_light.rot_u, rot_v), so that different seeds give
 * different but equally well stratified sets.
 *  - directional: a rectangle perpendicular to the direction that covers the
 *    grid's projection, placed one voxel before the grid; origin = corner +
 *    a U + b V. Power per photon E A / N (A the rectangle's area in m^2).
 *  - spot: uniform in solid angle within the cone of half angle theta:
 *    cos t = 1 - a (1 - cos theta), phi = 2 pi b. Power I Omega / N with
 *    Omega = 2 pi (1 - cos theta).
 *  - point: the same with cos theta = -1 (whole sphere), power I 4 pi / N.
 * Photons that start outside the grid are advanced to where they enter it
 * (rc_slab, kernels/ray_core.h); those that never hit it are counted as missed. */
#ifndef BAKER_LIGHT_SAMPLE_H
#define BAKER_LIGHT_SAMPLE_H

#include "kernels/shared.h"

#if defined(__OPENCL_VERSION__) || defined(__OPENCL_C_VERSION__)
#define PH_DEVICE 1
/* a kernel built without LIGHT_* flags keeps every generator */
#if !defined(LIGHT_DIRECTIONAL) && !defined(LIGHT_SPOT) && !defined(LIGHT_POINT)
#define LIGHT_DIRECTIONAL 1
#define LIGHT_SPOT 1
#define LIGHT_POINT 1
#endif
#else
#define PH_DEVICE 0
#endif

/* ph_light.type: the rows of light_kinds[] (baker/lights.h), whose `define`
 * names the LIGHT_* flag above */
#define PH_DIRECTIONAL 0
#define PH_SPOT 1
#define PH_POINT 2

/* One light as the march sees it. Plain floats so the layout is the same in
 * C and OpenCL C; pinned at 96 bytes. */
typedef struct ph_light {
  float px, py, pz; /* spot, point: position; directional: rectangle corner */
  int type;         /* PH_DIRECTIONAL, PH_SPOT, PH_POINT */
  float dx, dy, dz; /* unit direction (spot axis, directional direction) */
  float cos_max;    /* spot: cos of the half angle; point: -1 */
  float ux, uy, uz; /* directional: rectangle edge U (voxels); spot/point: unit basis vector */
  float rot_u;      /* Cranley–Patterson rotation of the first coordinate */
  float vx, vy, vz; /* directional: rectangle edge V (voxels); spot/point: unit basis vector */
  float rot_v;      /* ... and of the second */
  float power[3];   /* W per photon, RGB (grey kernels use power[0] only) */
  bk_uint first;    /* this light's photons are [first, first + count) */
  bk_uint count;
  bk_uint tile_rows;    /* launch order (ph_launch_plan): Q, 0 keeps index order */
  bk_uint tile_stride;  /* ... and the stride between consecutive tiles */
  bk_uint pad;
} ph_light;
BK_STATIC_ASSERT(sizeof(ph_light) == 96, "ph_light layout is shared with kernels");

/* Radical inverse base 2 of k in [0, 1): the bits of k mirrored about the
 * binary point. 24 bits are kept so the float is exact and below 1. */
BK_INLINE float ph_radical_inverse2(bk_uint k) {
  k = (k << 16) | (k >> 16);
  k = ((k & 0x00ff00ffu) << 8) | ((k & 0xff00ff00u) >> 8);
  k = ((k & 0x0f0f0f0fu) << 4) | ((k & 0xf0f0f0f0u) >> 4);
  k = ((k & 0x33333333u) << 2) | ((k & 0xccccccccu) >> 2);
  k = ((k & 0x55555555u) << 1) | ((k & 0xaaaaaaaau) >> 1);
  return (float)(k >> 8) * (1.0f / 16777216.0f);
}

/* x + r wrapped into [0, 1) for x, r in [0, 1). */
BK_INLINE float ph_rotate(float x, float r) {
  float y = x + r;
  y = y >= 1.0f ? y - 1.0f : y;
  return y < 1.0f ? y : 0.99999994f; /* float rounding of x + r - 1 can give 1 */
}

/* The rotated Hammersley point k of n. */
BK_INLINE void ph_hammersley(bk_uint k, bk_uint n, float rot_u, float rot_v, float *a, float *b) {
  float u = (float)k / (float)n;
  *a = ph_rotate(u < 1.0f ? u : 0.99999994f, rot_u);
  *b = ph_rotate(ph_radical_inverse2(k), rot_v);
}

/* The light-domain point of photon k (0 <= k < count) of light L: the
 * rotated Hammersley point the generator maps (ph_map). The adaptive pipeline
 * warps it through its sampling PDF first (kernels/light_domain.h). */
BK_INLINE void ph_point(BK_CONSTANT const ph_light *L, bk_uint k, float *a, float *b) {
  ph_hammersley(k, L->count, L->rot_u, L->rot_v, a, b);
}

/* Launch order: the photon each work-item traces. Hammersley point k lies at
 * u = k / n, and the top q bits of v are the low q bits of k mirrored. In
 * index order a work-group holds a thin u-ring over all of v (for a spot,
 * one cone angle and every azimuth), and the groups PoCL hands a thread
 * together (halves, then quarters, ...) are one band of cone angles, dear
 * ones (through the refracting object) or cheap: the threads finish apart.
 * So photons are dealt in tiles of PH_TILE: a stripe of PH_TILE * Q
 * consecutive k taken one class of k mod Q at a time is a patch of about
 * PH_TILE Q / n by 1/Q of the light's domain (square for Q ~ sqrt(n /
 * PH_TILE)): neighbouring paths in one group. And consecutive groups take
 * tiles a golden-ratio stride apart, so any run of groups samples the whole
 * light. A bijection on [0, n) (past the last whole stripe the order is
 * kept): a batch traces the same photons and, its deposits being integer
 * sums, gives the same bits. */
#define PH_TILE 256u
/* Shards record it: a merge refuses shards traced in another order. */
#define PH_LAUNCH_ORDER 1

/* The plan of a light of n photons, made once on the host (photons.c):
 * Q (0: too few photons for a whole stripe, index order) and a stride
 * coprime with the number of whole tiles. */
BK_INLINE void ph_launch_plan(bk_uint n, bk_uint *rows, bk_uint *stride) {
  bk_uint q = 0;
  while (q < 12u && ((bk_ulong)PH_TILE << (2u * q + 2u)) <= (bk_ulong)n) q++;
  const bk_uint Q = 1u << q, tiles = n / (PH_TILE * Q) * Q;
  *rows = q == 0u ? 0u : Q;
  *stride = 1u;
  if (*rows == 0u) return;
  bk_uint st = (bk_uint)((bk_ulong)tiles * 40503u >> 16) | 1u; /* 40503 / 2^16 ~ 0.618 */
  for (;; st += 2u) { /* the first odd st from there coprime with tiles */
    bk_uint a = st, b = tiles;
    while (b) {
      bk_uint t = a % b;
      a = b;
      b = t;
    }
    if (a == 1u) break;
  }
  *stride = st;
}

/* The photon (of 0..n-1) that slot `slot` traces under the plan (Q, stride). */
BK_INLINE bk_uint ph_launch_order(bk_uint slot, bk_uint n, bk_uint Q, bk_uint stride) {
  if (Q == 0u) return slot;
  const bk_uint stripe = PH_TILE * Q, whole = n / stripe * stripe;
  if (slot >= whole) return slot;
  const bk_uint tiles = whole / PH_TILE;
  const bk_uint t = (bk_uint)((bk_ulong)(slot / PH_TILE) * stride % tiles);
  return t / Q * stripe + t % Q + slot % PH_TILE * Q;
}

/* The light whose photons [first, first + count) hold photon `index`. */
BK_INLINE bk_uint ph_light_of(BK_CONSTANT const ph_light *lights, bk_uint light_count,
                              bk_uint index) {
  bk_uint l = 0;
  while (l + 1 < light_count && index >= lights[l].first + lights[l].count) l++;
  return l;
}

/* The photon (an index over every light's photons, as pm_march_photon takes)
 * that launch slot `slot` traces. */
BK_INLINE bk_uint ph_photon_of_slot(BK_CONSTANT const ph_light *lights, bk_uint light_count,
                                    bk_uint slot) {
  BK_CONSTANT const ph_light *L = lights + ph_light_of(lights, light_count, slot);
  if (slot < L->first || slot - L->first >= L->count) return slot;
  return L->first + ph_launch_order(slot - L->first, L->count, L->tile_rows, L->tile_stride);
}

/* The sampling function of each light kind (baker/lights.h): origin and unit
 * direction, voxel coordinates, of the photon from the light-domain point
 * (a, b) in [0,1)^2. */

/* directional: the rectangle corner + a U + b V, along d */
BK_INLINE void ph_map_directional(BK_CONSTANT const ph_light *L, float a, float b, bk_v3 *origin,
                                  bk_v3 *dir) {
  bk_v3 d = v3(L->dx, L->dy, L->dz);
  bk_v3 u = v3(L->ux, L->uy, L->uz), w = v3(L->vx, L->vy, L->vz);
  *origin = v3_madd(v3_madd(v3(L->px, L->py, L->pz), u, a), w, b);
  *dir = d;
}

/* spot and point: uniform in solid angle about d down to cos_max */
BK_INLINE void ph_map_cone(BK_CONSTANT const ph_light *L, float a, float b, bk_v3 *origin,
                           bk_v3 *dir) {
  bk_v3 d = v3(L->dx, L->dy, L->dz);
  bk_v3 u = v3(L->ux, L->uy, L->uz), w = v3(L->vx, L->vy, L->vz);
  float ct = 1.0f - a * (1.0f - L->cos_max);
  float st = sqrt(fmax(0.0f, 1.0f - ct * ct));
  float phi = 6.283185307179586f * b;
  float cp, sp;
  bk_sincos(phi, &sp, &cp);
  *origin = v3(L->px, L->py, L->pz);
  *dir = v3_normalize(v3_madd(v3_madd(v3_scale(d, ct), u, st * cp), w, st * sp));
}

/* The photon of light L from the light-domain point (a, b), by its kind.
 * The LIGHT_* flags of a specialised kernel drop the kinds the scene does not
 * have. */
BK_INLINE void ph_map(BK_CONSTANT const ph_light *L, float a, float b, bk_v3 *origin, bk_v3 *dir) {
#if !PH_DEVICE || LIGHT_DIRECTIONAL
  if (L->type == PH_DIRECTIONAL) {
    ph_map_directional(L, a, b, origin, dir);
    return;
  }
#endif
#if !PH_DEVICE || LIGHT_SPOT || LIGHT_POINT
  ph_map_cone(L, a, b, origin, dir);
#endif
}

/* Origin and unit direction of photon k (0 <= k < count) of light L, voxel
 * coordinates: ph_map of ph_point. */
BK_INLINE void ph_sample(BK_CONSTANT const ph_light *L, bk_uint k, bk_v3 *origin, bk_v3 *dir) {
  float a, b;
  ph_point(L, k, &a, &b);
  ph_map(L, a, b, origin, dir);
}

#endif
