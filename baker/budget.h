/* budget.h: the bake's peak memory, estimated once from the scene before
 * anything is allocated, and checked against the memory this machine has
 * available (or --max-memory).
 *
 * Model: peak = fixed + per_voxel × voxels. `fixed` covers the OpenCL
 * runtime (PoCL and LLVM compiling a kernel: 120–280 MB measured);
 * per_voxel is the largest phase, the march: the volume (n, and σs, σa
 * with one value per voxel for a grey medium, else three), the {∇n, n}
 * field, σt and the accumulators per march channel, the scatter grid. The
 * write holds less since it builds one OpenVDB tree at a time from grids
 * made slab by slab (out_grids.h). Both are calibrated against the peak
 * resident size of real bakes (docs/memory.md): the estimate is meant to be
 * high, never low, so that a bake it accepts is not killed by the kernel's
 * OOM killer minutes later. The march and voxelization keep their own
 * checks as a second line. */
#ifndef BAKER_BUDGET_H
#define BAKER_BUDGET_H

#include <stdint.h>

#include "base/grid.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BUDGET_FIXED_BYTES (320.0 * 1024 * 1024)
/* per voxel, reference and adaptive mode, for an RGB medium and a grey one
 * (budget_grey): above the slopes measured with multiple scattering on
 * (docs/memory.md: reference 30.8 and 14.8 B since σ is coded, 50-52 and
 * 18.7-20.9 before; adaptive 98-103 and 56-60 B before, not measured
 * since; multiple scattering keeps nothing per voxel of its own) and above
 * the voxelize phase, whose peak is the plain σ arrays, the density and
 * the code side by side (up to 41 B RGB, 21 grey);
 * tests/memory_per_voxel.sh asserts the goals, 48 and 20 B */
#define BUDGET_REFERENCE_BYTES 48.0
#define BUDGET_REFERENCE_GREY_BYTES 21.0
/* per voxel more, a photon shard (--shard): its 64-bit sums held through
 * the write, which encodes them a window at a time (measured 22.5 and 54.0
 * B per voxel, 3.8 B above the reference slopes, docs/memory.md) */
#define BUDGET_SHARD_BYTES 4.0
#define BUDGET_SHARD_GREY_BYTES 4.0
#define BUDGET_ADAPTIVE_BYTES 122.0
#define BUDGET_ADAPTIVE_GREY_BYTES 74.0
/* per voxel more, an adaptive target bake: its checks filter while the
 * march's sums (3 channels and the packed count, or 1 and it) and a copy
 * of half A's sum are held (batches.h target_terms): counted, not measured */
#define BUDGET_ADAPTIVE_TARGET_BYTES 36.0
#define BUDGET_ADAPTIVE_TARGET_GREY_BYTES 20.0
/* dispersion: two more fields {∇n, n} (46 bytes at most, field.h), the R
 * and B planes of n and the interleaved ior_rgb grid written (20): counted,
 * not measured */
#define BUDGET_DISPERSION_BYTES 66.0
/* n from a VDB (grid.ior_vdb) may vary in every brick of the {∇n, n}
 * field: its worst case over the dense float4 field the constants above
 * were measured with (field.h) */
#define BUDGET_IOR_VDB_BYTES 7.0
/* per voxel, the flux of an anisotropic medium (some g != 0, reference mode):
 * 7 counters, radiance_flux, radiance_uncollided, radiance_flux_uncollided
 * and phase_g (baker/march.h) */
#define BUDGET_FLUX_BYTES 88.0
/* and with a scene camera, its counter and `radiance_camera` (8 + 4):
 * counted, not measured */
#define BUDGET_CAMERA_BYTES 12.0
/* per voxel more for a grey medium written as NanoVDB (.nvdb): each grid is
 * converted whole, its OpenVDB tree beside its NanoVDB copy (12 B each for
 * a Vec3 grid), where .vdb leaves hold masks only. Measured 32 B grey and
 * 58 B RGB per voxel (192³ → 256³, docs/memory.md): the RGB figure covers
 * the latter */
#define BUDGET_NANOVDB_GREY_BYTES 13.0

typedef struct budget {
  grid_dims_t dims;
  double voxels;
  double per_voxel;
  double peak; /* bytes */
} budget_t;

/* Whether the scene's volume is grey (R = G = B for σs and σa everywhere),
 * known from the scene before voxelization. */
int budget_grey(const scene_t *s);
/* Bytes per voxel a photon shard holds beyond the bake's (BUDGET_SHARD_*). */
double budget_shard_bytes(const scene_t *s);
/* Bytes per voxel writing to out_path holds beyond the bake's (NanoVDB). */
double budget_output_bytes(const scene_t *s, const char *out_path);

/* Bytes this process may still use: MemAvailable of /proc/meminfo, else
 * the physical memory; capped by max_bytes when it is > 0. */
uint64_t budget_available(uint64_t max_bytes);

/* Bytes per voxel less at every phase when a grey volume's σ is coded
 * (volume_t.code_grey): σs and σt, 4 + 4 B, become one 4-byte word, which
 * takes σs's place as it is made (vox_code.c). */
#define BUDGET_GREY_CODE_SAVES 4.0

/* Refuses (BK_ERR_INPUT) a bake whose estimated peak exceeds what is
 * available, naming the estimate, the limit and the largest resolution that
 * would fit. A grey scene that fits only with its σ coded passes with
 * *code_grey set to 1 (else 0), to be voxelized so. `kept`: bytes per voxel
 * a batch of frames keeps from one frame to the next (baker/frame_reuse.h:
 * the march's fields). box: the objects' world box (vox_meshes_t.box) when
 * the bake is cropped to them (scene_crops), else NULL. */
int budget_check(const scene_t *s, const float (*box)[3], uint64_t max_bytes, double kept,
                 int *code_grey, bk_error_t *err);

/* Sums above this many bytes are checked against the device's largest
 * buffer before the voxels are made (budget_device_check): OpenCL
 * promises 128 MiB per buffer at least, the devices met so far 1 GiB and
 * more, and at that size the wait for the device is a small part of the
 * voxelization it would otherwise overlap. */
#define BUDGET_DEVICE_CHECK_BYTES (1024.0 * 1024 * 1024)

/* Bytes of the photon march's sums for the scene's grid (its largest
 * device buffer), counted low: three channels only for a coloured medium,
 * and an anisotropic medium's flux left out. box: as below. */
double budget_sums_bytes(const scene_t *s, const float (*box)[3]);

/* Refuses (BK_ERR_INPUT) a grid whose sums (budget_sums_bytes) exceed
 * max_alloc, the largest buffer `device` allows, naming the largest
 * resolution that fits. The march checks every buffer again (march_cl.c). */
int budget_device_check(const scene_t *s, const float (*box)[3], uint64_t max_alloc,
                        const char *device, bk_error_t *err);

/* Parses a size for --max-memory: a number with an optional K, M, G or T
 * (powers of 1024, an optional "iB" or "B"). Returns 0 when invalid. */
int budget_parse_size(const char *text, uint64_t *bytes);

#ifdef __cplusplus
}
#endif
#endif
