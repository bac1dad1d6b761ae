#!/usr/bin/env bash
# ctest's fuzz cases (tests/fuzz.cmake).
#   ctest_fuzz.sh short BINDIR TARGET TESTDIR WORKDIR SECONDS
#     a short libFuzzer run of TARGET from its seed corpus (fixed seed);
#     exit 77 (skipped) when the target was not built: clang's libFuzzer is
#     missing or BAKER_FUZZ is off.
#   ctest_fuzz.sh replay REPLAY-BINARY TARGET TESTDIR
#     every saved input under tests/data/fuzz/TARGET through the target's
#     code built without libFuzzer (a crash fails the test).
set -u
mode=$1
if [ "$mode" = replay ]; then
  bin=$2 target=$3 testdir=$4
  dir=$testdir/data/fuzz/$target
  inputs=$(find "$dir" -type f 2>/dev/null | sort)
  [ -n "$inputs" ] || { echo "no saved inputs for $target under $dir"; exit 0; }
  # shellcheck disable=SC2086
  exec "$bin" $inputs
fi

bindir=$2 target=$3 testdir=$4 work=$5 seconds=$6
if [ ! -x "$bindir/$target" ]; then
  echo "SKIPPED: $target not built: clang's libFuzzer (clang -fsanitize=fuzzer) was not usable at configure time, or BAKER_FUZZ=OFF"
  exit 77
fi
run=$work/$target
rm -rf "$run" && mkdir -p "$run/corpus" "$run/crashes"
cp "$testdir/fuzz/corpus/$target"/* "$run/corpus/"
"$bindir/$target" -seed=1 -runs=1500 -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
  -print_final_stats=1 -artifact_prefix="$run/crashes/" "$run/corpus" >"$run/log" 2>&1
rc=$?
# Only the fuzzer's own exit counts. fuzz_vdb's reads run in forked children
# (formats/isolate.cpp): a child that OpenVDB crashes prints its sanitizer
# report into this log (and no crash file, fuzz_children_die_plainly), and
# the parent takes it as a corrupt file, which is the behaviour under test.
tail -n 12 "$run/log"
if [ $rc -ne 0 ]; then
  echo "FAILED: $target found a crash (rc $rc); full log $run/log, input in $run/crashes/"
  grep -m 40 -E '^(==|SUMMARY|    #[0-9]+ )' "$run/log"
  exit $rc
fi
# with the fuzzer's exit 0, a crash file can only be a reader child's
left=$(find "$run/crashes" -type f ! -name 'oom-*' | head -5)
if [ -n "$left" ]; then
  echo "FAILED: a reader child left crash files, which are not findings: $left"
  exit 1
fi
children=$(grep -c '^==[0-9]*==ERROR' "$run/log")
echo "ok: no finding; $children sanitizer report(s) from reader children, no crash file from them"
exit 0
