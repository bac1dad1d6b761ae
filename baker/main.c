/* main.c: the `baker` command: dispatches to `bake`, `view` and `verify`.
 * Exit status: 0 success, 2 bad input or usage, 1 runtime failure. */
#include <stdio.h>
#include <string.h>

#include "bake.h"
#include "cache_cmd.h"
#include "clhost.h"
#include "merge.h"
#include "base/common.h"
#include "verify.h"
#include "view.h"

static void usage(FILE *out) {
  fprintf(out,
          "baker %s: offline lighting baker for refractive objects in participating media\n"
          "\n"
          "usage:\n"
          "  baker bake SCENE.json -o OUT.vdb [options]   voxelize, trace photons, write OpenVDB\n"
          "  baker view IN.vdb -o OUT.exr [options]       render a baked VDB to OpenEXR/PNG\n"
          "  baker merge SHARD.vdb... -o OUT.vdb          add photon shards (bake --shard I/N)\n"
          "  baker verify FILE.vdb...                     check every grid against its checksum\n"
          "  baker devices                                list OpenCL platforms and devices\n"
          "  baker cache [--clear]                        kernel cache: path, size; empty it\n"
          "  baker --version | --help\n"
          "\n"
          "`baker bake --help` and `baker view --help` list every option.\n"
          "Exit status: 0 success, 2 bad input or usage, 1 runtime failure.\n",
          BAKER_VERSION);
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage(stderr);
    return BK_ERR_INPUT;
  }
  const char *cmd = argv[1];
  if (!strcmp(cmd, "bake")) return bake_main(argc - 1, argv + 1);
  if (!strcmp(cmd, "view")) return view_main(argc - 1, argv + 1);
  if (!strcmp(cmd, "cache")) return cache_main(argc - 1, argv + 1);
  if (!strcmp(cmd, "merge")) return merge_main(argc - 1, argv + 1);
  if (!strcmp(cmd, "verify")) return verify_main(argc - 1, argv + 1);
  if (!strcmp(cmd, "devices")) {
    clh_list_devices(stdout);
    return BK_OK;
  }
  if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help")) {
    usage(stdout);
    return BK_OK;
  }
  if (!strcmp(cmd, "--version")) {
    printf("baker %s\n", BAKER_VERSION);
    return BK_OK;
  }
  fprintf(stderr, "baker: unknown command '%s'\n\n", cmd);
  usage(stderr);
  return BK_ERR_INPUT;
}
