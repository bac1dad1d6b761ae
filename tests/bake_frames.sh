#!/usr/bin/env bash
# Frame ranges in `baker bake` (DESIGN §6-7): a range writes one file per
# frame, a second run skips complete frames (restartable), a Slurm array task
# bakes its own frame, a range into a path without a pattern is refused, and a
# fresh bake says its scene's warnings once.
# Usage: bake_frames.sh BAKER WORKDIR SCENES_DIR
set -u
BAKER=$1 WORK=$2 SCENES=$3
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK" || exit 1
sed "s|meshes/sphere.obj|$SCENES/meshes/sphere.obj|; s/\"resolution\": 128/\"resolution\": 24/; s/\"count\": [0-9]*/\"count\": 5000/" \
  "$SCENES/sphere.json" > scene.json
fail() { echo "FAIL: $*"; exit 1; }

"$BAKER" bake scene.json -o 'out.####.vdb' --frames 1-5x2 -q || fail "range bake exited $?"
for f in out.0001.vdb out.0003.vdb out.0005.vdb; do [ -s "$f" ] || fail "$f missing"; done
[ -e out.0002.vdb ] && fail "frame 2 is not in 1-5x2"
vdb_print -m out.0003.vdb | grep -q "frame: 3" || fail "out.0003.vdb metadata lacks frame 3"

before=$(stat -c %Y.%s out.0003.vdb); sleep 1
"$BAKER" bake scene.json -o 'out.####.vdb' --frames 1-7x2 > log.txt 2>&1 || fail "restart exited $?"
[ "$(stat -c %Y.%s out.0003.vdb)" = "$before" ] || fail "complete frame 3 was baked again"
[ -s out.0007.vdb ] || fail "frame 7 was not baked on restart"
grep -q "3 skipped" log.txt || fail "restart did not report 3 skipped frames"

SLURM_ARRAY_TASK_ID=12 "$BAKER" bake scene.json -o 'slurm.$F4.vdb' -q || fail "slurm task exited $?"
[ -s slurm.0012.vdb ] || fail "slurm array task 12 did not write slurm.0012.vdb"

"$BAKER" bake scene.json -o single.vdb --frames 1-3 -q 2> err.txt; st=$?
[ $st = 2 ] || fail "range into a plain path exited $st, expected 2"
grep -q "single.vdb" err.txt || fail "message does not name the output"
[ -e single.vdb ] && fail "single.vdb written despite the error"
# a scene's warnings are said once per frame, not once more by the check
# of an existing output (there is none here)
"$BAKER" bake scene.json -o once.vdb --set no.such=1 2> err.txt || fail "bake with an unknown --set key exited $?"
[ "$(grep -c 'no.such=1: no: unknown key' err.txt)" = 1 ] || fail "the unknown key's warning is not said exactly once: $(cat err.txt)"
# ... nor by the check that finds the existing output baked otherwise
"$BAKER" bake scene.json -o once.vdb --set no.such=1 --photons 4000 2> err.txt || fail "re-bake exited $?"
grep -q "re-baking" err.txt || fail "once.vdb was not re-baked with other photons: $(cat err.txt)"
[ "$(grep -c 'no.such=1: no: unknown key' err.txt)" = 1 ] || fail "the re-bake's warning is not said exactly once: $(cat err.txt)"
echo "bake frames: ok"
