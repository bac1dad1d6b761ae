#!/usr/bin/env bash
# The light scattered towards the scene's camera (radiance_camera, issue
# 16; kernels/photon_march.h PM_CAMERA, kernels/view_march.h):
#   1. with g != 0 and a camera the bake writes `radiance_camera` and names
#      its camera in `radiance_camera_position`; camera.bake_phase false
#      writes neither and leaves every other grid bit-identical;
#   2. `baker view` from that camera uses it (in this side-lit g 0.8 fog
#      the image differs from the flux lobes' by more than 1%); from
#      another camera it falls back to the lobes: the two files' views are
#      then identical;
#   3. two photon shards merge into the single bake's radiance_camera bit
#      for bit, and the merged file names the camera.
# Usage: camera_phase.sh BAKER BENCH_TOOL WORKDIR
set -u
baker=$1 tool=$2 work=$3
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cat > fog.json <<JSON
{
  "grid":    { "bounds": [[-1, -1, -1], [1, 1, 1]], "resolution": 32 },
  "medium":  { "sigma_s": 1.5, "sigma_a": 0.05, "g": 0.8 },
  "lights":  [ { "type": "directional", "direction": [0.3, -1, 0.2], "irradiance": [1, 1, 1] } ],
  "photons": { "count": 100000, "bounces": "auto" },
  "camera":  { "position": [0, 0.6, -3.2], "look_at": [0, 0, 0], "up": [0, 1, 0],
               "fov_deg": 40, "resolution": [64, 48] }
}
JSON
"$baker" bake fog.json -o cam.vdb -q 2> cam.err || { cat cam.err; fail "bake failed"; }
"$baker" bake fog.json -o lobe.vdb -q --set camera.bake_phase=false 2> lobe.err ||
  { cat lobe.err; fail "bake with camera.bake_phase false failed"; }
"$baker" verify cam.vdb > cam.verify 2>&1 || { cat cam.verify; fail "cam.vdb does not verify"; }
grep -q "radiance_camera" cam.verify || { cat cam.verify; fail "no radiance_camera grid"; }
"$baker" verify lobe.vdb > lobe.verify 2>&1 || fail "lobe.vdb does not verify"
grep -q "radiance_camera" lobe.verify && fail "camera.bake_phase false still wrote radiance_camera"
for g in radiance radiance_flux radiance_uncollided radiance_flux_uncollided; do
  d=$("$tool" vdbdiff cam.vdb lobe.vdb $g) || fail "vdbdiff $g"
  echo "$g: $d"
  echo "$d" | grep -q '"max_abs": 0[,}]' || fail "$g differs with the camera's counter"
done
if /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null; then
  /usr/bin/python3 -c '
import sys, pyopenvdb as vdb
m = vdb.readMetadata("cam.vdb").get("radiance_camera_position")
assert m == "[0, 0.600000024, -3.20000005]", m
assert "radiance_camera_position" not in vdb.readMetadata("lobe.vdb")
print("radiance_camera_position:", m)' || fail "radiance_camera_position metadata"
fi
view() { "$baker" view "$1" -o "$2" --scene fog.json -q "${@:3}" || fail "view $1"; }
view cam.vdb cam.exr
view lobe.vdb lobe.exr
d=$("$tool" exrdiff cam.exr lobe.exr) || fail "exrdiff"
echo "scene camera, radiance_camera against the lobes: $d"
/usr/bin/python3 -c 'import json, sys; sys.exit(json.loads(sys.argv[1])["rel_rms"] <= 0.01)' "$d" ||
  fail "the view from the bake's camera did not use radiance_camera"
view cam.vdb cam_moved.exr --camera-pos 0.2,0.6,-3.2
view lobe.vdb lobe_moved.exr --camera-pos 0.2,0.6,-3.2
d=$("$tool" exrdiff cam_moved.exr lobe_moved.exr) || fail "exrdiff"
echo "another camera: $d"
echo "$d" | grep -q '"max_abs": 0[,}]' || fail "from another camera the view must use the lobes"
"$baker" bake fog.json -o s1.vdb -q --shard 1/2 || fail "shard 1/2"
"$baker" bake fog.json -o s2.vdb -q --shard 2/2 || fail "shard 2/2"
"$baker" merge s1.vdb s2.vdb -o merged.vdb -q || fail "merge"
d=$("$tool" vdbdiff merged.vdb cam.vdb radiance_camera) || fail "vdbdiff merged"
echo "merged shards, radiance_camera: $d"
echo "$d" | grep -q '"max_abs": 0[,}]' || fail "merged radiance_camera differs from the bake's"
if /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null; then
  /usr/bin/python3 -c '
import pyopenvdb as vdb
m = vdb.readMetadata("merged.vdb").get("radiance_camera_position")
assert m == "[0, 0.600000024, -3.20000005]", m' ||
    fail "the merged file does not name the camera"
fi
echo "camera_phase: OK"
