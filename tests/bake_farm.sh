#!/usr/bin/env bash
# Farm-grade frames and the command line of `baker bake` (issue 13 items 5-6,
# issue 17 item 3), one CASE per run in WORKDIR/CASE.
# Usage: bake_farm.sh BAKER WORKDIR SCENES_DIR CASE
set -u
BAKER=$1 WORK=$2/$4 SCENES=$3 CASE=$4
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK" || exit 1
sed "s|meshes/sphere.obj|$SCENES/meshes/sphere.obj|; s/\"resolution\": 128/\"resolution\": 12/; s/\"count\": [0-9]*/\"count\": 2000/" \
  "$SCENES/sphere.json" > scene.json
unset SLURM_ARRAY_TASK_ID SGE_TASK_ID PBS_ARRAYID PBS_ARRAY_INDEX
fail() { echo "FAIL ($CASE): $*"; [ -f log.txt ] && cat log.txt; exit 1; }
bake() { "$BAKER" bake "$@"; }
mtime() { stat -c %Y.%N "$1"; }

case $CASE in
list_order)
  bake scene.json -o 'o.####.vdb' --frames '3,1-2,3,5-9:4' > log.txt 2>&1 || fail "exit $?"
  order=$(grep -E '^frame [0-9]+ \(' log.txt | awk '{printf "%s ", $2}')
  [ "$order" = "3 1 2 5 9 " ] || fail "frames baked in order '$order', expected 3 1 2 5 9"
  for f in 1 2 3 5 9; do [ -s o.000$f.vdb ] || fail "o.000$f.vdb missing"; done
  ;;
keep_going)
  cp scene.json s.0001.json; cp scene.json s.0003.json   # frame 2 has no scene
  bake 's.####.json' -o 'o.####.vdb' --frames 1-3 -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "without --keep-going exit $st, expected 2"
  [ -e o.0003.vdb ] && fail "without --keep-going frame 3 was baked after frame 2 failed"
  bake 's.####.json' -o 'o.####.vdb' --frames 1-3 --keep-going -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "--keep-going with a missing scene exit $st, expected 2 (bad input only)"
  [ -s o.0003.vdb ] || fail "--keep-going did not bake frame 3"
  grep -Eq '^2 +FAILED +.*s\.0002\.json' log.txt || fail "summary lacks 'frame 2 FAILED s.0002.json'"
  grep -Eq '^1 +skipped' log.txt || fail "summary lacks frame 1 skipped"
  grep -Eq '^3 +baked' log.txt || fail "summary lacks frame 3 baked"
  ;;
stale_settings)
  bake scene.json -o 'o.####.vdb' --frames 1-2 -q || fail "first bake exit $?"
  t1=$(mtime o.0001.vdb); sleep 1
  bake scene.json -o 'o.####.vdb' --frames 1-2 > log.txt 2>&1 || fail "re-run exit $?"
  [ "$(mtime o.0001.vdb)" = "$t1" ] || fail "an up-to-date frame was baked again"
  bake scene.json -o 'o.####.vdb' --frames 1-2 --photons 3000 > log.txt 2>&1 || fail "exit $?"
  grep -q "frame 1: o.0001.vdb was baked with photons 2000, now 3000: re-baking" log.txt ||
    fail "no line saying why frame 1 is re-baked"
  vdb_print -m o.0002.vdb | grep -q "photons=3000" || fail "frame 2 not re-baked with 3000 photons"
  for opt in "--seed 7" "--step 0.25" "--integrator rk4" "--compression zip" "--half" \
             "--resolution 10" "--mode adaptive"; do
    bake scene.json -o 'o.####.vdb' --frames 1 --photons 3000 $opt > log.txt 2>&1 || fail "$opt: exit $?"
    grep -q "re-baking" log.txt || fail "$opt did not re-bake frame 1"
  done
  bake scene.json -o single.vdb -q && t1=$(mtime single.vdb) && sleep 1 || fail "single bake"
  bake scene.json -o single.vdb --set photons.seed=9 > log.txt 2>&1 || fail "--set exit $?"
  grep -q "single.vdb was baked with scene" log.txt || fail "--set did not make the scene stale"
  ;;
stale_scene)
  bake scene.json -o out.vdb -q || fail "first bake exit $?"
  sed -i 's/"count": 2000/"count": 2001/' scene.json
  bake scene.json -o out.vdb > log.txt 2>&1 || fail "exit $?"
  grep -q "out.vdb was baked with scene .*re-baking" log.txt || fail "changed scene not re-baked"
  cp scene.json x.json; cp out.vdb foreign.vdb
  vdb_print -m foreign.vdb > /dev/null || fail "vdb_print"
  printf 'not a vdb' > broken.vdb
  bake scene.json -o broken.vdb > log.txt 2>&1 || fail "broken output: exit $?"
  grep -q "broken.vdb is not a complete baker file" log.txt || fail "broken output not re-baked"
  ;;
missing_scene)
  bake scene.json -o out.vdb -q || fail "first bake exit $?"
  bake nowhere.json -o out.vdb -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "missing scene with an existing output exit $st, expected 2 (never a skip)"
  grep -q "nowhere.json" log.txt || fail "message does not name the scene"
  ;;
set_override)
  bake scene.json -o a.vdb --set 'medium.sigma_s=0.3' --set 'lights[0].intensity=[5,5,5]' \
    --set photons.count=1500 --set photons.integrator=rk4 -q || fail "exit $?"
  meta=$(vdb_print -m a.vdb)
  echo "$meta" | grep -q "photon_count: 1500" || fail "photons.count=1500 not applied"
  echo "$meta" | grep -q "photon_integrator: rk4" || fail "photons.integrator=rk4 not applied"
  bake scene.json -o b.vdb --set photons.count=1500 --set photons.integrator=rk4 -q || fail "b"
  [ "$(vdb_print -m a.vdb | grep scene_hash)" != "$(vdb_print -m b.vdb | grep scene_hash)" ] ||
    fail "medium/light overrides left the scene hash unchanged"
  ;;
