#!/usr/bin/env bash
# Installs what is needed, builds, and runs every test under ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
# Kernel binaries are cached inside the build tree so tests never touch ~/.cache.
export BAKER_CACHE_DIR="$PWD/build/kernel-cache"
ctest --test-dir build --output-on-failure -j"$(nproc)" "$@"
