#!/usr/bin/env bash
# lapmesh developer entry point (Debian 12, as root or with sudo).
#   scripts/run.sh demo    install dependencies, build, compute the curvature of CGAL's cow.off
#   scripts/run.sh test    install dependencies, build, run the whole test suite (ctest)
#   scripts/run.sh setup   install dependencies only (idempotent)
#   scripts/run.sh build   install dependencies and build
#   scripts/run.sh sanitize  AddressSanitizer + UndefinedBehaviorSanitizer build of the CLI and
#                          the unit tests that exercise readers, operators and the CLI, run with
#                          ctest; then each reader's fuzzer for FUZZ_SECONDS (default 60)
# Environment: BUILD_DIR (default build), SANITIZE_DIR (default build-sanitize), JOBS (default nproc),
#              WARNINGS_AS_ERRORS=ON (compile the project's own code with -Werror; CI sets it).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# ccache hashes paths under the checkout relative to it: two clones share their compilations.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$ROOT}"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
# nproc counts OMP_NUM_THREADS as the processors it may use; a build should not.
JOBS="${JOBS:-$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)}"

PACKAGES=(build-essential cmake ccache pkg-config doxygen
          libcgal-dev libcgal-demo libgmp-dev libmpfr-dev libboost-dev
          libeigen3-dev libspectra-dev libsuitesparse-dev libopenblas0 libtbb-dev
          libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev
          libcpp-httplib-dev nlohmann-json3-dev chromium
          pybind11-dev python3-dev python3-numpy python3-scipy python3-pytest python3-dask python3-distributed)

# The fuzzers need clang's libFuzzer: installed by `sanitize` only, to keep `demo` quick.
FUZZ_PACKAGES=(clang libclang-rt-14-dev)

# setup [EXTRA_PACKAGE...]: installs what is missing of PACKAGES and the extra ones.
setup() {
  local missing=()
  for p in "${PACKAGES[@]}" "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  # The viewer page is built with npm (node >= 20): take Debian's only when there is none
  # (e.g. from nodesource), whose npm package would conflict with it.
  command -v npm >/dev/null 2>&1 || missing+=(nodejs npm)
  if [ ${#missing[@]} -gt 0 ]; then
    echo "lapmesh: installing ${missing[*]}" >&2
    local sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  fi
}

# build [TARGET...]: configure and build the given targets (all of them by default).
build() {
  setup
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release \
        -DLAPMESH_WARNINGS_AS_ERRORS="${WARNINGS_AS_ERRORS:-OFF}" >/dev/null
  if [ $# -gt 0 ]; then
    cmake --build "$BUILD_DIR" -j "$JOBS" --target "$@"
  else
    cmake --build "$BUILD_DIR" -j "$JOBS"
  fi
}

# The sanitizer build keeps to the translation units that read files and run the CLI: CGAL is
# heavy to compile, and ASan + UBSan builds of all of it would not fit CI's time.
SANITIZE_TARGETS=(lapmesh_cli io_test cli_test operators_test curvature_test)
sanitize() {
  setup "${FUZZ_PACKAGES[@]}"
  local dir="${SANITIZE_DIR:-$ROOT/build-sanitize}"
  cmake -S "$ROOT" -B "$dir" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -g1 -DNDEBUG" \
        -DLAPMESH_SANITIZE=ON -DLAPMESH_BUILD_EXAMPLES=OFF -DLAPMESH_BUILD_BENCHMARKS=OFF >/dev/null
  cmake --build "$dir" -j "$JOBS" --target "${SANITIZE_TARGETS[@]}"
  # Tests of executables left out of this build are registered as *_NOT_BUILT: skip them by name.
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1" UBSAN_OPTIONS="print_stacktrace=1" \
    ctest --test-dir "$dir" --output-on-failure -j "$JOBS" \
          -E 'NOT_BUILT|install_and_find_package|doc_builds|viewer_e2e'
  bash "$ROOT/scripts/fuzz.sh" "${FUZZ_SECONDS:-60}"
}

case "${1:-demo}" in
  setup) setup ;;
  build) build ;;
  demo)
    build lapmesh_cli  # only what the demo runs: the tests, examples and modules are left to `test`
    mkdir -p "$ROOT/out"
    mesh="$BUILD_DIR/cgal-data/data/meshes/cow.off"
    "$BUILD_DIR/src/lapmesh" curvature "$mesh" -o "$ROOT/out/cow_mean_curvature.ply" --area mixed --colormap coolwarm --clip 1
    "$BUILD_DIR/src/lapmesh" curvature "$mesh" -o "$ROOT/out/cow_curvature.csv" --area mixed -q
    echo "per-vertex curvatures: $ROOT/out/cow_curvature.csv; coloured mesh: $ROOT/out/cow_mean_curvature.ply"
    ;;
  test)
    build
    ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS"
    ;;
  sanitize) sanitize ;;
  *) echo "usage: scripts/run.sh demo|test|setup|build|sanitize" >&2; exit 2 ;;
esac