set_errors)
  check() { # expected message pieces after the --set
    bake scene.json -o e.vdb -q --set "$1" 2> log.txt; st=$?
    [ $st = 2 ] || fail "--set $1 exit $st, expected 2"
    shift; for w in "$@"; do grep -qF -- "$w" log.txt || fail "message lacks '$w'"; done
    [ -e e.vdb ] && fail "e.vdb written despite the error"; return 0; }
  check 'medium.sigma_s=-1' "--set medium.sigma_s=-1: medium.sigma_s:" ">= 0"
  check 'lights[0].angle_deg=120' "--set lights[0].angle_deg=120:" "(0, 90]"
  check 'lights[4].intensity=1' "lights" "no element [4]"
  check 'grid.resolution.x=1' "grid.resolution" "not an object"
  check 'photons.integrator=rk5' "--set photons.integrator=rk5" "rk4"
  check 'noequals' "KEY=VALUE"
  check 'grid.bounds[0][9]=1' "no element [9]"
  ;;
stdin_scene)
  mkdir m other && cp "$SCENES/meshes/sphere.obj" m/sphere.obj
  sed "s|$SCENES/meshes/sphere.obj|m/sphere.obj|" scene.json > other/rel.json
  bake - -o out.vdb -q < other/rel.json 2> log.txt || fail "scene on stdin exit $?"
  vdb_print -m out.vdb | grep -q "scene_file: -$" || fail "scene_file is not -"
  bake other/rel.json -o out2.vdb -q 2> /dev/null && fail "control: the path should be relative to other/"
  printf '{ "grid": 3 }' | bake - -o bad.vdb -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "bad stdin scene exit $st"; grep -q "<stdin>:1:" log.txt || fail "message lacks <stdin>:1:"
  ;;
output_refused)
  bake scene.json -o - -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "-o - exit $st, expected 2"; grep -q "standard output" log.txt || fail "-o - message"
  [ -e ./- ] && fail "a file named - was written"
  mkdir d; bake scene.json -o d -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "-o DIR exit $st, expected 2"; grep -q "is a directory" log.txt || fail "-o DIR message"
  bake scene.json -o nodir/x.vdb -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "-o into a missing directory exit $st"
  ;;
task_vars)
  SGE_TASK_ID=4 bake scene.json -o 'sge.####.vdb' -q || fail "SGE exit $?"
  [ -s sge.0004.vdb ] || fail "SGE_TASK_ID=4 did not bake frame 4"
  PBS_ARRAYID=5 bake scene.json -o 'pbs.####.vdb' -q || fail "PBS exit $?"
  [ -s pbs.0005.vdb ] || fail "PBS_ARRAYID=5 did not bake frame 5"
  PBS_ARRAY_INDEX=6 bake scene.json -o 'pbs.####.vdb' --frames task -q || fail "PBS Pro exit $?"
  [ -s pbs.0006.vdb ] || fail "PBS_ARRAY_INDEX=6 with --frames task did not bake frame 6"
  SGE_TASK_ID=undefined bake scene.json -o 'u.####.vdb' -q 2> log.txt; st=$?
  [ $st = 2 ] || fail "SGE_TASK_ID=undefined exit $st, expected 2 (no task)"
  grep -q "no array task variable" log.txt || fail "undefined task message"
  SLURM_ARRAY_TASK_ID=2 SGE_TASK_ID=3 bake scene.json -o 's.####.vdb' --frames 7 -q || fail "exit"
  [ -s s.0007.vdb ] && [ ! -e s.0002.vdb ] || fail "--frames LIST must win over the task variable"
  ;;
progress_json)
  bake scene.json -o 'o.####.vdb' --frames 2 --progress=json -q 2> log.txt || fail "exit $?"
  grep -qE '^\{"stage":"[^"]+","fraction":[0-9.]+,"eta_s":([0-9.]+|null),"frame":2\}$' log.txt ||
    fail "no JSON progress line with frame 2"
  grep -vE '^\{' log.txt && fail "non-JSON lines on stderr with -q --progress=json"
  python3 -c 'import json,sys; [json.loads(l) for l in open("log.txt")]' || fail "invalid JSON"
  bake scene.json -o x.vdb --progress=xml -q 2> log.txt; [ $? = 2 ] || fail "--progress=xml accepted"
  ;;
log_threads)
  echo "earlier line" > run.log
  bake scene.json -o x.vdb --threads 1 --log run.log -q 2> err.txt || fail "exit $?"
  [ -s err.txt ] && fail "-q printed: $(cat err.txt)"
  head -1 run.log | grep -q "earlier line" || fail "--log did not append"
  grep -q "sphere.obj: 1280 triangles" run.log || fail "--log lacks the messages -q hides"
  bake nowhere.json -o x.vdb --log run.log -q 2> /dev/null
  grep -q "baker bake: nowhere.json" run.log || fail "--log lacks the error"
  bake scene.json -o x.vdb --threads 0 2> log.txt; [ $? = 2 ] || fail "--threads 0 accepted"
  bake scene.json -o x.vdb --log /nonexistent/dir/f.log 2> log.txt; [ $? = 2 ] || fail "bad --log"
  ;;
*) fail "unknown case" ;;
esac
echo "bake farm $CASE: ok"
