/* view.h: the viewing pass, `baker view IN.vdb -o OUT.exr`.
 *
 * In: a baked VDB (or any VDB with the same grids and a similarity transform)
 * and a pinhole camera (flags, else the scene's camera, else one framing the
 * grid). Out: a linear half RGBA OpenEXR and optionally an sRGB PNG preview,
 * per frame. Each pixel's camera ray bends through n with the ray equation
 * and gathers L = ∫ T σs L̄ dt + T_end·L_background (kernels/view.h).
 *
 * Grids read (DESIGN.md §5): `radiance` (Vec3f, required, L̄), `ior` (float;
 * absent: n = 1; values below 1, e.g. the zero background, are taken as 1),
 * `extinction` (float or Vec3f; absent: the grey `density` grid, else equal to
 * `scattering`, else 0), `scattering` (float or Vec3f; absent: equal to
 * σt, i.e. albedo 1). They are resampled onto one dense box, the union of the
 * grids' active boxes in the radiance grid's index space; the medium is empty
 * outside it, and inside a grid's box its edge voxels hold (no zero padding),
 * so a box of constant voxels is a box of constant medium whose faces are
 * the voxels' faces. Transforms must be a similarity (rotation, uniform scale,
 * translation), since the ray equation keeps its form only under those.
 *
 * Alpha is 1 − mean over RGB of the transmittance T_end (0 where a ray misses
 * the volume); RGB includes T_end·background, so with the default black
 * background the image is premultiplied and composites over a plate. */
#ifndef BAKER_VIEW_H
#define BAKER_VIEW_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* argv[0] is the subcommand ("view"), as main() passes argv + 1.
 * Returns the exit status: 0 ok, 2 bad input or usage, 1 runtime failure;
 * prints its own messages. */
int view_main(int argc, char **argv);

void view_usage(FILE *out);

/* The refractive field the kernel reads, from n (nx*ny*nz floats, x-fastest):
 * ng holds 4 floats per voxel, ∇n per voxel length (central differences,
 * one-sided on the faces: kernels/ior.h, as the photon march) and n. */
void view_ng_field(int nx, int ny, int nz, const float *ior, float *ng);

/* The layout the kernel reads 4-float fields in: src (nx*ny*nz voxels of 4
 * floats) with one layer of replicated edge voxels around it, into dst of
 * (nx+2)*(ny+2)*(nz+2) voxels. */
void view_pad4(int nx, int ny, int nz, const float *src, float *dst);

/* Where camera rays may walk straight inside refracting bricks: per voxel,
 * the Chebyshev distance in voxels (capped at VIEW_FLAT_MAX) to the nearest
 * voxel whose ∇n (from view_ng_field) is not zero. scratch: nx*ny*nz bytes. */
void view_flat_field(int nx, int ny, int nz, const float *ng, unsigned char *flat,
                     unsigned char *scratch);

#ifdef __cplusplus
}
#endif
#endif
