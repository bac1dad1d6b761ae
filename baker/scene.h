/* scene.h: the scene file (DESIGN.md §4) loaded and validated.
 *
 * In: a JSON file. Out: a scene_t with every key checked for type and range,
 * defaults filled in, paths resolved relative to the scene file, and, for keys
 * that later stages may still find wrong (a mesh that will not load, a VDB
 * without the named grid), a `where` string "scene.json:LINE:COL: key.path"
 * so their messages point back at the scene. Unknown keys are warned about. */
#ifndef BAKER_SCENE_H
#define BAKER_SCENE_H

#include <limits.h>
#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SCENE_PATH_MAX 4096
#define SCENE_WHERE_MAX 512
#define SCENE_MAX_OBJECTS 1024
#define SCENE_MAX_LIGHTS 64

/* Rows of light_kinds[] (lights.h) and of integrator_kinds[] (integrators.h). */
typedef enum { LIGHT_DIRECTIONAL = 0, LIGHT_SPOT = 1, LIGHT_POINT = 2 } light_type_t;
typedef enum { MODE_REFERENCE = 0, MODE_ADAPTIVE = 1 } photon_mode_t;
typedef enum { INTEGRATOR_EULER = 0, INTEGRATOR_RK4 = 1 } integrator_t;

typedef struct scene_vdb_ref {
  int present;
  char file[SCENE_PATH_MAX]; /* resolved against the scene directory */
  char grid[256];
  char where[SCENE_WHERE_MAX];
} scene_vdb_ref_t;

typedef struct scene_object {
  char mesh[SCENE_PATH_MAX]; /* resolved path */
  char where[SCENE_WHERE_MAX]; /* "scene.json:L:C: objects[i].mesh" */
  float ior;                 /* >= 1; n_d, the reference (green) channel */
  /* n per channel R, G, B (G = ior): "ior": [nR, nG, nB], or from "abbe"
   * (scene_dispersion_rgb); all 0 (the default) when not given: n = ior in
   * every channel (scene_object_n) */
  float ior_rgb[3];
  float sigma_a[3], sigma_s[3];
  float g;                   /* Henyey–Greenstein asymmetry of its medium, (-1, 1); default 0 */
  float scale[3];            /* "scale": number or [x,y,z]; default 1 */
  float rotate_deg[3];       /* XYZ Euler, applied x then y then z; default 0 */
  float translate[3];
} scene_object_t;

typedef struct scene_light {
  light_type_t type;
  float position[3];   /* spot, point */
  float direction[3];  /* spot, directional; normalised on load */
  float angle_deg;     /* spot: half-angle of the cone, (0, 90] */
  float intensity[3];  /* spot, point: W/sr */
  float irradiance[3]; /* directional: W/m^2 */
} scene_light_t;

typedef struct scene_camera {
  int present;
  float position[3], look_at[3], up[3];
  float fov_deg;       /* vertical field of view */
  int width, height;
  int bake_phase;      /* some g != 0: bake the light scattered towards position
                          (radiance_camera, baker/march.c) */
} scene_camera_t;

/* Thresholds of the adaptive pipeline: a negative value means "auto". */
#define SCENE_AUTO (-1.0f)
/* photons.bounces "auto" (baker/bounces.h decides), and the largest N. */
#define SCENE_BOUNCES_AUTO (-1)
#define SCENE_MAX_BOUNCES 100000
/* photons.step's least value, 2^-10 voxel: a photon takes at most
 * PM_MAX_STEPS (65 536) steps, 64 voxels of curved path at this step.
 * Finer steps ran for minutes and stopped most photons that met a surface
 * at the limit, their light missing from the grid. */
#define SCENE_MIN_STEP_LOG2 10
#define SCENE_MIN_STEP (1.0 / (double)(1 << SCENE_MIN_STEP_LOG2))

typedef struct scene {
  char path[SCENE_PATH_MAX]; /* the scene file as given */
  char dir[SCENE_PATH_MAX];  /* its directory, for relative paths */
  uint64_t hash;             /* FNV-1a of the scene file's bytes */
  int frame;                 /* the frame its keyframed values were evaluated at */
  int keyed_values;          /* how many of its values are keyframed (scene_keys.c) */

  /* grid */
  float bounds_min[3], bounds_max[3];
  int resolution;            /* voxels along the longest side */
  float ior_smoothing;       /* voxels, > 0; default 2 */
  /* In a vacuum medium, bake only the box around the objects (grid_crop);
   * default on (scene_crops says when it applies) */
  int crop_to_objects;
  char where_resolution[SCENE_WHERE_MAX];

  /* medium */
  float medium_sigma_s[3], medium_sigma_a[3];
  float medium_ior;          /* >= 1; default 1 */
  float medium_g;            /* Henyey–Greenstein asymmetry, (-1, 1); default 0 */
  scene_vdb_ref_t density_vdb, ior_vdb;

  scene_object_t *objects;
  int object_count;
  scene_light_t *lights;
  int light_count;

  /* photons */
  photon_mode_t mode;
  long long photon_count;    /* default 122000 */
  unsigned seed;             /* default 1 */
  integrator_t integrator;   /* default euler */
  float step;                /* voxels, default 0.5 */
  int bounces;               /* scattering events per photon, or SCENE_BOUNCES_AUTO (default) */
  int batches;               /* independent batches; 0 (default): scene_batches() picks */
  float target_error;        /* > 0: add batches until the error estimate is below; 0 off */
  float time_budget_s;       /* > 0: stop adding batches at this march time; 0 off */

  /* adaptive */
  int pilot;                 /* default 4000 */
  float gradient_threshold;  /* SCENE_AUTO or >= 0 */
  float luminance_threshold; /* SCENE_AUTO or >= 0 */
  float alpha;               /* default 1 */
  int retable;               /* adaptive.tables "measured" (1): rebuilt after every batch
                                from the measured error; "pilot" (0, default) */

  scene_camera_t camera;
  float background[3];
} scene_t;

