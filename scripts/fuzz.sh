#!/usr/bin/env bash
# Fuzzes lapmesh's mesh readers with libFuzzer: scripts/fuzz.sh [SECONDS] (default 60 per
# format). Builds test/fuzz with clang (ASan + UBSan + libFuzzer) in build-fuzz/, then runs
# fuzz_off, fuzz_obj, fuzz_ply and fuzz_stl for SECONDS each from the committed seeds
# (test/fuzz/corpus/FORMAT) and the regressions (test/fuzz/regressions/FORMAT), with a memory
# limit and a per-input time limit. Exits non-zero on any crash, leak, timeout or
# out-of-memory; the input that caused it is in build-fuzz/artifacts/FORMAT/ and belongs in
# test/fuzz/regressions/FORMAT/ once fixed (io_test then replays it in the ordinary suite).
# Environment: LAPMESH_FUZZ_FORMATS (default "off obj ply stl"), LAPMESH_FUZZ_JOBS (build
# jobs, default 2), CXX (default clang++).
set -euo pipefail
seconds="${1:-60}"
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build-fuzz"
mkdir -p "$build"
formats="${LAPMESH_FUZZ_FORMATS:-off obj ply stl}"

cmake -S "$root" -B "$build" -DCMAKE_CXX_COMPILER="${CXX:-clang++}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLAPMESH_BUILD_FUZZERS=ON -DLAPMESH_BUILD_TOOLS=OFF -DLAPMESH_BUILD_EXAMPLES=OFF \
  -DLAPMESH_BUILD_TESTS=OFF -DLAPMESH_BUILD_BENCHMARKS=OFF >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log"; exit 1; }
targets=()
for f in $formats; do targets+=(--target "fuzz_$f"); done
cmake --build "$build" -j "${LAPMESH_FUZZ_JOBS:-2}" "${targets[@]}"

status=0
for f in $formats; do
  work="$build/corpus/$f"         # grows while fuzzing; the committed seeds stay as they are
  artifacts="$build/artifacts/$f/"
  mkdir -p "$work" "$artifacts"
  seeds=("$root/test/fuzz/corpus/$f")
  [ -d "$root/test/fuzz/regressions/$f" ] && seeds+=("$root/test/fuzz/regressions/$f")
  echo "== fuzz_$f: ${seconds} s"
  # -rss_limit_mb also caps a single allocation (malloc_limit_mb defaults to it): a reader
  # that trusts a declared count fails here. -timeout: seconds per input.
  if ! "$build/test/fuzz/fuzz_$f" "$work" "${seeds[@]}" -max_total_time="$seconds" -max_len=65536 \
       -rss_limit_mb=2048 -timeout=10 -artifact_prefix="$artifacts" -print_final_stats=1 \
       >"$build/fuzz_$f.log" 2>&1; then
    tail -n 60 "$build/fuzz_$f.log"
    echo "fuzz_$f FAILED: reproducer(s) in $artifacts" >&2
    status=1
  else
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$build/fuzz_$f.log" | tr '\n' ' '
    echo
  fi
done
exit $status
