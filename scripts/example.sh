#!/usr/bin/env bash
# Installs what is needed, builds, bakes the bundled armadillo scene and
# renders it: out/armadillo.vdb, out/armadillo.exr, out/armadillo.png.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
mkdir -p out
build/baker bake scenes/armadillo.json -o out/armadillo.vdb --force
if build/baker view --help >/dev/null 2>&1; then
  build/baker view out/armadillo.vdb --scene scenes/armadillo.json -o out/armadillo.exr --png out/armadillo.png
fi
vdb_print out/armadillo.vdb
