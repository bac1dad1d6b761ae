/* view_fields.h: what the camera rays read, prepared from the loaded volume
 * (kernels/view_march.h).
 *
 * In: the volume's dense, unpadded arrays (n; the medium {S = σs L̄, σt};
 * RGB σt). Out: the ray core's padded layout of the medium and σt, the
 * {∇n, n} field (baker/field.h, the photon march's own builder) and two
 * constant-block pyramids (baker/octree.h): of n with the march's halo,
 * where rays walk straight, and of the medium with the 1-voxel halo that
 * trilinear sampling reads, where one step crosses a whole brick. */
#ifndef BAKER_VIEW_FIELDS_H
#define BAKER_VIEW_FIELDS_H

#include "base/common.h"
#include "view_volume.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Builds v->ng, v->npyr (when v->refraction) and v->mpyr, then pads
 * v->medium and v->sigma_t4 in place. BK_ERR_RUNTIME when out of memory. */
int view_fields_build(view_volume_t *v, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
