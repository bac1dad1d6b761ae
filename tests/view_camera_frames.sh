#!/usr/bin/env bash
# A keyframed camera through one bake (docs/animation.md): `baker view
# --frames` over a single input renders each frame with the scene's camera
# at that frame, reads the file once (the read row says the other frames
# reused it), and every frame's image equals a single view with that
# frame's camera written out by hand (exrdiff max_abs 0). A keyframed camera
# whose look_at meets its position at some frame is refused, naming it.
# Usage: view_camera_frames.sh BAKER BENCH_TOOL WORKDIR SCENES_DIR
set -u
BAKER=$1 TOOL=$2 WORK=$3 SCENES=$4
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
scene() { # $1: the camera's position value, $2: its look_at value
  sed "s|meshes/sphere.obj|$SCENES/meshes/sphere.obj|; s/\"resolution\": 128/\"resolution\": 32/;
       s/\"count\": [0-9]*/\"count\": 5000/; s/\"resolution\": \[800, 600\]/\"resolution\": [64, 48]/;
       s/\"position\": \[0, 0.6, -3.2\]/\"position\": $1/;
       s/\"look_at\": \[0, 0, 0\]/\"look_at\": $2/" "$SCENES/sphere.json"
}
scene '{"keys": {"1": [0, 0.5, -3], "3": [1, 1.5, -2]}}' '[0, 0, 0]' > moving.json
scene '[0, 0.5, -3]' '[0, 0, 0]' > at1.json
scene '[0.5, 1, -2.5]' '[0, 0, 0]' > at2.json
scene '[1, 1.5, -2]' '[0, 0, 0]' > at3.json
grep -q '"keys"' moving.json || fail "the camera keys did not reach the scene"
"$BAKER" bake at1.json -o one.vdb -q --set photons.bounces=0 || fail "bake exited $?"

"$BAKER" view one.vdb -o anim.####.exr --frames 1-3 --scene moving.json -v > log.txt 2>&1 ||
  { cat log.txt; fail "view --frames exited $?"; }
grep -E "^read .*3 frames, 2 reused \(file unchanged\)" log.txt ||
  { cat log.txt; fail "the read row does not say 2 frames reused the file"; }
[ "$(grep -c "reused from frame 1" log.txt)" = 2 ] || { cat log.txt; fail "no per-frame reuse line"; }
for f in 1 2 3; do
  "$BAKER" view one.vdb -o "single$f.exr" --scene "at$f.json" -q || fail "view at$f exited $?"
  d=$("$TOOL" exrdiff "anim.000$f.exr" "single$f.exr") || fail "exrdiff $f"
  echo "frame $f: $d"
  echo "$d" | grep -q '"max_abs": 0[,}]' || fail "frame $f differs from its single view"
done
d=$("$TOOL" exrdiff anim.0001.exr anim.0003.exr)
echo "$d" | grep -q '"max_abs": 0[,}]' && fail "the camera did not move (frames 1 and 3 equal)"

scene '{"keys": {"1": [0, 0.5, -3], "3": [0, 0, 0]}}' '[0, 0, 0]' > bad.json
"$BAKER" view one.vdb -o bad.####.exr --frames 1-3 --scene bad.json 2> err.txt
rc=$?; cat err.txt
[ $rc = 2 ] || fail "a camera on its look_at at frame 3: exit $rc, want 2"
grep -q "bad.json.*camera.look_at.*at frame 3" err.txt || fail "the message does not name file, key and frame"
ls bad.*.exr 2>/dev/null && fail "frames written before the refusal"
echo "ok"
