#!/usr/bin/env bash
# Installs the Debian packages baker needs (as root with apt-get; otherwise it
# prints the exact command to run) and configures + builds into build/.
# Usage: scripts/setup.sh [--no-build] [--bench]
# --bench adds the yardsticks that only benchmarks use (POV-Ray for
# `scripts/bench --only povray`); the test suite never needs them.
set -euo pipefail
cd "$(dirname "$0")/.."

build=1 bench=0
for a in "$@"; do
  case "$a" in
    --no-build) build=0 ;;
    --bench) bench=1 ;;
    *) echo "setup: unknown option $a (expected --no-build, --bench)" >&2; exit 2 ;;
  esac
done

PACKAGES=(
  build-essential cmake ccache pkg-config
  libopenvdb-dev libblosc-dev libopenvdb-tools python3-openvdb python3-numpy python3-matplotlib
  libnanovdb-dev libnanovdb-tools
  libopenmesh-dev libopenexr-dev libpng-dev
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers clinfo
  clang time
  # farm recipes tested for real, and the relocatable bundle (about 10 s to install)
  slurm-wlm munge parallel patchelf
)
BENCH_PACKAGES=(povray) # scripts/bench's povray section: POV-Ray 3.7, the photon-mapping yardstick
[ "$bench" = 1 ] && PACKAGES+=("${BENCH_PACKAGES[@]}")

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then
    echo "setup: installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq "${missing[@]}" >/dev/null
  else
    echo "setup: missing Debian packages. Run:" >&2
    echo "  sudo apt-get update && sudo apt-get install -y ${missing[*]}" >&2
    exit 2
  fi
fi

[ "$build" = 0 ] && exit 0
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"
