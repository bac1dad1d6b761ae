#!/usr/bin/env bash
# Installs what is needed, builds, and runs every test under ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
# Blender as a Python module for the interop_blender test (pip, cached in
# build/); without it that test is skipped, not failed.
scripts/blender/setup_bpy.sh build/bpy-venv ||
  echo "test.sh: bpy could not be installed; interop_blender will be skipped" >&2
# Mitsuba 3 for the mitsuba_small validation test (pip, cached in build/);
# without it that test is skipped, not failed.
scripts/setup_mitsuba.sh build/mitsuba-venv ||
  echo "test.sh: mitsuba could not be installed; mitsuba_small will be skipped" >&2
# Kernel binaries are cached inside the build tree so tests never touch ~/.cache.
export BAKER_CACHE_DIR="$PWD/build/kernel-cache"
ctest --test-dir build --output-on-failure -j"$(nproc)" "$@"