/* Every default of DESIGN.md §4 on a zeroed scene: what scene_load starts
 * from, and what a scene made in code (tests, benchmarks) starts from. */
void scene_defaults(scene_t *s);
/* An object's defaults: ior 1.5, scale 1, nothing else. */
void scene_object_defaults(scene_object_t *o);

/* Dispersion (DESIGN §4 extension, README "Dispersion"): the channels are
 * the Fraunhofer lines that define the Abbe number, R = C (656.3 nm),
 * G = d (587.6 nm), B = F (486.1 nm), so n_G = n_d and n_B - n_R =
 * (n_d - 1)/V_d exactly; n(λ) = A + B/λ² (Cauchy) splits that difference
 * around n_d. */
void scene_dispersion_rgb(float n_d, float abbe, float out[3]);
/* 1 when an object's n differs between channels: the bake then carries n
 * per channel (volume_t.ior_rb) and specialises its kernels (-DDISPERSION). */
int scene_has_dispersion(const scene_t *s);
/* Whether the medium's and every object's σs and σa are the same in R, G
 * and B (the voxelized volume is then grey: voxelize.h). */
int scene_is_grey(const scene_t *s);
/* Whether the bake covers only the box around the objects (grid_crop): the
 * medium is a vacuum (σs = σa = 0; its n constant, no ior_vdb), so nothing
 * outside the objects' reach scatters, absorbs or bends light, and
 * grid.crop_to_objects is on (the default). */
int scene_crops(const scene_t *s);
/* The batches a bake traces (baker/batches.h): photons.batches when set;
 * else SCENE_OPEN_BATCHES with a target error or time budget (their unit of
 * work is count / batches photons: finer steps stop nearer the goal);
 * else, for a fixed photon count, as few large Hammersley sets as the
 * estimate allows (the noise estimate's cost is their sparseness,
 * docs/error.md): SCENE_FIXED_BATCHES for the grid-wide terms, which
 * average over every lit voxel, and SCENE_VOXEL_BATCHES when each voxel's
 * own spread is wanted (per_voxel: --error-grid's standard error). */
#define SCENE_FIXED_BATCHES 2
#define SCENE_VOXEL_BATCHES 4
#define SCENE_OPEN_BATCHES 8
int scene_batches(const scene_t *s, int per_voxel);
/* n of object o in channel ch (0 R, 1 G, 2 B). */
float scene_object_n(const scene_object_t *o, int ch);

/* Loads and validates. On failure returns BK_ERR_INPUT (a missing or
 * unreadable scene file included: the user named it) or BK_ERR_RUNTIME (out of
 * memory), with err naming the file, line, column and key. */
int scene_load(const char *path, scene_t *out, bk_error_t *err);
/* The same with `--set KEY=VALUE` overrides applied to the JSON before it is
 * validated (scene_set.c; messages about their values name the --set), and
 * path "-" for standard input (read once per process; named <stdin>,
 * relative paths against the working directory). The hash covers the
 * overrides as well as the file's bytes. */
int scene_load_with(const char *path, const char *const *sets, int set_count, scene_t *out,
                    bk_error_t *err);
/* The same at a frame: keyframed values ({"keys": {"FRAME": VALUE}}, lights'
 * values and object transforms; docs/animation.md) take that frame's value.
 * scene_load and scene_load_with evaluate them at frame 0. */
int scene_load_frame(const char *path, const char *const *sets, int set_count, int frame,
                     scene_t *out, bk_error_t *err);

/* scene_set.c: the overrides on a parsed tree (BK_ERR_INPUT naming the
 * --set for a key path that does not fit the tree), and standard input's
 * bytes, read on first use. */
struct json_value;
int scene_apply_sets(struct json_value *root, const char *const *sets, int count,
                     bk_error_t *err);
int scene_read_stdin(const char **text, size_t *len, bk_error_t *err);
void scene_free(scene_t *s);

const char *scene_light_type_name(light_type_t t);
const char *scene_mode_name(photon_mode_t m);
const char *scene_integrator_name(integrator_t i);

#ifdef __cplusplus
}
#endif
#endif
