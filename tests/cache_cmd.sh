#!/usr/bin/env bash
# `baker cache` and the cap in a real bake: a bake into a cache holding old
# entries past BAKER_CACHE_MAX_MB prunes the oldest and keeps its own; `baker
# cache` reports path, entries and size; `--clear` empties it and leaves
# other files alone. Usage: cache_cmd.sh BAKER WORKDIR SCENES_DIR
set -u
BAKER=$1 WORK=$2 SCENES=$3
rm -rf "$WORK" && mkdir -p "$WORK/cache" && cd "$WORK" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
export BAKER_CACHE_DIR=$WORK/cache
unset BAKER_NO_CACHE

# three stale entries of 300 KiB, last used 3, 2 and 1 hours ago
for i in 1 2 3; do
  f=cache/$(printf '%016x' $i).clbin
  head -c 307200 /dev/zero > "$f"
  touch -d "-$((4 - i)) hours" "$f"
done
echo keep > cache/README
BAKER_CACHE_MAX_MB=0.8 "$BAKER" bake "$SCENES/cube.json" -o a.vdb --resolution 16 \
  --photons 1000 --force -q || fail "bake exited $?"
[ -e cache/0000000000000001.clbin ] && fail "the least recently used entry was not pruned"
[ -e cache/0000000000000003.clbin ] || fail "the most recently used stale entry was pruned"
new=$(ls cache/*.clbin | grep -v '/000000000000000[123]' | wc -l)
[ "$new" -ge 1 ] || fail "the bake's own kernel binary is not in the cache"
total=$(du -cb cache/*.clbin | tail -1 | cut -f1)
[ "$total" -le 838861 ] || echo "note: $total bytes after the bake (its own binaries stay)"

"$BAKER" cache > info.txt || fail "baker cache exited $?"
grep -q "kernel cache: $WORK/cache" info.txt || fail "baker cache does not print the path: $(cat info.txt)"
n=$(ls cache/*.clbin | wc -l)
grep -q "entries: $n$" info.txt || fail "baker cache does not count $n entries: $(cat info.txt)"
grep -q "MiB cap" info.txt || fail "baker cache does not print the cap"

"$BAKER" cache --clear > clear.txt || fail "baker cache --clear exited $?"
grep -q "removed $n entr" clear.txt || fail "--clear did not report $n entries: $(cat clear.txt)"
ls cache/*.clbin 2>/dev/null && fail "--clear left entries"
[ -e cache/README ] || fail "--clear removed a file that is not a cache entry"
"$BAKER" cache | grep -q "entries: 0$" || fail "baker cache after --clear is not empty"
"$BAKER" cache --bogus 2>/dev/null; [ $? = 2 ] || fail "an unknown option must exit 2"
BAKER_NO_CACHE=1 "$BAKER" cache | grep -q "off" || fail "BAKER_NO_CACHE=1 must say the cache is off"
echo "cache: ok"
