#!/usr/bin/env bash
# An object in a vacuum (docs/memory.md, issue 14): the bake covers only the
# box around the objects (baker/vox_crop.h), so its memory follows them,
# not grid.bounds.
#   1. the cropped file says which voxels it holds (grid_crop), and its
#      radiance, ior and scattering equal those of the whole grid's bake
#      (grid.crop_to_objects: false) where they overlap: scattering and n
#      to float rounding, radiance within 1% relative L2 over lit voxels
#      (paths enter the crop at other step points than they cross it in
#      the whole grid); nothing scatters outside the crop;
#      `baker view` of the two files gives the same image (1e-3 relative
#      RMS), and two photon shards of the cropped bake merge into it bit
#      for bit;
#   2. the same object in a grid of 8x the voxels (bounds and resolution
#      doubled, the voxel size kept) peaks within 1 byte per added voxel of
#      the smaller grid's peak: memory follows the object (an uncropped
#      bake costs about 20 bytes per voxel).
# Usage: crop_vacuum.sh BAKER WORKDIR SCENES
set -u
baker=$1 work=$2 scenes=$3
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cat > vac.json <<JSON
{
  "grid":    { "bounds": [[-2, -2, -2], [2, 2, 2]], "resolution": 96, "ior_smoothing": 2.0 },
  "medium":  { "sigma_s": [0, 0, 0], "sigma_a": [0, 0, 0] },
  "objects": [ { "mesh": "$scenes/meshes/sphere.obj", "ior": 1.3,
                 "sigma_a": [0.1, 0.1, 0.1], "sigma_s": [2, 2, 2],
                 "transform": { "scale": 0.4, "translate": [0, 0.2, 0] } } ],
  "lights":  [ { "type": "spot", "position": [0, 3, 0], "direction": [0, -1, 0],
                 "angle_deg": 20, "intensity": [10, 10, 10] } ],
  "photons": { "count": 100000, "bounces": 0 },
  "camera":  { "position": [0, 0.6, -3.2], "look_at": [0, 0, 0], "up": [0, 1, 0],
               "fov_deg": 40, "resolution": [160, 120] }
}
JSON
"$baker" bake vac.json -o crop.vdb -q 2> crop.err || { cat crop.err; fail "cropped bake failed"; }
"$baker" bake vac.json -o whole.vdb -q --set grid.crop_to_objects=false 2> whole.err ||
  { cat whole.err; fail "whole-grid bake failed"; }
if /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null; then
  /usr/bin/python3 - crop.vdb whole.vdb <<'PY' || fail "the cropped bake differs from the whole grid's"
import sys
import numpy as np
import pyopenvdb as vdb
crop, whole = sys.argv[1], sys.argv[2]
note = vdb.readMetadata(crop).get("grid_crop", "")
assert note.startswith("voxels ["), f"grid_crop metadata missing: {note!r}"
assert "grid_crop" not in vdb.readMetadata(whole), "the whole grid's bake says it was cropped"
def dense(path, name, ijk, shape):
    g = vdb.read(path, name)
    a = np.zeros(shape + ([3] if "Vec3" in type(g).__name__ else []), np.float32)
    g.copyToArray(a, ijk=ijk)
    return g, a
for name, tol in (("ior", 1e-5), ("scattering", 1e-5), ("radiance", 0.01)):
    g = vdb.read(crop, name)
    lo, hi = g.evalActiveVoxelBoundingBox()
    shape = [h - l + 1 for l, h in zip(lo, hi)]
    w = vdb.read(whole, name)
    vs = g.transform.voxelSize()[0]
    off = [round((c - d) / vs) for c, d in zip(g.transform.indexToWorld(lo), w.transform.indexToWorld((0, 0, 0)))]
    _, a = dense(crop, name, tuple(lo), shape)
    _, b = dense(whole, name, tuple(off), shape)
    a, b = a.reshape(len(a.flat) // (3 if a.ndim == 4 else 1), -1).mean(1), b.reshape(len(b.flat) // (3 if b.ndim == 4 else 1), -1).mean(1)
    lit = b > 0.02 * np.percentile(b, 99.9)
    err = np.sqrt(((a - b)[lit] ** 2).mean()) / b[lit].mean()
    print(f"{name}: crop {shape} at {off} of the whole grid, relative L2 over {lit.sum()} voxels {err:.2e} (limit {tol:g})")
    assert err <= tol, name
    if name == "scattering":
        full = np.zeros(w.evalActiveVoxelDim(), np.float32)
        w.copyToArray(full, ijk=w.evalActiveVoxelBoundingBox()[0])
        assert abs(full.sum() - a.sum()) <= 1e-5 * full.sum(), "scattering outside the crop"
PY
else
  echo "SKIP (part 1): /usr/bin/python3 has no pyopenvdb to read the grids back"
fi
tool=$(dirname "$baker")/bench_tool
if [ -x "$tool" ]; then
  "$baker" view crop.vdb -o crop.exr -q --scene vac.json &&
    "$baker" view whole.vdb -o whole.exr -q --scene vac.json ||
    fail "baker view of the two files failed"
  "$tool" exrdiff crop.exr whole.exr > view.json || fail "exrdiff failed"
  python3 -c 'import json, sys; d = json.load(open("view.json")); print("views:", d)
sys.exit(0 if d["rel_rms"] <= 1e-3 else 1)' || fail "the cropped bake's view differs"
  for i in 1 2; do "$baker" bake vac.json -o "shard$i.vdb" -q --shard "$i/2" || fail "shard $i/2"; done
  "$baker" merge shard1.vdb shard2.vdb -o merged.vdb -q || fail "merge of the cropped shards"
  "$tool" vdbdiff merged.vdb crop.vdb radiance > merge.json || fail "vdbdiff failed"
  python3 -c 'import json, sys; d = json.load(open("merge.json")); print("merged shards:", d)
sys.exit(0 if d["max_abs"] == 0 and d["voxels"] > 0 else 1)' || fail "merged shards differ"
else
  echo "SKIP (views, shards): $tool is not built"
fi
[ -x /usr/bin/time ] || { echo "SKIP (part 2): GNU time (/usr/bin/time) is not installed"; exit 0; }
peak() { # bounds-half-extent resolution: the peak RSS in bytes
  /usr/bin/time -f "peak_kb %M" "$baker" bake vac.json -o m.vdb --force -q --photons 20000 \
    --set "grid.bounds=[[-$1,-$1,-$1],[$1,$1,$1]]" --resolution "$2" 2> err.txt ||
    { cat err.txt; return 1; }
  echo $(( $(sed -n 's/^peak_kb //p' err.txt) * 1024 ))
}
peak 2 32 > /dev/null || fail "warm-up bake failed"
lo=$(peak 2 192) || fail "bake of 192^3 failed"
hi=$(peak 4 384) || fail "bake of 384^3 failed"
python3 - "$lo" "$hi" <<'PY' || fail "memory grows with grid.bounds around a fixed object"
import sys
lo, hi = int(sys.argv[1]), int(sys.argv[2])
slope = (hi - lo) / (384**3 - 192**3)
print(f"the object in 192^3 (bounds 4 m): peak {lo / 2**20:.0f} MiB; in 384^3 (8 m, same voxels): "
      f"{hi / 2**20:.0f} MiB: {slope:.3f} B per added voxel (limit 1)")
sys.exit(0 if slope <= 1.0 else 1)
PY
