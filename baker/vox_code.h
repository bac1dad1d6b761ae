/* vox_code.h: a volume's σs and σt coded in one word per voxel plus a table
 * (the layout is kernels/medium_code.h's).
 *
 * In: a volume with plain sigma_s and sigma_t arrays (sigma_channels per
 * voxel; σt = σs + σa), its medium's coefficients (medium_s, medium_a) and
 * the density that scaled them (density; NULL: 1). Out: a voxel whose
 * values are the medium's at its density, or at density 0, bit for bit, is
 * that density; any other (an object, its blended shell) is an entry of
 * the table, consecutive equal entries shared. The table is the volume's
 * few object values and the shell around each object, so RGB σ goes from
 * 24 to about 4 bytes per voxel, grey from 8 (vox_summarise codes RGB
 * volumes, and grey ones when volume_t.code_grey asks). */
#ifndef BAKER_VOX_CODE_H
#define BAKER_VOX_CODE_H

#include "voxelize.h"

/* Codes v in place: sigma_code replaces sigma_s and sigma_t, and the
 * density goes. A grey volume's code is made in σs's array, grown by the
 * table, so coding needs no second array the size of the grid. Out of
 * memory, the plain arrays stay (still valid). */
void vox_code(volume_t *v);

/* σs (t = 0) or σt (t = 1) of voxels [lo, hi) of a coded volume into out,
 * sigma_channels floats per voxel (what vol_sigma_s and vol_sigma_t give,
 * a run at a time for the writer). */
void vox_code_run(const volume_t *v, int t, size_t lo, size_t hi, float *out);

/* The same for every voxel, in a new array (sigma_channels floats per
 * voxel; the caller frees it); NULL when memory is short. */
float *vox_code_decode(const volume_t *v, int t);

#endif
