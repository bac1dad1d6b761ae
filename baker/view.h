/* view.h: the viewing pass, `baker view IN.vdb -o OUT.exr`, and its command.
 *
 * In: a baked VDB (or any VDB with the same grids and a similarity transform)
 * and a pinhole camera (flags, else the scene's camera, else one framing the
 * grid). Out: a linear half RGBA OpenEXR and optionally an sRGB PNG preview,
 * per frame. Each pixel's camera ray bends through n with the ray equation
 * and gathers L = ∫ T σs L̄ dt + T_end·L_background (kernels/view_march.h).
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

#include <stdio.h>

#include "base/common.h"
#include "view_camera.h"
#include "view_fields.h"
#include "view_image.h"
#include "view_render.h"
#include "view_volume.h"

#ifdef __cplusplus
extern "C" {
#endif

/* argv[0] is the subcommand ("view"), as main() passes argv + 1.
 * Returns the exit status: 0 ok, 2 bad input or usage, 1 runtime failure;
 * prints its own messages. */
int view_main(int argc, char **argv);

void view_usage(FILE *out);

#ifdef __cplusplus
}
#endif
#endif
