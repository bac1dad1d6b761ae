/* view_arrays.h: the view's dense arrays: their allocation (aligned for
 * PoCL to use in place), the checks of the values read, and giving an input
 * array's pages back once it has been used. */
#ifndef BAKER_VIEW_ARRAYS_H
#define BAKER_VIEW_ARRAYS_H

#include <stddef.h>

#include "base/common.h"

/* view_alloc's alignment: PoCL uses such arrays in place (CL_MEM_USE_HOST_PTR) */
#define VIEW_ALIGN 4096
#define VIEW_CHUNKS 64 /* reductions over a grid, side by side (same result in any order) */

/* Zeroed and VIEW_ALIGN-aligned, so PoCL can use the array in place as a
 * buffer instead of copying tens of MB; freed with free(). */
void *view_alloc(size_t count, size_t size, const char *what, bk_error_t *err);

/* view_alloc's array without the zeroing (nor its first touch): for an
 * array whose every entry is written before it is read. */
void *view_alloc_unset(size_t count, size_t size, const char *what, bk_error_t *err);

/* Gives the memory of the whole pages in bytes [lo, hi) of a back to the
 * system: an input array whose values there have been used and are not read
 * again. */
void view_release_bytes(const void *a, size_t lo, size_t hi);

/* Inputs are turned into the kernel's arrays this many z slices at a
 * time, each slab of an input given back once used (view_release_slices),
 * so that the outputs' pages come as the inputs' go. */
#define VIEW_PACK_SLAB 8

/* The end of the slab of z slices that starts at k0, in a grid of nz. */
static inline size_t view_slab_end(size_t k0, int nz) {
  return k0 + VIEW_PACK_SLAB < (size_t)nz ? k0 + VIEW_PACK_SLAB : (size_t)nz;
}

/* Gives back z slices [k0, k1) of an input array (NULL: none) of ch floats
 * per voxel, slice voxels per slice. */
void view_release_slices(const float *a, int ch, size_t slice, size_t k0, size_t k1);

/* The padded entry (field.h) of the first voxel of row j + ny k. */
size_t view_padded_row(int nx, int ny, size_t row);

/* Refuses NaN/inf anywhere in grid `name` of path, and negative values when
 * nonneg (coefficients). */
int view_check_values(const char *path, const char *name, const float *a, size_t n, int nonneg,
                      bk_error_t *err);

/* Expands a 1-channel array of n voxels to 3 (replacing it). */
int view_expand_to_rgb(float **a, size_t n, bk_error_t *err);

/* All entries of a (n voxels x ch) equal: fills c[3]. */
int view_is_constant(const float *a, size_t n, int ch, float c[3]);

#endif
