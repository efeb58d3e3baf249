#!/usr/bin/env bash
# The figures of doc/intrinsic.md: CGAL's bull.off (many obtuse triangles) with the cotangent
# and the intrinsic Delaunay Laplacian, curvature and explicit smoothing, rendered by lapmesh's
# own viewer in headless Chromium (doc/report/render.cjs).
#   scripts/intrinsic_figures.sh [BUILD_DIR]   (default: build)
# Needs what scripts/report.sh needs: BUILD/src/lapmesh with the viewer, its node_modules,
# CGAL's meshes in BUILD/cgal-data, node and chromium.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$(realpath "${1:-$ROOT/build}")"
MESH="$BUILD/cgal-data/data/meshes/bull.off"
OUT="$ROOT/doc/images/intrinsic"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
[ -f "$MESH" ] || { echo "intrinsic_figures.sh: $MESH: no such file" >&2; exit 1; }
mkdir -p "$OUT"
view='colormap=coolwarm&range=percentile&clip=1'
smooth='op=smooth&scheme=explicit&lambda=0.9&lambda_unit=bound&iterations=30&colormap=viridis'
cat > "$WORK/jobs.json" <<JSON
{"cli": "$BUILD/src/lapmesh", "node_modules": "$BUILD/src/viewer/web/node_modules", "chromium": "$(command -v chromium)",
 "meshes": [{"key": "bull", "file": "$MESH"}], "out_dir": "$OUT", "results": "$WORK/results.json",
 "width": 480, "height": 360,
 "figures": [
  {"name": "bull_mean_cotangent", "mesh": "bull", "query": "op=curvature&laplacian=cotangent&area=mixed&quantity=mean&$view"},
  {"name": "bull_mean_intrinsic", "mesh": "bull", "query": "op=curvature&laplacian=intrinsic-delaunay&area=mixed&quantity=mean&RANGE_OF(bull_mean_cotangent)&colormap=coolwarm"},
  {"name": "bull_explicit_cotangent", "mesh": "bull", "query": "$smooth&laplacian=cotangent"},
  {"name": "bull_explicit_intrinsic", "mesh": "bull", "query": "$smooth&laplacian=intrinsic-delaunay"}
 ]}
JSON
node "$ROOT/doc/report/render.cjs" "$WORK/jobs.json"
cp "$WORK/results.json" "$OUT/results.json"
echo "intrinsic_figures.sh: wrote $(ls "$OUT"/*.png | wc -l) figures in $OUT"
