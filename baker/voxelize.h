/* voxelize.h: scene -> refractive-index and medium-coefficient grids.
 *
 * In: a validated scene (its meshes, medium, optional ior_vdb/density_vdb).
 * Out: per voxel n, sigma_s and sigma_t = sigma_s + sigma_a. Inside an object n = object IOR and
 * sigma = object coefficients; outside, the medium's. The boundary is smoothed
 * over s = `ior_smoothing` voxels from the exact signed distance d to the
 * triangles (in voxels, negative inside): the object's weight is
 *     w(d) = 1 - S((d + s/2) / s),   S(t) = 3t^2 - 2t^3 on [0, 1], clamped,
 * so w = 1 for d <= -s/2, w = 0 for d >= s/2 and w = 0.5 exactly on the
 * surface, and x = x_out + w (x_in - x_out) for x in n, sigma_s, sigma_a:
 * grad n exists (|grad n| <= 1.5 |n_in - n_out| / s per voxel) and the
 * n = (n_in + n_out)/2 isosurface is the mesh surface.
 *
 * Inside test: rays along x, y and z through the voxel centres, hit parity per
 * axis (shared edges and vertices counted once, by the top-left rule). A ray
 * with an odd number of hits passed through a hole and abstains; a voxel is
 * inside when more axes say inside than outside (on a closed mesh: 2 of 3).
 * So open meshes still fill: the Stanford bunny's base has holes, and a ray
 * through one abstains while the two other axes see a closed body.
 *
 * Several objects are composited in scene order over the medium,
 * x <- x + w (x_object - x): a later object overrides earlier ones where it is
 * inside and blends smoothly at its surface (list a bubble after the glass
 * around it). The medium is constant; ior_vdb replaces its n (values below 1,
 * e.g. a zero background, are raised to 1 with a warning) and density_vdb
 * scales its sigma_s and sigma_a voxel by voxel. A dispersive scene's
 * objects composite their n per channel the same way (ior_rb); the medium's
 * n is the same in every channel. */
#ifndef BAKER_VOXELIZE_H
#define BAKER_VOXELIZE_H

#include "base/grid.h"
#include "kernels/medium_code.h"
#include "mesh_io.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One pass over every voxel (vox_scan): n's exact range; whether σs or σt
 * differ anywhere from voxel 0 (varies) or between channels (coloured); the
 * same for σt alone (t_varies, t_coloured), which is what the march
 * specialises on; and what multiple scattering decides on
 * (baker/bounces.c): the sums of σs and σt over the channels, of σt where
 * σs > 0 and the count of those voxels, whether σs alone varies or is
 * coloured, whether g varies or is set. */
typedef struct vox_scan {
  float n_min, n_max;
  int varies, coloured, t_varies, t_coloured;
  double ss, st, st_scattering;
  size_t scattering;
  int s_varies, s_coloured, g_varies, g_set;
} vox_scan_t;

typedef struct volume {
  grid_dims_t dims;
  /* a vacuum's crop (vox_crop.h): dims is the part of the scene's grid
   * `whole` whose first voxel is whole's crop_off; not cropped: whole = dims */
  grid_dims_t whole;
  int crop_off[3];
  int cropped;
  float *ior;      /* n per voxel, >= 1 */
  float *sigma_s;  /* sigma_channels per voxel (RGB interleaved, or one), 1/m */
  /* σt = σs + σa, sigma_channels per voxel, 1/m: the float sum of the two
   * coefficients, which is all any later stage needs of σa (the march's
   * extinction, the `extinction` grid). While voxelize composites the
   * objects it holds σa; vox_summarise makes it the sum. */
  float *sigma_t;
  /* 3, or 1 once vox_build found the medium grey (R = G = B for both
   * coefficients everywhere): its one value stands for every channel, 16
   * bytes per voxel less through every phase of the bake. 0 reads as 3 (a
   * volume filled by hand). Read through vox_sigma_index. */
  int sigma_channels;
  /* σs and σt coded in one word per voxel plus a table (kernels/medium_code.h,
   * baker/vox_code.h): vox_summarise codes an RGB volume that is not
   * homogeneous and frees sigma_s and sigma_t (NULL then). NULL: the plain
   * arrays above hold them (grey, homogeneous, or filled by hand). Read
   * either through vol_sigma_s and vol_sigma_t. */
  float *sigma_code;
  size_t sigma_code_floats; /* the whole buffer: voxels, then the table */
  /* code a grey volume's σ too (4 bytes per voxel instead of 8): set when
   * the bake fits in memory only so (budget_check); vox_summarise reads it */
  int code_grey;
  /* the medium's σs and σa (channel order as sigma_channels) and, while
   * voxelize runs, the density that scales them (density_vdb resampled;
   * NULL: 1 everywhere): what the code expresses a voxel by */
  float medium_s[3], medium_a[3];
  float *density;
  float *g;        /* Henyey–Greenstein g per voxel; NULL: the medium's everywhere */
  /* dispersion (scene_has_dispersion): n of the R channel, then of B, one
   * plane of grid_count floats each, composited like ior (which is G's);
   * NULL otherwise */
  float *ior_rb;
  /* What the scene contains, for kernel specialisation (DESIGN §3). */
  int has_refraction;  /* n varies somewhere */
  /* sigma_s and sigma_t the same in every voxel; vox_summarise then keeps
   * voxel 0's values only (sigma_channels floats each), which
   * vox_sigma_index reads for every voxel */
  int homogeneous;
  int grey;            /* R = G = B for both coefficients everywhere */
  float n_min, n_max;
  /* the pass these came from, when `scanned` (vox_summarise; a volume
   * filled by hand is scanned by the march itself) */
  vox_scan_t scan;
  int scanned;
  /* A hash of every input vox_build read (baker/frame_reuse.h), set by a
   * batch of frames to say which volume this is; 0: not known. */
  uint64_t key;
} volume_t;

