/* fuzz_scene: JSON text -> scene_load, the path `baker bake` and `baker view`
 * take (parser, --set machinery excluded, every key's validation). The scene
 * loader does not open the meshes or VDBs it names; it only joins their
 * paths to the scene's directory, and that directory is an empty one of
 * our own. Exit status is not checked: any return is fine, a crash is not. */
#include "fuzz_util.h"
#include "scene.h"

int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc, (void)argv;
  fuzz_enter_workdir();
  return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  fuzz_write_input("scene.json", data, size);
  scene_t s;
  bk_error_t err;
  if (scene_load("scene.json", &s, &err) == BK_OK) scene_free(&s);
  return 0;
}
