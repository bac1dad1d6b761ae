#!/usr/bin/env bash
# scripts/gpu-check: without a GPU it says so and exits 3; with PoCL standing
# in for the GPU (--device) the whole path runs: bake, view, PoCL bake,
# comparison (bench_tool vdbdiff) within 1e-5, report; --set reaches both
# bakes; grids of another seed are told apart; notes outside the report's
# markers survive a rewrite.
# Usage: gpu_check.sh SOURCE_DIR BAKER WORKDIR BENCH_TOOL
set -u
SRC=$1 BAKER=$2 WORK=$3 TOOL=$4
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$WORK" && mkdir -p "$WORK" || exit 1
G=$SRC/scripts/gpu-check
if ! "$BAKER" devices | grep -E '^ +[0-9]+:[0-9]+ ' | grep -vq 'Portable Computing Language'; then
  "$G" --baker "$BAKER" --tool "$TOOL" --out "$WORK/none" > "$WORK/none.txt"; st=$?
  [ $st = 3 ] || fail "no GPU: exit $st, expected 3"
  grep -q "no non-PoCL OpenCL device found" "$WORK/none.txt" || fail "no GPU: message missing"
fi
pocl=$("$BAKER" devices | grep 'Portable Computing Language' | head -1 | awk '{print $1}')
[ -n "$pocl" ] || { echo "SKIP: no PoCL device"; exit 77; }
printf '<!-- gpu-check report: begin -->\nstale\n<!-- gpu-check report: end -->\nNOTE-KEPT\n' > "$WORK/gpu.md"
"$G" --baker "$BAKER" --tool "$TOOL" --device "$pocl" --resolution 16 --photons 2000 \
  --set photons.bounces=0 --out "$WORK/run" --doc "$WORK/gpu.md" > "$WORK/run.txt" 2>&1 ||
  { cat "$WORK/run.txt"; fail "gpu-check with PoCL standing in exited $?"; }
grep -q "agree" "$WORK/gpu.md" || fail "the report does not say the grids agree"
grep -q "photons.bounces=0" "$WORK/gpu.md" || fail "the report does not name the --set"
grep -q "^NOTE-KEPT$" "$WORK/gpu.md" || fail "the notes outside the report's markers were lost"
! grep -q "^stale$" "$WORK/gpu.md" || fail "the old report between the markers was kept"
grep -q "single scattering" "$WORK/run/bake-gpu.log" || fail "--set photons.bounces=0 did not reach the bake"
"$BAKER" bake "$SRC/scenes/sphere.json" -o "$WORK/other.vdb" --resolution 16 --photons 2000 \
  --set photons.bounces=0 --seed 7 --force -q || fail "bake with another seed"
"$G" --tool "$TOOL" --compare "$WORK/other.vdb" "$WORK/run/pocl.vdb" > "$WORK/cmp.txt"; st=$?
[ $st = 1 ] || { cat "$WORK/cmp.txt"; fail "grids of another seed: exit $st, expected 1"; }
grep -q "^| view |" "$WORK/gpu.md" || fail "the report lacks the view timing"
grep -Eq "^\| bake \| .* \| [0-9.]+ \| [0-9]+ \|$" "$WORK/gpu.md" || fail "the report lacks the bakes' peak memory"
[ -s "$WORK/run/gpu.exr" ] || fail "no view image"
echo "gpu-check: ok"
