#!/usr/bin/env bash
# The GNU parallel recipe for real (scripts/farm/parallel_frames): 3 frames
# of a tiny scene, each a job, all open as their frame; a rerun skips them.
# Exit 77 (skipped) without GNU parallel. Usage: farm_parallel.sh BAKER SOURCE_DIR WORKDIR
set -u
BAKER=$1 SRC=$2 WORK=$3
command -v parallel >/dev/null || { echo "SKIP: GNU parallel not installed (apt-get install parallel)"; exit 77; }
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK" || exit 1
sed "s|\"resolution\": 128|\"resolution\": 16|; s|meshes/|$SRC/scenes/meshes/|" "$SRC/scenes/cube.json" > scene.json
export BAKER BAKER_JOBS=2
"$SRC/scripts/farm/parallel_frames" 1-3 scene.json 'out.$F4.vdb' --photons 1000 -q || fail "parallel_frames exited $?"
for f in 1 2 3; do
  vdb_print -m out.000$f.vdb | grep -q "frame: $f" || fail "out.000$f.vdb does not open as frame $f"
done
[ "$(tail -n +2 baker-frames.joblog | wc -l)" = 3 ] || fail "the job log does not list 3 jobs"
"$SRC/scripts/farm/parallel_frames" 1-3 scene.json 'out.$F4.vdb' --photons 1000 || fail "rerun exited $?"
echo "parallel: 3 jobs baked 3 frames"
