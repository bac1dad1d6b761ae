#!/usr/bin/env bash
# Peak memory per voxel of a bake (docs/memory.md, issue 14): the slope of
# the peak resident size (GNU time) between two resolutions, i.e. the bytes
# each added voxel costs at the bake's peak phase, without the fixed cost of
# PoCL, LLVM and the program. Asserted against the issue's goals, for the
# two scene kinds:
#   grey  scenes/sphere.json: the glass ball in grey fog
#   rgb   the same in RGB fog, sigma_s (0.5, 0.3, 0.1), scaled by a density
#         VDB (made with /usr/bin/python3's pyopenvdb; without it the fog is
#         uniform, and the test says so)
# A kernel is compiled (and cached) by a small bake first, so that neither
# measured bake pays for LLVM. Then `baker view` of the two grey files, whose
# slope is asserted at 18 B per voxel (docs/memory.md, "baker view's
# memory": the medium, {S, σt} under grey light, packed over the grids as
# they are given back; 40 B before the pack gave them back, 24.5 while grey
# radiance was read as three floats and σt kept whole, 22 while the medium
# was four floats).
# Usage: memory_per_voxel.sh BAKER WORKDIR SCENES
set -u
baker=$1 work=$2 scenes=$3
[ -x /usr/bin/time ] || { echo "SKIP: GNU time (/usr/bin/time) is not installed"; exit 77; }
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
rgb_set=(--set 'medium.sigma_s=[0.5,0.3,0.1]')
if /usr/bin/python3 - "$work/density.vdb" <<'PY' 2>/dev/null; then
import math, sys
import pyopenvdb as vdb
n, size = 32, 2.0 / 32
g = vdb.FloatGrid()
g.name = "density"
acc = g.getAccessor()
for i in range(n):
    for j in range(n):
        for k in range(n):
            x, y, z = (-1 + (a + 0.5) * size for a in (i, j, k))
            acc.setValueOn((i, j, k), 0.6 + 0.4 * math.sin(3 * x) * math.sin(4 * y + 1) * math.sin(5 * z + 2))
xf = vdb.createLinearTransform(voxelSize=size)
xf.translate((-1 + size / 2,) * 3)
g.transform = xf
vdb.write(sys.argv[1], grids=[g])
PY
  rgb_set+=(--set "medium.density_vdb={\"file\": \"$work/density.vdb\", \"grid\": \"density\"}")
  echo "rgb: fog scaled by a density VDB"
else
  echo "rgb: uniform fog (/usr/bin/python3 has no pyopenvdb to write a density VDB)"
fi
peak_of() { # command...: its peak RSS in bytes
  /usr/bin/time -f "peak_kb %M" "$@" 2> err.txt || { cat err.txt; return 1; }
  echo $(( $(sed -n 's/^peak_kb //p' err.txt) * 1024 ))
}
peak() { # kind resolution: the peak RSS in bytes of its bake
  local extra=()
  [ "$1" = rgb ] && extra=("${rgb_set[@]}")
  peak_of "$baker" bake "$scenes/sphere.json" -o "m_$1_$2.vdb" --force -q \
    --photons 20000 --resolution "$2" "${extra[@]}"
}
view_peak() { # file: the peak RSS in bytes of its view
  peak_of "$baker" view "$1" -o v.exr --scene "$scenes/sphere.json" -q --resolution 64x48
}
slope_at_most() { # label lo hi limit
  python3 - "$@" <<'PY'
import sys
kind, lo, hi, limit = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
slope = (hi - lo) / (256**3 - 192**3)
print(f"{kind}: peak {lo / 2**20:.0f} MiB at 192^3, {hi / 2**20:.0f} MiB at 256^3: "
      f"{slope:.1f} B/voxel (limit {limit:g})")
sys.exit(0 if slope <= limit else 1)
PY
}
# the issue's goals: 20 (grey) and 48 (rgb) bytes per voxel at every
# phase's peak. Measured with the coded sigma (kernels/medium_code.h)
# 14.8 and 30.9 B as slopes from 192^3 to 256^3 at 20 000 photons. From
# 192^3, not smaller: below it the {grad n, n} field's bricks along the
# ball's surface (which grow as the square of the resolution) and the
# program's own allocations move the slope by a byte between runs
for kind_limit in grey:20 rgb:48; do
  kind=${kind_limit%%:*} limit=${kind_limit#*:}
  peak "$kind" 32 > /dev/null || fail "$kind warm-up bake failed"
  lo=$(peak "$kind" 192) || fail "$kind bake at 192 failed"
  hi=$(peak "$kind" 256) || fail "$kind bake at 256 failed"
  slope_at_most "$kind" "$lo" "$hi" "$limit" || fail "$kind: more bytes per voxel than $limit"
done
lo=$(view_peak m_grey_192.vdb) || fail "view at 192 failed"
hi=$(view_peak m_grey_256.vdb) || fail "view at 256 failed"
slope_at_most "view of grey" "$lo" "$hi" 18 || fail "view: more bytes per voxel than 18"
