#!/usr/bin/env bash
# Keyframed lights and frame reuse (docs/animation.md): a 3-frame batch at
# 32^3 in which only the light moves voxelizes once, keeps the octree and the
# OpenCL context (the --stats JSON says so per stage), and writes grids
# bit-identical (checksum_v2_<grid> metadata, checked by `baker verify`) to
# three separate single-frame bakes; the light really moves (radiance
# differs between frames); a keyframed object transform rebuilds the voxels
# and is still bit-identical; bad keyframes exit 2 naming file and key.
# Usage: bake_reuse.sh BAKER WORKDIR SCENES_DIR
set -u
BAKER=$1 WORK=$2 SCENES=$3
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
command -v vdb_print >/dev/null || { echo "SKIP: vdb_print not found"; exit 77; }
base() { # $1: the light's position value, $2: the object's translate value
  sed "s|meshes/sphere.obj|$SCENES/meshes/sphere.obj|; s/\"resolution\": 128/\"resolution\": 32/;
       s/\"count\": [0-9]*/\"count\": 20000/; s/\"position\": \[0, 3, 0\]/\"position\": $1/;
       s/\"translate\": \[0, 0.2, 0\]/\"translate\": $2/" "$SCENES/sphere.json"
}
LIGHT='{"keys": {"1": [0, 3, 0], "3": [0.6, 2.5, 0.2]}}'
base "$LIGHT" '[0, 0.2, 0]' > light.json
base '[0, 3, 0]' '{"keys": {"1": [0, 0.2, 0], "3": [0.2, 0.1, 0]}}' > object.json
sums() { vdb_print -m "$1" | grep "checksum_" | sort; }

# $1 scene, $2 stem, then bake options: the batch, then each frame alone;
# grids must agree
batch_and_alone() {
  local scene=$1 stem=$2; shift 2
  "$BAKER" bake "$scene" -o "$stem.batch.####.vdb" --frames 1-3 --stats "$stem.####.json" -q "$@" ||
    fail "$stem: batch exited $?"
  set -- "$scene" "$stem" "$@"
  for f in 1 2 3; do
    "$BAKER" bake "$1" -o "$2.alone.####.vdb" --frames $f -q "${@:3}" ||
      fail "$2: frame $f alone exited $?"
    b="$2.batch.000$f.vdb" a="$2.alone.000$f.vdb"
    [ -n "$(sums "$b")" ] || fail "$b: no checksum metadata"
    [ "$(sums "$b")" = "$(sums "$a")" ] || { diff <(sums "$b") <(sums "$a"); fail "$b differs from $a"; }
    "$BAKER" verify "$b" > /dev/null || fail "baker verify $b"
  done
}
reused() { # $1 stats file, $2 stage name: prints true/false
  python3 -c "import json,sys; s=[x for x in json.load(open(sys.argv[1]))['stages'] if x['name']==sys.argv[2]]
print('missing' if not s else 'true' if s[0]['reused'] else 'false')" "$1" "$2"
}

batch_and_alone light.json light
[ "$(sums light.batch.0001.vdb | grep radiance)" != "$(sums light.batch.0003.vdb | grep radiance)" ] ||
  fail "the keyframed light did not change the radiance between frames 1 and 3"
ior1=$(sums light.batch.0001.vdb | grep checksum_v2_ior)
[ -n "$ior1" ] || fail "light.batch.0001.vdb records no checksum_v2_ior"
[ "$ior1" = "$(sums light.batch.0003.vdb | grep checksum_v2_ior)" ] ||
  fail "a light move changed the ior grid"
for stage in voxelize octree "OpenCL init"; do
  [ "$(reused light.0001.json "$stage")" = false ] || fail "frame 1: $stage not false"
  for f in 2 3; do
    [ "$(reused light.000$f.json "$stage")" = true ] || fail "frame $f: $stage not reused"
  done
done
grep -q '"reused_from_frame": 1' light.0003.json || fail "frame 3 does not name frame 1"

# adaptive mode keeps the volume, the octree and the context as well
batch_and_alone light.json adaptive --mode adaptive
for stage in voxelize octree "OpenCL init"; do
  [ "$(reused adaptive.0003.json "$stage")" = true ] || fail "adaptive frame 3: $stage not reused"
done

batch_and_alone object.json object
for f in 2 3; do
  [ "$(reused object.000$f.json voxelize)" = false ] || fail "moved object: frame $f voxels reused"
  [ "$(reused object.000$f.json "OpenCL init")" = true ] || fail "object: frame $f context not kept"
done

# bad keyframes: exit 2, the file and the key named, no output
bad() { # $1 the light's position value, $2 text the message must hold
  base "$1" '[0, 0.2, 0]' > bad.json
  "$BAKER" bake bad.json -o bad.vdb -q 2> err.txt; st=$?
  [ $st = 2 ] || fail "bad keys $1: exit $st, expected 2"
  grep -q "bad.json:[0-9]*:[0-9]*: lights\[0\].position.keys" err.txt && grep -q "$2" err.txt ||
    { cat err.txt; fail "bad keys $1: message"; }
  [ -e bad.vdb ] && fail "bad keys $1: bad.vdb written"
  return 0
}
bad '{"keys": {"one": [0, 3, 0]}}' "whole frame number"
bad '{"keys": {"1": [0, 3]}}' "keys.1: expected an array of 3 numbers"
bad '{"keys": {}}' "empty object"
bad '{"keys": {"1": [0, 3, 0], "01": [0, 2, 0]}}' "keyed twice"
echo "bake reuse: ok"
