#!/usr/bin/env bash
# Peak memory per voxel of a bake (docs/memory.md, issue 14): the slope of
# the peak resident size (GNU time) between two resolutions, i.e. the bytes
# each added voxel costs at the bake's peak phase, without the fixed cost of
# PoCL, LLVM and the program. Asserted against the level measured when the
# arrays were last cut, with a margin, for the two scene kinds:
#   grey  scenes/sphere.json: the glass ball in grey fog (sigma stored once)
#   rgb   the same with RGB fog sigma_s (0.5, 0.3, 0.1)
# A kernel is compiled (and cached) by a small bake first, so that neither
# measured bake pays for LLVM.
# Usage: memory_per_voxel.sh BAKER WORKDIR SCENES
set -u
baker=$1 work=$2 scenes=$3
[ -x /usr/bin/time ] || { echo "SKIP: GNU time (/usr/bin/time) is not installed"; exit 77; }
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
peak() { # kind resolution: the peak RSS in bytes
  local extra=()
  [ "$1" = rgb ] && extra=(--set 'medium.sigma_s=[0.5,0.3,0.1]')
  /usr/bin/time -f "peak_kb %M" "$baker" bake "$scenes/sphere.json" -o m.vdb --force -q \
    --photons 20000 --resolution "$2" "${extra[@]}" 2> err.txt || { cat err.txt; return 1; }
  echo $(( $(sed -n 's/^peak_kb //p' err.txt) * 1024 ))
}
# bytes per voxel at the peak phase now (docs/memory.md) and the limit
# asserted, the budget's own figure (baker/budget.h: it must stay above):
# measured 18.7-19.6 (grey) and 50.2-51.6 (rgb) B as slopes from 192^3 up
# at 200 000 photons. From 192^3, not smaller: below it the {grad n, n}
# field's bricks along the ball's surface (which grow as the square of the
# resolution) and the program's own allocations move the slope by a byte
# between runs (20.9-21.3 B grey from 128^3 to 192^3)
for kind_limit in grey:21 rgb:64; do
  kind=${kind_limit%%:*} limit=${kind_limit#*:}
  peak "$kind" 32 > /dev/null || fail "$kind warm-up bake failed"
  lo=$(peak "$kind" 192) || fail "$kind bake at 192 failed"
  hi=$(peak "$kind" 256) || fail "$kind bake at 256 failed"
  python3 - "$kind" "$lo" "$hi" "$limit" <<'PY' || fail "$kind: more bytes per voxel than $limit"
import sys
kind, lo, hi, limit = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
slope = (hi - lo) / (256**3 - 192**3)
print(f"{kind}: peak {lo / 2**20:.0f} MiB at 192^3, {hi / 2**20:.0f} MiB at 256^3: "
      f"{slope:.1f} B/voxel (limit {limit:g})")
sys.exit(0 if slope <= limit else 1)
PY
done
