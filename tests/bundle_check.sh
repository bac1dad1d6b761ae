#!/usr/bin/env bash
# The relocatable bundle (scripts/bundle, issue 14 item 5): unpacked into a
# fresh folder with the system's OpenCL vendors hidden (OCL_ICD_VENDORS = an
# empty folder, so only the bundled PoCL can serve) and LD_LIBRARY_PATH
# unset, `bin/baker --version`, `devices` and a tiny bake work, and every
# library the loader maps, the dlopen'ed PoCL and its drivers included, lies
# inside the bundle (or is a kernel PoCL compiled into its cache) or is one
# of the allowed system libraries. Then the --no-pocl flavour finds a driver
# that has no ICD file by its soname.
# Usage: bundle_check.sh SOURCE_DIR BUILD_DIR WORKDIR   (exit 77: skipped)
set -u
SRC=$1 BUILD=$2 WORK=$3
fail() { echo "FAIL: $*"; exit 1; }
command -v patchelf >/dev/null || { echo "SKIP: patchelf is not installed (apt-get install patchelf)"; exit 77; }
[ -e /usr/lib/x86_64-linux-gnu/libpocl.so.2 ] || { echo "SKIP: PoCL is not installed"; exit 77; }
rm -rf "$WORK" && mkdir -p "$WORK/node" "$WORK/icd-empty" || exit 1
"$SRC/scripts/bundle" --fast --build "$BUILD" -o "$WORK/baker-bundle.tar.gz" || fail "scripts/bundle exited $?"
tar -C "$WORK/node" -xzf "$WORK/baker-bundle.tar.gz" || fail "cannot unpack the bundle"
rm "$WORK/baker-bundle.tar.gz"
B=$WORK/node/baker
cd "$WORK/node" || exit 1
unset LD_LIBRARY_PATH BAKER_NO_CACHE
export OCL_ICD_VENDORS=$WORK/icd-empty BAKER_CACHE_DIR=$WORK/kcache POCL_CACHE_DIR=$WORK/pocl-cache

"$B/bin/baker" --version | grep -q "^baker " || fail "bin/baker --version"
"$B/bin/baker" devices > devices.txt 2>&1 || fail "bin/baker devices: $(cat devices.txt)"
grep -q "Portable Computing Language" devices.txt || fail "the bundled PoCL is not listed: $(cat devices.txt)"

cat > scene.json <<'JSON'
{ "grid": {"resolution": 16, "bounds": [[-1,-1,-1],[1,1,1]]},
  "medium": {"sigma_s": 0.5, "sigma_a": 0.1},
  "lights": [{"type": "directional", "direction": [0,-1,0], "irradiance": 1}],
  "photons": {"count": 1000} }
JSON
LD_DEBUG=libs "$B/bin/baker" bake scene.json -o tiny.vdb --force -q 2> ld.txt || {
  grep -v "^ *[0-9]*:" ld.txt; fail "bundled bake exited non-zero"; }
[ -s tiny.vdb ] || fail "the bundled bake wrote no tiny.vdb"
grep -q "calling init: $B/lib/x86_64-linux-gnu/libpocl.so.2" ld.txt || fail "the bundled libpocl was not loaded"

ALLOWED='/(linux-vdso|ld-linux[^/]*|libc|libm|libstdc\+\+|libgcc_s|libpthread|libdl|librt|libOpenCL)\.so[.0-9]*$'
# the baker process only: PoCL runs the system's ld, and the wrapper sh and coreutils
pid=$(grep "initialize program: $B/libexec/baker" ld.txt | head -1 | tr -d ' ' | cut -d: -f1)
[ -n "$pid" ] || fail "LD_DEBUG shows no baker process"
outside=$(grep "^ *$pid:" ld.txt | sed -n 's/.*calling init: //p' | sort -u | grep -v "^$B/" | grep -v "^$POCL_CACHE_DIR/" | grep -Ev "$ALLOWED")
[ -z "$outside" ] || fail "loaded from outside the bundle: $outside"
for f in "$B/libexec/baker" "$B"/lib/x86_64-linux-gnu/*.so* "$B"/lib/x86_64-linux-gnu/pocl/*.so; do
  bad=$(ldd "$f" | awk '$2 == "=>" {print $1, $3}' | grep -v " $B/" | grep -Ev "^[^ ]* /.*$ALLOWED" | grep -Ev "^(libc|libm|libstdc\+\+|libgcc_s|libpthread|libdl|librt|libOpenCL)\.so[.0-9]* ")
  [ -z "$bad" ] || fail "ldd $f resolves outside the bundle: $bad"
done

# --no-pocl on a node whose GPU driver has no ICD file (docs/gpu.md): the
# wrapper finds the driver by its soname in the loader's cache. The system's
# PoCL stands in for libnvidia-opencl.so.1 (BAKER_ICD_DRIVERS).
"$SRC/scripts/bundle" --no-pocl --fast --build "$BUILD" -o "$WORK/nopocl.tar.gz" > /dev/null ||
  fail "scripts/bundle --no-pocl exited $?"
mkdir -p "$WORK/node2" && tar -C "$WORK/node2" -xzf "$WORK/nopocl.tar.gz" || fail "cannot unpack --no-pocl"
N=$WORK/node2/baker/bin/baker
BAKER_ICD_DRIVERS= "$N" devices 2>&1 | grep -q "Portable Computing Language" &&
  fail "--no-pocl with no ICD files and no drivers looked for still lists PoCL"
BAKER_ICD_DRIVERS=libpocl.so.2 "$N" devices > devices2.txt 2>&1
grep -q "Portable Computing Language" devices2.txt ||
  fail "a driver without an ICD file was not found by its soname: $(cat devices2.txt)"
echo "bundle: ok ($(du -sm "$B" | cut -f1) MiB unpacked)"
rm -rf "$WORK/node" "$WORK/node2" "$WORK/pocl-cache" "$WORK/nopocl.tar.gz" # 500 MiB; a failure leaves them to look at
