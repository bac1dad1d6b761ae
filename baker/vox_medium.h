/* vox_medium.h: the medium the voxelize stage composites its objects over.
 *
 * In: the scene's medium (ior, sigma_s, sigma_a) and its optional ior_vdb and
 * density_vdb grids. Out: every voxel of `out` (dims set, grids allocated)
 * holds the medium: n is the constant, or ior_vdb resampled with values below
 * 1 raised to 1 (a warning says how many); sigma_s and σa (in sigma_t,
 * until vox_summarise) are the constants, scaled voxel by voxel by density_vdb where one is given
 * (negative densities set to 0). Non-finite values in either grid are input
 * errors naming the grid and the voxel. A dispersive scene also gets the R
 * and B planes of n (volume_t.ior_rb), the medium's n in both. */
#ifndef BAKER_VOX_MEDIUM_H
#define BAKER_VOX_MEDIUM_H

#include "voxelize.h"

int vox_medium(const scene_t *scene, volume_t *out, bk_error_t *err);

/* Dispersion: composites object obj's R and B n with weight w at voxel gv
 * over the planes rb (plane floats apart), as voxelize composites n. */
void vox_blend_dispersion(const scene_object_t *obj, float w, size_t gv, size_t plane, float *rb);

/* The volume (its sigma_t σs + σa) scanned once over every voxel
 * (vox_scan_t, voxelize.h). */
void vox_scan(const volume_t *v, vox_scan_t *out);

/* The volume's own scan (vox_summarise), or for a volume filled by hand
 * one made into *own. */
const vox_scan_t *vox_scan_of(const volume_t *v, vox_scan_t *own);

/* Once the objects are composited: sigma_t made σs + σa (it held σa), and
 * what the kernels may specialise on (DESIGN §3): vox_scan, kept in
 * v->scan, and from it n's range, whether σs and σt vary and whether they
 * are grey; a grey volume then stores them once per voxel (voxelize.h). */
void vox_summarise(volume_t *v);

#endif
