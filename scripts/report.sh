#!/usr/bin/env bash
# The reproducible report: regenerates every figure and table of doc/report.md with lapmesh's
# own commands, from a generated bumpy box (lapmesh::bumpy_box(), written by the example
# program make_shape), CGAL's data set (cow.off, bunny00.off), and any mesh named on the
# command line.
#
#   scripts/report.sh [--build DIR] [--work DIR] [--list-meshes|--tables-only] [--no-study] [MESH ...]
#   (or: cmake --build DIR --target report)
#
# Every mesh is keyed by its path: a mesh named like a built-in one (a course's cow.off or
# bumpy.off) gets its own key (its folder's name in front: data-cow), its own rows and figures.
# --list-meshes prints "KEY<TAB>ORIGIN<TAB>PATH" per mesh and stops; --tables-only stops after
# the measured tables (WORK/bounds.csv, recon_KEY.csv, study_KEY.csv); --no-study skips
# `lapmesh denoise-study`; --work DIR puts the intermediate files in DIR (default BUILD/report).
# Environment: RECON_KS (the k of the reconstruction table, default "5 10 30 100 300"),
# STUDY_MAX_VERTICES (default 15000), BUILD_DIR, LAPMESH_CHROMIUM.
# Needs, in the build directory DIR (default: build, or $BUILD_DIR): src/lapmesh with the viewer
# and its page, examples/reconstruction_error and examples/make_shape, the viewer's node_modules
# (playwright-core) and CGAL's meshes in cgal-data/data/meshes; node and Debian's chromium on
# the PATH. Writes doc/report.md, doc/images/report/*.png|svg.
# Any missing piece or failed step stops it with one line on stderr and a non-zero status.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${BUILD_DIR:-$ROOT/build}"
WORK=""
MODE=report
STUDY_WANTED=1
USER_MESHES=()
die() { echo "report.sh: $*" >&2; exit 1; }
while [ $# -gt 0 ]; do
  case "$1" in
    --build) [ $# -ge 2 ] || die "--build needs a directory"; BUILD="$2"; shift 2 ;;
    --build=*) BUILD="${1#--build=}"; shift ;;
    --work) [ $# -ge 2 ] || die "--work needs a directory"; WORK="$2"; shift 2 ;;
    --work=*) WORK="${1#--work=}"; shift ;;
    --list-meshes) MODE=list; shift ;;
    --tables-only) MODE=tables; shift ;;
    --no-study) STUDY_WANTED=0; shift ;;
    -h|--help) sed -n '2,21p' "$0"; exit 0 ;;
    -*) die "unknown option $1 (see --help)" ;;
    *) [ -f "$1" ] || die "$1: no such file"; USER_MESHES+=("$(realpath "$1")"); shift ;;
  esac
done
[ -d "$BUILD" ] || die "$BUILD: no such build directory"
BUILD="$(realpath "$BUILD")"
WORK="${WORK:-$BUILD/report}"
trap 'echo "report.sh: failed (status $?) at line $LINENO: $BASH_COMMAND" >&2' ERR

CLI="$BUILD/src/lapmesh"
RECON="$BUILD/examples/reconstruction_error"
MAKE_SHAPE="$BUILD/examples/make_shape"
NODE_MODULES="$BUILD/src/viewer/web/node_modules"
MESHES_DIR="$BUILD/cgal-data/data/meshes"
CHROMIUM="${LAPMESH_CHROMIUM:-/usr/bin/chromium}"

# The meshes, each with a key that names its rows, CSV files and images. Keys come from the
# file's name; a second file of the same name (another path) takes its folder's name in front,
# then a number. The same path twice is one mesh.
KEYS=(); PATHS=(); ORIGINS=()
declare -A KEY_USED=() PATH_USED=()
sanitize() { local s="${1//[^A-Za-z0-9-]/-}"; echo "${s:-mesh}"; }  # no "_": it separates key and figure in image names
add_mesh() {  # PATH ORIGIN
  local path="$1" origin="$2" stem key base i
  [ -z "${PATH_USED[$path]+x}" ] || return 0
  stem="$(basename "$path")"; stem="$(sanitize "${stem%.*}")"
  key="$stem"
  [ -z "${KEY_USED[$key]+x}" ] || key="$(sanitize "$(basename "$(dirname "$path")")")-$stem"
  base="$key"; i=2
  while [ -n "${KEY_USED[$key]+x}" ]; do key="$base-$i"; i=$((i + 1)); done
  KEY_USED[$key]=1; PATH_USED[$path]=1
  KEYS+=("$key"); PATHS+=("$path"); ORIGINS+=("$origin")
}
add_mesh "$WORK/bumpy-box.off" generated
add_mesh "$MESHES_DIR/cow.off" cgal
add_mesh "$MESHES_DIR/bunny00.off" cgal
for m in ${USER_MESHES[@]+"${USER_MESHES[@]}"}; do add_mesh "$m" user; done
if [ $MODE = list ]; then
  for i in "${!KEYS[@]}"; do printf '%s\t%s\t%s\n' "${KEYS[$i]}" "${ORIGINS[$i]}" "${PATHS[$i]}"; done
  exit 0
fi

[ -x "$CLI" ] || die "$CLI not found: cmake --build $BUILD --target lapmesh_cli"
[ -x "$RECON" ] || die "$RECON not found: cmake --build $BUILD --target reconstruction_error"
[ -x "$MAKE_SHAPE" ] || die "$MAKE_SHAPE not found: cmake --build $BUILD --target make_shape"
for m in cow.off bunny00.off; do
  [ -f "$MESHES_DIR/$m" ] || die "$MESHES_DIR/$m not found: install libcgal-demo and re-run cmake"