/* Where channel c of voxel i lies in an array of `channels` (1 or 3)
 * values per voxel; 0 reads as 3. */
static inline size_t vox_channel_at(int channels, size_t i, int c) {
  return channels == 1 ? i : 3 * i + (size_t)c;
}

/* Where channel c of voxel i lies in sigma_s and sigma_t (voxel 0's for
 * every voxel of a homogeneous volume). */
static inline size_t vox_sigma_index(const volume_t *v, size_t i, int c) {
  return vox_channel_at(v->sigma_channels, v->homogeneous ? 0 : i, c);
}

/* σs (t = 0) or σt (t = 1) of channel c at voxel i (per metre), however
 * they are stored. */
static inline float vol_sigma(const volume_t *v, size_t i, int c, int t) {
  if (v->sigma_code)
    return mc_sigma(v->sigma_code, (bk_long)grid_count(&v->dims), v->sigma_channels == 1 ? 1 : 3,
                    (bk_long)i, v->sigma_channels == 1 ? 0 : c, t);
  return (t ? v->sigma_t : v->sigma_s)[vox_sigma_index(v, i, c)];
}
static inline float vol_sigma_s(const volume_t *v, size_t i, int c) { return vol_sigma(v, i, c, 0); }
static inline float vol_sigma_t(const volume_t *v, size_t i, int c) { return vol_sigma(v, i, c, 1); }

/* The band an object changes reaches this far (voxels) beyond the
 * smoothing half-width. Only |d| < s/2 uses the distance (beyond it w is 0
 * or 1 by the inside vote alone), so half a voxel guards the rounding of
 * the band test; each voxel more of margin costs about 2x in the distance
 * pass (armadillo, 128^3: 145 ms at 0.5, 460 at 2). */
#define VOX_BAND_MARGIN 0.5f

/* Bytes per voxel the volume needs (for grid_check_memory): n, and σs and
 * σa (then σt) with C = 1 (grey) or 3 values each. */
#define VOX_BYTES_PER_VOXEL(C) ((1 + 2 * (size_t)(C)) * sizeof(float))

/* Every object's mesh, read, checked and moved into the world (its
 * transform applied), in scene order, with their world box (what a
 * vacuum's crop and its memory budget need) and the time it took. */
typedef struct vox_meshes {
  mesh_tris_t *mesh;
  int count;
  long long tris;
  double load_ms;  /* reading the files: the "mesh load" row */
  double check_ms; /* checking and placing them: part of the "voxelize" row */
  float box[2][3];
} vox_meshes_t;
int vox_meshes_load(const scene_t *scene, vox_meshes_t *m, bk_error_t *err);
void vox_meshes_free(vox_meshes_t *m);

/* The volume of the scene: vox_meshes_load, then vox_build_meshes. */
int vox_build(const scene_t *scene, volume_t *out, bk_timings_t *timings, bk_error_t *err);
/* The volume from meshes already read, which it frees (each as soon as it
 * is in the volume); the "mesh load" row gets their read's time.
 * code_grey: volume_t.code_grey. */
int vox_build_meshes(const scene_t *scene, vox_meshes_t *meshes, int code_grey, volume_t *out,
                     bk_timings_t *timings, bk_error_t *err);
void vox_free(volume_t *v);

#ifdef __cplusplus
}
#endif
#endif
