/* bench_voxelize.c: times vox_build on one mesh and reports peak memory.
 *
 * Usage: bench_voxelize MESH RESOLUTION [IOR_SMOOTHING]. The grid bounds are
 * the mesh's bounding box grown by 5% of its longest side; the object has
 * n = 1.5 in a medium of n = 1. Prints the stage timings, then one line
 * "MESH RES^3: voxelize X ms (load Y ms), peak RSS Z MiB" for scripts. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "mesh_io.h"
#include "voxelize.h"

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: bench_voxelize MESH RESOLUTION [IOR_SMOOTHING]\n");
    return BK_ERR_INPUT;
  }
  const char *path = argv[1];
  bk_verbosity = 2; /* the per-pass times of the stage */
  int resolution = atoi(argv[2]);
  float smoothing = argc > 3 ? (float)atof(argv[3]) : 2.0f;
  bk_error_t err;
  mesh_tris_t m;
  int rc = mesh_io_read(path, &m, &err);
  if (rc) {
    fprintf(stderr, "bench_voxelize: %s\n", err.msg);
    return rc;
  }
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int v = 0; v < m.vertex_count; v++)
    for (int a = 0; a < 3; a++) {
      lo[a] = fminf(lo[a], m.positions[3 * v + a]);
      hi[a] = fmaxf(hi[a], m.positions[3 * v + a]);
    }
  int tris = m.triangle_count;
  mesh_io_free(&m);
  float longest = fmaxf(hi[0] - lo[0], fmaxf(hi[1] - lo[1], hi[2] - lo[2]));

  static scene_t scene; /* large: keep it off the stack */
  scene_object_t obj;
  scene_defaults(&scene);
  scene_object_defaults(&obj); /* ior 1.5, scale 1 */
  snprintf(scene.path, sizeof scene.path, "bench_voxelize");
  for (int a = 0; a < 3; a++) {
    scene.bounds_min[a] = lo[a] - 0.05f * longest;
    scene.bounds_max[a] = hi[a] + 0.05f * longest;
  }
  scene.resolution = resolution;
  scene.ior_smoothing = smoothing;
  snprintf(obj.mesh, sizeof obj.mesh, "%s", path);
  scene.objects = &obj;
  scene.object_count = 1;

  bk_timings_t timings = {0};
  volume_t vol;
  double t0 = bk_now_ms();
  rc = vox_build(&scene, &vol, &timings, &err);
  double total = bk_now_ms() - t0;
  if (rc) {
    fprintf(stderr, "bench_voxelize: %s\n", err.msg);
    return rc;
  }
  size_t inside = 0;
  for (size_t i = 0; i < grid_count(&vol.dims); i++) inside += vol.ior[i] > 1.25f;
  bk_timings_print(&timings, stdout);
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  double load = 0.0;
  for (int i = 0; i < timings.count; i++)
    if (!strcmp(timings.stages[i].name, "mesh load")) load = timings.stages[i].ms;
  printf("%s %dx%dx%d (%d tris, smoothing %g): vox_build %.0f ms (mesh load %.0f ms), "
         "%zu inside voxels, peak RSS %.0f MiB\n",
         path, vol.dims.nx, vol.dims.ny, vol.dims.nz, tris, smoothing, total, load, inside,
         ru.ru_maxrss / 1024.0);
  vox_free(&vol);
  return 0;
}
