#!/usr/bin/env bash
# Runs `baker bake` on one kind of bad input and checks that it exits with
# status 2, that stderr names the offending file and the problem, and that no
# output file (nor a temporary one) is left behind.
# Usage: cli_bad_input.sh BAKER WORKDIR MESHDIR CASE
set -u
BAKER=$1 WORK=$2/$4 MESHES=$3 CASE=$4
rm -rf "$WORK" && mkdir -p "$WORK/out" && cd "$WORK" || exit 1

good_grid='"grid": { "bounds": [[-1,-1,-1],[1,1,1]], "resolution": 16 }'
light='"lights": [ { "type": "point", "position": [0,0,0], "intensity": [1,1,1] } ]'
scene() { printf '{\n  %s,\n  %s%s\n}\n' "$good_grid" "$light" "$1" > scene.json; }
out=out/result.vdb
expect_status=2

case "$CASE" in
  malformed_json)
    printf '{\n  "grid": { "bounds": [[-1,-1,-1],[1,1,1]] "resolution": 16 }\n}\n' > scene.json
    expect=("scene.json:2:" "expected");;
  missing_key)
    printf '{\n  "grid": { "bounds": [[-1,-1,-1],[1,1,1]] }\n}\n' > scene.json
    expect=("scene.json:" "resolution");;
  wrong_type)
    printf '{\n  "grid": { "bounds": [[-1,-1,-1],[1,1,1]], "resolution": "sixteen" }\n}\n' > scene.json
    expect=("scene.json:2:" "grid.resolution" "string");;
  negative_resolution)
    printf '{\n  "grid": { "bounds": [[-1,-1,-1],[1,1,1]],\n           "resolution": -5 }\n}\n' > scene.json
    expect=("scene.json:3:" "grid.resolution" "-5");;
  huge_grid)
    printf '{\n  "grid": { "bounds": [[-1,-1,-1],[1,1,1]], "resolution": 100000 }\n}\n' > scene.json
    expect=("scene.json" "100000x100000x100000" "would need" "PiB");;
  missing_mesh)
    scene ', "objects": [ { "mesh": "nowhere/missing.obj", "ior": 1.5 } ]'
    expect=("missing.obj" "objects[0].mesh");;
  nan_mesh)
    printf 'v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n' > nan.obj
    scene ', "objects": [ { "mesh": "nan.obj", "ior": 1.5 } ]'
    expect=("nan.obj" "non-finite");;
  empty_mesh)
    printf '# nothing here\n' > empty.obj
    scene ', "objects": [ { "mesh": "empty.obj", "ior": 1.5 } ]'
    expect=("empty.obj" "no triangles");;
  unwritable_output)
    scene ''
    mkdir -p locked && chmod 555 locked
    out=locked/result.vdb
    # root may write anywhere a mode allows: use a directory nobody can create files in
    if [ "$(id -u)" = 0 ]; then out=/proc/result.vdb; fi
    expect=("result.vdb" "not writable");;
  truncated_ior_vdb)
    # a real VDB written by baker itself, cut in half
    scene ''
    "$BAKER" bake scene.json -o full.vdb -q || { echo "could not make the VDB to truncate"; exit 1; }
    head -c $(( $(stat -c %s full.vdb) / 2 )) full.vdb > cut.vdb
    printf '{\n  %s,\n  "medium": { "ior_vdb": { "file": "cut.vdb", "grid": "ior" } },\n  %s\n}\n' \
      "$good_grid" "$light" > scene.json
    expect=("cut.vdb");;
  fifo_mesh)
    # a pipe with no writer: opening it to read would wait for ever
    mkfifo pipe.obj || { echo "FAIL: mkfifo failed"; exit 1; }
    scene ', "objects": [ { "mesh": "pipe.obj", "ior": 1.5 } ]'
    expect=("pipe.obj" "not a regular file" "objects[0].mesh");;
  device_vdb)
    # /dev/zero never ends: hashing it for frame reuse, or reading it, would
    # not stop
    scene ', "medium": { "sigma_s": [1,1,1], "sigma_a": [0,0,0],
                "density_vdb": { "file": "/dev/zero", "grid": "density" } }'
    expect=("/dev/zero" "not a regular file");;
  *) echo "unknown case $CASE"; exit 1;;
esac

# bounded time: a hang fails the case (exit 124) instead of the suite
timeout 60 "$BAKER" bake scene.json -o "$out" -q 2> stderr.txt
status=$?
fail=0
if [ "$status" != "$expect_status" ]; then
  echo "FAIL: exit status $status, expected $expect_status"; fail=1
fi
for s in "${expect[@]}"; do
  grep -qF -- "$s" stderr.txt || { echo "FAIL: stderr lacks '$s'"; fail=1; }
done
leftover=$(find "$(dirname "$out")" -maxdepth 1 \( -name 'result.vdb' -o -name '.result.vdb.tmp*' \) 2>/dev/null)
[ -z "$leftover" ] || { echo "FAIL: output left behind: $leftover"; fail=1; }
echo "--- stderr:"; cat stderr.txt
exit $fail
