#!/usr/bin/env bash
# scripts/report.sh keys every mesh by its path: user meshes named like the built-in ones
# (cow.off, bumpy-box.off) get their own keys, rows and files, and the same path twice is one
# mesh. Runs the script's mesh list and its measured tables (no figures, no study, k = 5 and 10).
# Usage: mesh_keys_test.sh BUILD_DIR SCRATCH_DIR
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
fail() { echo "FAIL: $*" >&2; exit 1; }
[ $# = 2 ] || fail "usage: mesh_keys_test.sh BUILD_DIR SCRATCH_DIR"
BUILD="$(realpath "$1")"; TMP="$2"
rm -rf "$TMP"; mkdir -p "$TMP/a" "$TMP/b" "$TMP/data"; TMP="$(realpath "$TMP")"
"$BUILD/examples/make_shape" icosphere "$TMP/a/cow.off" 1           # 42 vertices
"$BUILD/examples/make_shape" bumpy-sphere "$TMP/b/cow.off" 2        # 162 vertices
"$BUILD/examples/make_shape" icosphere "$TMP/data/bumpy-box.off" 2  # 162 vertices
cd "$TMP"

list="$(bash "$ROOT/scripts/report.sh" --build "$BUILD" --work "$TMP/work" --list-meshes a/cow.off b/cow.off data/bumpy-box.off ./a/cow.off)"
echo "$list"
expected="bumpy-box generated $TMP/work/bumpy-box.off
cow cgal $BUILD/cgal-data/data/meshes/cow.off
bunny00 cgal $BUILD/cgal-data/data/meshes/bunny00.off
a-cow user $TMP/a/cow.off
b-cow user $TMP/b/cow.off
data-bumpy-box user $TMP/data/bumpy-box.off"
[ "$(echo "$list" | tr '\t' ' ')" = "$expected" ] || fail "mesh list differs from: $expected"

RECON_KS="5 10" bash "$ROOT/scripts/report.sh" --build "$BUILD" --work "$TMP/work" --tables-only --no-study a/cow.off b/cow.off data/bumpy-box.off
cat "$TMP/work/bounds.csv"
vertices() { awk -F, -v k="$1" '$1 == k && $3 == "cotangent" { print $2 }' "$TMP/work/bounds.csv"; }
[ "$(vertices cow)" = 2904 ] || fail "CGAL's cow: $(vertices cow) vertices"
[ "$(vertices a-cow)" = 42 ] || fail "a/cow.off: $(vertices a-cow) vertices"
[ "$(vertices b-cow)" = 162 ] || fail "b/cow.off: $(vertices b-cow) vertices"
[ "$(vertices data-bumpy-box)" = 162 ] || fail "data/bumpy-box.off: $(vertices data-bumpy-box) vertices"
[ "$(vertices bumpy-box)" -gt 1100 ] || fail "the generated bumpy box: $(vertices bumpy-box) vertices"
[ "$(cut -d, -f1,3 "$TMP/work/bounds.csv" | sort | uniq -d)" = "" ] || fail "duplicate rows in bounds.csv"
for k in bumpy-box cow bunny00 a-cow b-cow data-bumpy-box; do [ -s "$TMP/work/recon_$k.csv" ] || fail "no recon_$k.csv"; done
! cmp -s "$TMP/work/recon_cow.csv" "$TMP/work/recon_a-cow.csv" || fail "a/cow.off has CGAL's cow's reconstruction errors"
echo "PASS"