done
if [ $MODE = report ]; then
  "$CLI" view --help >/dev/null 2>&1 || die "$CLI has no 'view' subcommand (install libcpp-httplib-dev nlohmann-json3-dev and rebuild)"
  [ -d "$NODE_MODULES/playwright-core" ] || die "$NODE_MODULES/playwright-core not found: build the target lapmesh_cli (it runs npm for the viewer page)"
  [ -f "$BUILD/share/lapmesh/viewer/index.html" ] || die "the viewer page is not built ($BUILD/share/lapmesh/viewer/index.html)"
  command -v node >/dev/null || die "node not found (apt-get install nodejs)"
  [ -x "$CHROMIUM" ] || die "$CHROMIUM not found (apt-get install chromium)"
fi

START=$(date +%s)
IMAGES="$ROOT/doc/images/report"
# WORK is emptied: refuse a non-empty folder that an earlier run did not make
if [ -d "$WORK" ] && [ -n "$(ls -A "$WORK")" ] && [ ! -f "$WORK/.lapmesh-report" ]; then
  die "$WORK is not empty and was not made by report.sh: choose another --work"
fi
rm -rf "$WORK"; mkdir -p "$WORK"; : > "$WORK/.lapmesh-report"
STUDY=0
STUDY_OPTIONS="--levels 0.02,0.05,0.1,0.3 --lambdas 0.03,0.1,0.3,1 --iterations 10 --hausdorff-spacing 2 --seed 1"
STUDY_MAX_VERTICES="${STUDY_MAX_VERTICES:-15000}"
RECON_KS="${RECON_KS:-5 10 30 100 300}"   # fewer for a quick --tables-only run (the test)
if [ $STUDY_WANTED = 1 ]; then case "$("$CLI" --help)" in *denoise-study*) STUDY=1 ;; esac; fi
if [ $MODE = report ]; then
  mkdir -p "$IMAGES"
  rm -f "$IMAGES"/*.png "$IMAGES"/*.svg
fi

# 1. the bumpy box: lapmesh::bumpy_box(seed 1), generated by lapmesh's own code
"$MAKE_SHAPE" bumpy-box "$WORK/bumpy-box.off" 1
: > "$WORK/meshes.tsv"
for i in "${!KEYS[@]}"; do printf '%s\t%s\t%s\n' "${KEYS[$i]}" "${ORIGINS[$i]}" "${PATHS[$i]}" >> "$WORK/meshes.tsv"; done

# 2. tables measured by the command-line tool and the example program, one row set per key
echo "mesh,vertices,laplacian,stability_bound,mean_edge2" > "$WORK/bounds.csv"
for i in "${!KEYS[@]}"; do
  key="${KEYS[$i]}"; m="${PATHS[$i]}"
  echo "== $key ($m): stability bounds, reconstruction error"
  e2="$("$CLI" smooth "$m" -o "$WORK/tmp.off" --scheme implicit --lambda auto --iterations 1 | sed -n 's/.*lambda \([^,]*\),.*/\1/p')"
  for lap in uniform cotangent; do
    line="$("$CLI" smooth "$m" -o "$WORK/tmp.off" --scheme explicit --lambda auto --iterations 1 --laplacian "$lap")"
    bound="$(echo "$line" | sed -n 's/.*stability bound \([^;]*\);.*/\1/p')"
    nv="$(echo "$line" | sed -n 's/^.*: \([0-9]*\) vertices (.*/\1/p')"
    [ -n "$bound" ] && [ -n "$e2" ] && [ -n "$nv" ] || die "$key: could not read the stability bound from: $line"
    echo "$key,$nv,$lap,$bound,$e2" >> "$WORK/bounds.csv"
  done
  # shellcheck disable=SC2086  # RECON_KS is a list of numbers
  "$RECON" "$m" $RECON_KS > "$WORK/recon_$key.csv"
  # The study smooths 4 levels x 2 schemes x 2 Laplacians x 4 time steps x 10 iterations and
  # measures a Hausdorff distance after each step: about a minute for 10k vertices on 2 busy
  # cores, so larger meshes are left out (run it on them by hand with the same options).
  if [ $STUDY = 1 ] && [ "$nv" -le "$STUDY_MAX_VERTICES" ]; then
    echo "== $key: denoise-study"
    "$CLI" denoise-study "$m" -o "$WORK/study_$key.csv" --plot "$WORK/denoise_study_$key.svg" $STUDY_OPTIONS > "$WORK/study_$key.txt"
    [ $MODE = tables ] || cp "$WORK/denoise_study_$key.svg" "$IMAGES/"
  fi
done
rm -f "$WORK/tmp.off"
if [ $MODE = tables ]; then
  echo "report.sh: wrote the tables of ${#KEYS[@]} meshes in $WORK in $(( $(date +%s) - START )) s"
  exit 0
fi

# 3. figures through the viewer, then the report
node "$ROOT/doc/report/report.cjs" jobs "$WORK" "$CLI" "$NODE_MODULES" "$CHROMIUM" "$IMAGES" > "$WORK/jobs.json"
echo "== figures"
node "$ROOT/doc/report/render.cjs" "$WORK/jobs.json"
END=$(date +%s)
node "$ROOT/doc/report/report.cjs" report "$WORK" "$(( END - START ))" "$STUDY" "$STUDY_OPTIONS" "$STUDY_MAX_VERTICES" > "$WORK/report.md"
mv "$WORK/report.md" "$ROOT/doc/report.md"
echo "report.sh: wrote doc/report.md and $(ls "$IMAGES" | wc -l) images in doc/images/report/ in $(( END - START )) s"
