#!/usr/bin/env bash
# lapmesh developer entry point (Debian 12, as root or with sudo).
#   scripts/run.sh demo    install dependencies, build, compute the curvature of CGAL's cow.off
#   scripts/run.sh test    install dependencies, build, run the whole test suite (ctest)
#   scripts/run.sh setup   install dependencies only (idempotent)
#   scripts/run.sh build   install dependencies and build
# Environment: BUILD_DIR (default build), JOBS (default nproc).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
JOBS="${JOBS:-$(nproc)}"

PACKAGES=(build-essential cmake ccache pkg-config doxygen
          libcgal-dev libcgal-demo libgmp-dev libmpfr-dev libboost-dev
          libeigen3-dev libspectra-dev libsuitesparse-dev libopenblas0 libtbb-dev
          libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev
          libcpp-httplib-dev nlohmann-json3-dev chromium)

setup() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
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

build() {
  setup
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$BUILD_DIR" -j "$JOBS"
}

case "${1:-demo}" in
  setup) setup ;;
  build) build ;;
  demo)
    build
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
  *) echo "usage: scripts/run.sh demo|test|setup|build" >&2; exit 2 ;;
esac
