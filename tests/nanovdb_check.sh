#!/usr/bin/env bash
# NanoVDB and the metadata other tools check (DESIGN §5, issue 13):
# `-o x.nvdb` writes a file nanovdb_validate passes, with `density` a float fog
# volume (what pbrt-v4's nanovdb medium reads); nanovdb_convert of a baked .vdb
# passes too (no fog class on vector grids); the ior background is the
# medium's n and the bounds are vectors; `baker view` of the .nvdb is the
# image of the .vdb. nanovdb_validate exits 0 even when a grid fails, so its
# lines are counted.
# Usage: nanovdb_check.sh BAKER BENCH_TOOL WORKDIR SCENES_DIR
set -u
BAKER=$1 BENCH=$2 WORK=$3 SCENES=$4
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
sed "s|meshes/sphere.obj|$SCENES/meshes/sphere.obj|; s/\"ior\": 1.0 }/\"ior\": 1.25 }/" \
  "$SCENES/sphere.json" > scene.json
grep -q '"ior": 1.25' scene.json || fail "could not set the medium's n in the scene"
bake() { "$BAKER" bake scene.json --photons 50000 --resolution 40 -q "$@" || fail "bake $* exited $?"; }
bake -o s.vdb
bake -o s.nvdb

validate() { # file, grid count
  nanovdb_validate -v "$1" > "$1.log" 2>&1; cat "$1.log"
  grep -q failed "$1.log" && fail "nanovdb_validate: a grid of $1 failed"
  [ "$(grep -c ': passed' "$1.log")" = "$2" ] || fail "nanovdb_validate passed not all $2 grids of $1"
}
validate s.nvdb 6
nanovdb_convert -f s.vdb c.nvdb || fail "nanovdb_convert exited $?"
validate c.nvdb 6
nanovdb_print s.nvdb | tee print.txt
grep -Eq '^[0-9]+ +density +float +FOG ' print.txt || fail "density is not a float fog volume"
grep -Eq '^[0-9]+ +emission +Vec3f ' print.txt || fail "no Vec3f emission grid"

/usr/bin/python3 - s.vdb <<'PY' || fail "metadata check"
import sys, pyopenvdb as vdb
path = sys.argv[1]
meta = {g.name: g for g in vdb.readAllGridMetadata(path)}
fm = vdb.readMetadata(path)
ok = True
def need(cond, what):
    global ok
    print(("ok   " if cond else "FAIL ") + what)
    ok = ok and cond
need(abs(vdb.read(path, "ior").background - 1.25) < 1e-6, "ior background is the medium's n")
for name in ("radiance", "emission"):
    g = meta[name]
    need(g.gridClass == "unknown", f"{name} has no grid class (got {g.gridClass})")
    need(g.metadata.get("vector_type") == "invariant", f"{name} vector_type invariant")
for name in ("ior", "extinction", "scattering", "density"):
    need(meta[name].gridClass == "fog volume", f"{name} is a fog volume")
near = lambda v, w: len(v) == 3 and all(abs(a - b) < 1e-5 for a, b in zip(v, w))
need(near(fm["grid_bounds_min"], (-1, -1, -1)) and near(fm["grid_bounds_max"], (1, 1, 1)),
     "grid_bounds_min/max are vectors")
need(isinstance(fm.get("grid_bounds"), str), "grid_bounds string kept")
sys.exit(0 if ok else 1)
PY

view() { "$BAKER" view "$1" --scene scene.json -o "$2" --resolution 96x72 -q || fail "view $1 exited $?"; }
view s.vdb v_vdb.exr
view s.nvdb v_nvdb.exr
d=$("$BENCH" exrdiff v_nvdb.exr v_vdb.exr) || fail "exrdiff exited $?"
echo "view .nvdb vs .vdb: $d"
echo "$d" | grep -q '"differ": 0[,}]' || fail "the .nvdb view differs from the .vdb view"
echo "nanovdb_check: ok"
