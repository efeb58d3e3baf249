#!/usr/bin/env bash
# The figures of doc/intrinsic.md: CGAL's ChineseDragon-10kv.off (a fifth of its triangles have an
# angle above 120 degrees) with the cotangent and the intrinsic Delaunay Laplacian: mean curvature,
# and explicit smoothing with one absolute step between the two operators' stability bounds.
# Rendered by lapmesh's own viewer in headless Chromium (doc/report/render.cjs).
#   scripts/intrinsic_figures.sh [BUILD_DIR]   (default: build)
# Needs what scripts/report.sh needs: BUILD/src/lapmesh with the viewer, its node_modules,
# CGAL's meshes in BUILD/cgal-data, node and chromium.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$(realpath "${1:-$ROOT/build}")"
MESH="$BUILD/cgal-data/data/meshes/ChineseDragon-10kv.off"
OUT="$ROOT/doc/images/intrinsic"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
[ -f "$MESH" ] || { echo "intrinsic_figures.sh: $MESH: no such file" >&2; exit 1; }
mkdir -p "$OUT"
camera='ui=0&azimuth=60&elevation=10&zoom=1.3'
view="colormap=coolwarm&range=percentile&clip=1&$camera"
smooth="op=smooth&scheme=explicit&lambda=0.02&lambda_unit=absolute&iterations=20&colormap=viridis&$camera"
cat > "$WORK/jobs.json" <<JSON
{"cli": "$BUILD/src/lapmesh", "node_modules": "$BUILD/src/viewer/web/node_modules", "chromium": "$(command -v chromium)",
 "meshes": [{"key": "dragon", "file": "$MESH"}], "out_dir": "$OUT", "results": "$WORK/results.json",
 "width": 480, "height": 360,
 "figures": [
  {"name": "dragon_mean_cotangent", "mesh": "dragon", "query": "op=curvature&laplacian=cotangent&area=mixed&quantity=mean&$view"},
  {"name": "dragon_mean_intrinsic", "mesh": "dragon", "query": "op=curvature&laplacian=intrinsic-delaunay&area=mixed&quantity=mean&RANGE_OF(dragon_mean_cotangent)&colormap=coolwarm&$camera"},
  {"name": "dragon_explicit_cotangent", "mesh": "dragon", "query": "$smooth&laplacian=cotangent"},
  {"name": "dragon_explicit_intrinsic", "mesh": "dragon", "query": "$smooth&laplacian=intrinsic-delaunay"}
 ]}
JSON
node "$ROOT/doc/report/render.cjs" "$WORK/jobs.json"
cp "$WORK/results.json" "$OUT/results.json"
echo "intrinsic_figures.sh: wrote $(ls "$OUT"/*.png | wc -l) figures in $OUT"
