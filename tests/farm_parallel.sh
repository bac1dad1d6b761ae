#!/usr/bin/env bash
# The GNU parallel recipes for real (scripts/farm/): 3 frames of a tiny scene,
# each a job, all open as their frame; a rerun skips them (parallel_frames).
# One frame as 3 photon shards, merged: equal to the bake on one machine
# (the grids' checksums), shards deleted (parallel_shards).
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

"$SRC/scripts/farm/parallel_shards" 3 scene.json merged.vdb --photons 3001 -q || fail "parallel_shards exited $?"
"$BAKER" bake scene.json -o single.vdb --photons 3001 -q || fail "single bake failed"
sums() { vdb_print -m "$1" | grep -E '^(checksum_[a-z_]+|photon_count|bake_settings):' | grep -v checksum_box; }
[ "$(sums merged.vdb)" = "$(sums single.vdb)" ] ||
  fail "merged and single bake differ: $(diff <(sums merged.vdb) <(sums single.vdb))"
ls merged.shard-* >/dev/null 2>&1 && fail "parallel_shards left its shards"
[ "$(tail -n +2 merged.shards.joblog | wc -l)" = 3 ] || fail "the job log does not list 3 shard jobs"
echo "parallel: 3 shard jobs merged = the single bake (grid checksums equal)"
