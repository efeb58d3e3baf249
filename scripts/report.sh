#!/usr/bin/env bash
# The reproducible report: regenerates every figure and table of doc/report.md with lapmesh's
# own commands, from CGAL's data set (cow.off, bunny00.off), a generated bumpy sphere, and any
# mesh named on the command line.
#
#   scripts/report.sh [--build DIR] [MESH ...]        (or: cmake --build DIR --target report)
#
# Needs, in the build directory DIR (default: build, or $BUILD_DIR): src/lapmesh with the viewer
# and its page, examples/reconstruction_error, the viewer's node_modules (playwright-core) and
# CGAL's meshes in cgal-data/data/meshes; node and Debian's chromium on the PATH. Writes
# doc/report.md, doc/images/report/*.png|svg; intermediate files go to DIR/report/.
# Any missing piece or failed step stops it with one line on stderr and a non-zero status.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${BUILD_DIR:-$ROOT/build}"
USER_MESHES=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build) BUILD="$2"; shift 2 ;;
    --build=*) BUILD="${1#--build=}"; shift ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) USER_MESHES+=("$(realpath "$1")"); shift ;;
  esac
done
BUILD="$(realpath "$BUILD")"
die() { echo "report.sh: $*" >&2; exit 1; }
trap 'echo "report.sh: failed (status $?) at line $LINENO: $BASH_COMMAND" >&2' ERR

CLI="$BUILD/src/lapmesh"
RECON="$BUILD/examples/reconstruction_error"
NODE_MODULES="$BUILD/src/viewer/web/node_modules"
MESHES_DIR="$BUILD/cgal-data/data/meshes"
CHROMIUM="${LAPMESH_CHROMIUM:-/usr/bin/chromium}"
[ -x "$CLI" ] || die "$CLI not found: cmake --build $BUILD --target lapmesh_cli"
"$CLI" view --help >/dev/null 2>&1 || die "$CLI has no 'view' subcommand (install libcpp-httplib-dev nlohmann-json3-dev and rebuild)"
[ -x "$RECON" ] || die "$RECON not found: cmake --build $BUILD --target reconstruction_error"
[ -d "$NODE_MODULES/playwright-core" ] || die "$NODE_MODULES/playwright-core not found: build the target lapmesh_cli (it runs npm for the viewer page)"
[ -f "$BUILD/share/lapmesh/viewer/index.html" ] || die "the viewer page is not built ($BUILD/share/lapmesh/viewer/index.html)"
command -v node >/dev/null || die "node not found (apt-get install nodejs)"
[ -x "$CHROMIUM" ] || die "$CHROMIUM not found (apt-get install chromium)"
for m in cow.off bunny00.off; do
  [ -f "$MESHES_DIR/$m" ] || die "$MESHES_DIR/$m not found: install libcgal-demo and re-run cmake"
done
for m in ${USER_MESHES[@]+"${USER_MESHES[@]}"}; do [ -f "$m" ] || die "$m: no such file"; done

START=$(date +%s)
WORK="$BUILD/report"
IMAGES="$ROOT/doc/images/report"
rm -rf "$WORK"; mkdir -p "$WORK" "$IMAGES"
rm -f "$IMAGES"/*.png "$IMAGES"/*.svg
STUDY=0
STUDY_OPTIONS="--levels 0.02,0.05,0.1,0.3 --lambdas 0.03,0.1,0.3,1 --iterations 10 --hausdorff-spacing 2 --seed 1"
STUDY_MAX_VERTICES="${STUDY_MAX_VERTICES:-15000}"
case "$("$CLI" --help)" in *denoise-study*) STUDY=1 ;; esac

# 1. the bumpy sphere: the viewer's built-in mesh (lapmesh::bumpy_sphere(5)), downloaded as OFF
cat > "$WORK/download.json" <<EOF
{"cli": "$CLI", "node_modules": "$NODE_MODULES", "chromium": "$CHROMIUM", "meshes": [],
 "download": [{"mesh": "bumpy-sphere", "to": "$WORK/bumpy.off"}]}
EOF
node "$ROOT/doc/report/render.cjs" "$WORK/download.json"
MESHES=("$WORK/bumpy.off" "$MESHES_DIR/cow.off" "$MESHES_DIR/bunny00.off" ${USER_MESHES[@]+"${USER_MESHES[@]}"})
: > "$WORK/meshes.txt"
for m in "${MESHES[@]}"; do echo "$m" >> "$WORK/meshes.txt"; done

# 2. tables measured by the command-line tool and the example program
echo "mesh,vertices,laplacian,stability_bound,mean_edge2" > "$WORK/bounds.csv"
for m in "${MESHES[@]}"; do
  name="$(basename "${m%.*}")"
  echo "== $name: stability bounds, reconstruction error"
  e2="$("$CLI" smooth "$m" -o "$WORK/tmp.off" --scheme implicit --lambda auto --iterations 1 | sed -n 's/.*lambda \([^,]*\),.*/\1/p')"
  for lap in uniform cotangent; do
    line="$("$CLI" smooth "$m" -o "$WORK/tmp.off" --scheme explicit --lambda auto --iterations 1 --laplacian "$lap")"
    bound="$(echo "$line" | sed -n 's/.*stability bound \([^;]*\);.*/\1/p')"
    nv="$(echo "$line" | sed -n 's/^[^:]*: \([0-9]*\) vertices.*/\1/p')"
    [ -n "$bound" ] && [ -n "$e2" ] || die "$name: could not read the stability bound from: $line"
    echo "$name,$nv,$lap,$bound,$e2" >> "$WORK/bounds.csv"
  done
  "$RECON" "$m" > "$WORK/recon_$name.csv"
  # The study smooths 4 levels x 2 schemes x 2 Laplacians x 4 time steps x 10 iterations and
  # measures a Hausdorff distance after each step: about a minute for 10k vertices on 2 busy
  # cores, so larger meshes are left out (run it on them by hand with the same options).
  if [ $STUDY = 1 ] && [ "$nv" -le "$STUDY_MAX_VERTICES" ]; then
    echo "== $name: denoise-study"
    "$CLI" denoise-study "$m" -o "$WORK/study_$name.csv" --plot "$IMAGES/denoise_study_$name.svg" $STUDY_OPTIONS > "$WORK/study_$name.txt"
  fi
done
rm -f "$WORK/tmp.off"

# 3. figures through the viewer, then the report
node "$ROOT/doc/report/report.cjs" jobs "$WORK" "$CLI" "$NODE_MODULES" "$CHROMIUM" "$IMAGES" > "$WORK/jobs.json"
echo "== figures"
node "$ROOT/doc/report/render.cjs" "$WORK/jobs.json"
END=$(date +%s)
node "$ROOT/doc/report/report.cjs" report "$WORK" "$(( END - START ))" "$STUDY" "$STUDY_OPTIONS" "$STUDY_MAX_VERTICES" > "$WORK/report.md"
mv "$WORK/report.md" "$ROOT/doc/report.md"
echo "report.sh: wrote doc/report.md and $(ls "$IMAGES" | wc -l) images in doc/images/report/ in $(( END - START )) s"
