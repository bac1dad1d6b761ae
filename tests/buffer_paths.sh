#!/usr/bin/env bash
# The batch runner's three ways to the sums give the same bake, bit for bit,
# radiance and error estimate alike: PoCL's buffers mapped in place (a CPU
# device), the GPU's path with PoCL standing in (BAKER_CL_DISCRETE=1:
# inputs copied to the device, sums read back after each batch and zeroed
# on the device where the batch callback asks) and the host's plain C march
# (--host). Cases: a reference bake (its twins have the sums zeroed between
# batches), target mode whose pilot restarts (the plan has them zeroed),
# adaptive mode (its filter's copies; no --host there), and a 208^3 bake
# whose sums (72 MB) go through the pinned stages of
# baker/clcopy.c, not straight.
# Usage: buffer_paths.sh SOURCE_DIR BAKER WORKDIR BENCH_TOOL
set -u
SRC=$1 BAKER=$2 WORK=$3 TOOL=$4
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$WORK" && mkdir -p "$WORK" || exit 1
"$BAKER" devices | grep -q 'Portable Computing Language' || { echo "SKIP: no PoCL device"; exit 77; }
COMMON=(bake "$SRC/scenes/sphere.json" --resolution 32 --photons 20000 --force -v -v)
bake() { # NAME PATH ARGS...: PATH is mapped, copied or host
  local name=$1 path=$2; shift 2
  local d=0 host=(); [ "$path" = copied ] && d=1; [ "$path" = host ] && host=(--host)
  BAKER_CL_DISCRETE=$d "$BAKER" "${COMMON[@]}" "${host[@]}" "$@" -o "$WORK/$name-$path.vdb" \
    --stats "$WORK/$name-$path.json" > "$WORK/$name-$path.log" 2>&1 ||
    { tail "$WORK/$name-$path.log"; fail "$name: the $path bake"; }
}
same() { # NAME PATH: compares with NAME's mapped bake
  local j; j=$("$TOOL" vdbdiff "$WORK/$1-mapped.vdb" "$WORK/$1-$2.vdb" radiance) || fail "$1: vdbdiff"
  grep -q '"max_abs": 0,' <<<"$j" || fail "$1: radiance differs on the $2 path: $j"
  python3 - "$WORK/$1-mapped.json" "$WORK/$1-$2.json" <<'PY' || fail "$1: the error estimate differs on the $2 path"
import json, sys
a, b = (json.load(open(p)).get("error") for p in sys.argv[1:])
keys = ("estimate", "noise", "step", "filter", "batches", "twin_batches")  # not the times
sys.exit(0 if a and b and all(a[k] == b[k] for k in keys) else 1)
PY
}
for p in mapped copied host; do bake reference $p; done
grep -q "twins with the bake's integrator" "$WORK/reference-copied.log" || fail "reference: no twins traced"
same reference copied && same reference host
for p in mapped copied host; do bake target $p --target-error 0.1 --set photons.bounces=0; done
grep -q "restarting with batches" "$WORK/target-copied.log" || fail "target: the pilot did not restart"
same target copied && same target host
for p in mapped copied; do bake adaptive $p --set photons.mode=adaptive --set photons.bounces=0; done
same adaptive copied
for p in mapped copied; do bake staged $p --resolution 208 --photons 4000 --set photons.bounces=0; done
same staged copied
echo "buffer paths: ok"
