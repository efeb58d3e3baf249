// Internal: from a polygon soup to validated, consistently oriented triangles.
//
// Polygons are triangulated by ear clipping; faces are re-oriented when the file mixes
// orientations; every defect is a Mesh_error naming the input vertex or face. Needs no CGAL,
// so the fuzz targets (test/fuzz) run exactly this code on their bytes.
#ifndef LAPMESH_INTERNAL_IO_SOUP_H
#define LAPMESH_INTERNAL_IO_SOUP_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/io_parsers.h>
#include <lapmesh/internal/topology.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <queue>
#include <string>
#include <unordered_map>
#include <vector>

namespace lapmesh {
namespace io {
namespace internal {

/// Ear clipping of a simple polygon (possibly non-convex, roughly planar), projected on the
/// plane of its Newell normal. Appends triangles to `out`; false if no ear can be found.
///
/// The ring is a linked list and the scan goes on from the vertex after each clipped ear, so
/// a convex polygon is a single pass (the fan from its last vertex). An ear must hold no
/// reflex (or flat) vertex; those sit in a uniform grid, so an ear test looks at the few
/// reflex vertices near the ear instead of the whole ring.
inline bool triangulate_polygon(const std::vector<std::size_t>& poly,
                                const std::vector<std::array<double, 3>>& pts,
                                std::vector<std::array<std::size_t, 3>>& out)
{
  const std::size_t n = poly.size();
  if(n < 3) return false;
  // Positions relative to the first vertex, scaled to unit size: the Newell normal and the
  // 2D predicates then neither overflow nor underflow.
  const Eigen::Vector3d origin(pts[poly[0]].data());
  double extent = 0;
  for(std::size_t idx : poly)
    extent = std::max(extent, (Eigen::Vector3d(pts[idx].data()) - origin).cwiseAbs().maxCoeff());
  if(!(extent > 0) || !std::isfinite(extent)) return false;
  std::vector<Eigen::Vector3d> q(n);
  for(std::size_t a = 0; a < n; ++a) q[a] = (Eigen::Vector3d(pts[poly[a]].data()) - origin) / extent;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for(std::size_t a = 0; a < n; ++a) {
    const Eigen::Vector3d& p = q[a];
    const Eigen::Vector3d& r = q[(a + 1) % n];
    normal += Eigen::Vector3d((p[1] - r[1]) * (p[2] + r[2]), (p[2] - r[2]) * (p[0] + r[0]), (p[0] - r[0]) * (p[1] + r[1]));
  }
  if(!(normal.norm() > 0)) return false;
  normal.normalize();
  const Eigen::Vector3d u = normal.unitOrthogonal(), v = normal.cross(u);
  std::vector<Eigen::Vector2d> xy(n);
  for(std::size_t a = 0; a < n; ++a) xy[a] = Eigen::Vector2d(q[a].dot(u), q[a].dot(v));
  auto cross2 = [&xy](std::size_t a, std::size_t b, std::size_t c) {
    return (xy[b] - xy[a]).x() * (xy[c] - xy[a]).y() - (xy[b] - xy[a]).y() * (xy[c] - xy[a]).x();
  };

  std::vector<std::size_t> next(n), prev(n);
  for(std::size_t a = 0; a < n; ++a) {
    next[a] = (a + 1) % n;
    prev[a] = (a + n - 1) % n;
  }
  std::vector<char> reflex(n), in_grid(n, 0);
  for(std::size_t a = 0; a < n; ++a) reflex[a] = cross2(prev[a], a, next[a]) <= 0;

  // The grid of reflex vertices over the bounding box of the polygon.
  Eigen::Vector2d lo = xy[0], hi = xy[0];
  for(const auto& p : xy) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const std::size_t num_reflex = std::size_t(std::count(reflex.begin(), reflex.end(), char(1)));
  const std::size_t side = std::max<std::size_t>(1, std::size_t(std::sqrt(double(num_reflex))));
  const Eigen::Vector2d cell_size = ((hi - lo) / double(side)).cwiseMax(Eigen::Vector2d::Constant(1e-300));
  auto cell_of = [&](const Eigen::Vector2d& p, int axis) {
    const double c = std::floor((p[axis] - lo[axis]) / cell_size[axis]);
    return std::size_t(std::clamp(c, 0.0, double(side - 1)));
  };
  std::vector<std::vector<std::size_t>> grid(side * side);
  auto add_to_grid = [&](std::size_t a) {
    grid[cell_of(xy[a], 1) * side + cell_of(xy[a], 0)].push_back(a);
    in_grid[a] = 1;
  };
  for(std::size_t a = 0; a < n; ++a)
    if(reflex[a]) add_to_grid(a);

  std::size_t live_reflex = num_reflex;  // reflex vertices still in the ring
  auto is_ear = [&](std::size_t i) {
    const std::size_t i0 = prev[i], i2 = next[i];
    if(reflex[i]) return false;
    if(live_reflex == 0) return true;  // a convex ring: every corner is an ear
    const Eigen::Vector2d bl = xy[i0].cwiseMin(xy[i]).cwiseMin(xy[i2]), bh = xy[i0].cwiseMax(xy[i]).cwiseMax(xy[i2]);
    const std::size_t x0 = cell_of(bl, 0), x1 = cell_of(bh, 0), y0 = cell_of(bl, 1), y1 = cell_of(bh, 1);
    for(std::size_t y = y0; y <= y1; ++y)
      for(std::size_t x = x0; x <= x1; ++x)
        for(std::size_t k : grid[y * side + x]) {
          if(!reflex[k] || k == i0 || k == i || k == i2 || next[k] == k) continue;  // clipped or now convex
          if(xy[k].x() < bl.x() || xy[k].x() > bh.x() || xy[k].y() < bl.y() || xy[k].y() > bh.y()) continue;
          if(cross2(i0, i, k) >= 0 && cross2(i, i2, k) >= 0 && cross2(i2, i0, k) >= 0) return false;
        }
    return true;
  };
  auto update = [&](std::size_t a) {
    const bool was = reflex[a];
    reflex[a] = cross2(prev[a], a, next[a]) <= 0;
    live_reflex = live_reflex - std::size_t(was) + std::size_t(reflex[a]);
    if(reflex[a] && !in_grid[a]) add_to_grid(a);  // only in a self-intersecting polygon
  };

  std::size_t remaining = n, i = 0, failures = 0;
  while(remaining > 3) {
    if(is_ear(i)) {
      const std::size_t i0 = prev[i], i2 = next[i];
      out.push_back({poly[i0], poly[i], poly[i2]});
      next[i0] = i2;
      prev[i2] = i0;
      next[i] = prev[i] = i;  // marks i as clipped
      --remaining;
      update(i0);
      update(i2);
      i = i2;
      failures = 0;
    } else {
      i = next[i];
      if(++failures > remaining) return false;
    }
  }
  // The last triangle in ring order from its first input vertex.
  std::array<std::size_t, 3> last = {prev[i], i, next[i]};
  std::rotate(last.begin(), std::min_element(last.begin(), last.end()), last.end());
  out.push_back({poly[last[0]], poly[last[1]], poly[last[2]]});
  return true;
}

/// Flips faces so that neighbours agree in orientation (breadth-first over each connected
/// component; the first face of a component keeps its orientation), through manifold edges
/// only. Returns the number of flipped faces; counts the non-manifold edges and notes a
/// surface that no orientation makes consistent.
inline std::size_t orient_consistently(std::vector<std::array<std::size_t, 3>>& tris, Soup_report& report)
{
  const std::size_t m = tris.size();
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> edge_faces;
  edge_faces.reserve(3 * m);
  auto key = [](std::size_t a, std::size_t b) { return std::uint64_t(std::min(a, b)) << 32 | std::uint64_t(std::max(a, b)); };
  for(std::size_t f = 0; f < m; ++f)
    for(int a = 0; a < 3; ++a) edge_faces[key(tris[f][a], tris[f][(a + 1) % 3])].push_back(f);
  for(const auto& entry : edge_faces) report.non_manifold_edges += entry.second.size() > 2;
  auto has_directed = [](const std::array<std::size_t, 3>& t, std::size_t a, std::size_t b) {
    return (t[0] == a && t[1] == b) || (t[1] == a && t[2] == b) || (t[2] == a && t[0] == b);
  };
  std::vector<char> state(m, 0);  // 0 unvisited, 1 visited
  std::size_t flipped = 0;
  for(std::size_t seed = 0; seed < m; ++seed) {
    if(state[seed]) continue;
    state[seed] = 1;
    std::queue<std::size_t> queue;
    queue.push(seed);
    while(!queue.empty()) {
      const std::size_t f = queue.front();
      queue.pop();
      for(int a = 0; a < 3; ++a) {
        const std::size_t p = tris[f][a], q = tris[f][(a + 1) % 3];
        const auto& faces = edge_faces[key(p, q)];
        if(faces.size() != 2) continue;  // a boundary or a non-manifold edge
        const std::size_t g = faces[0] == f ? faces[1] : faces[0];
        const bool agrees = has_directed(tris[g], q, p);
        if(state[g]) {
          if(!agrees) report.non_orientable = true;
          continue;
        }
        if(!agrees) {
          std::swap(tris[g][1], tris[g][2]);
          ++flipped;
        }
        state[g] = 1;
        queue.push(g);
      }
    }
  }
  return flipped;
}

/// True when the polygon names some vertex more than once (a triangle is checked without a copy).
inline bool uses_a_vertex_twice(const std::vector<std::size_t>& poly)
{
  if(poly.size() == 3) return poly[0] == poly[1] || poly[1] == poly[2] || poly[0] == poly[2];
  std::vector<std::size_t> sorted = poly;
  std::sort(sorted.begin(), sorted.end());
  return std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end();
}

} // namespace internal

/// Validates a soup and turns it into triangles over the same vertices, oriented
/// consistently where the surface allows it. Throws Mesh_error naming the vertex or face
/// (input face index) for: a non-finite coordinate, a mesh with no face, a face with fewer
/// than 3 vertices or a vertex index out of range, a polygon that cannot be triangulated, a
/// face with coordinates out of the representable range (edges longer than 1e145 or all
/// shorter than 1e-145). What real meshes have and lapmesh processes is counted in the
/// report instead: faces that use a vertex twice (left out; an error when no face is
/// left), zero-area faces, vertices in no face, non-manifold edges, a non-orientable surface.
inline std::vector<std::array<std::size_t, 3>> soup_to_triangles(const Polygon_soup& soup, Soup_report* report = nullptr)
{
  using lapmesh::internal::Face_defect;
  const std::size_t n = soup.points.size();
  for(std::size_t i = 0; i < n; ++i)
    for(double c : soup.points[i])
      if(!std::isfinite(c))
        throw Mesh_error("vertex " + std::to_string(i) + " has a non-finite coordinate", Mesh_error::Element::vertex,
                         std::int64_t(i));
  if(soup.polygons.empty()) throw Mesh_error("the mesh has no faces");
  constexpr std::size_t max_index = 0x7fffffff;  // lapmesh::internal::Index is an int
  if(n > max_index || soup.polygons.size() > max_index / 3)
    throw Mesh_error("the mesh has " + std::to_string(n) + " vertices and " + std::to_string(soup.polygons.size()) +
                     " faces, beyond lapmesh's limit of 2^31 - 1 vertices and 715827882 faces");

  std::vector<std::array<std::size_t, 3>> tris;
  tris.reserve(soup.polygons.size());
  Soup_report rep;
  auto squared = [](const std::array<double, 3>& a, const std::array<double, 3>& b) {
    return (Eigen::Vector3d(a.data()) - Eigen::Vector3d(b.data())).squaredNorm();
  };
  for(std::size_t f = 0; f < soup.polygons.size(); ++f) {
    const auto& poly = soup.polygons[f];
    auto fail = [f](const std::string& what) {
      throw Mesh_error("face " + std::to_string(f) + " " + what, Mesh_error::Element::face, std::int64_t(f));
    };
    if(poly.size() < 3) fail("has fewer than 3 vertices");
    for(std::size_t idx : poly)
      if(idx >= n) fail("has vertex index " + std::to_string(idx) + " out of range [0, " + std::to_string(n) + ")");
    if(internal::uses_a_vertex_twice(poly)) {
      ++rep.dropped_faces;
      continue;
    }
    const std::size_t before = tris.size();
    if(poly.size() == 3) {
      tris.push_back({poly[0], poly[1], poly[2]});
    } else {
      ++rep.triangulated_polygons;
      for(std::size_t a = 0; a < poly.size(); ++a)
        if(squared(soup.points[poly[a]], soup.points[poly[(a + 1) % poly.size()]]) > lapmesh::internal::max_squared_edge)
          throw Mesh_error(lapmesh::internal::out_of_range_message(std::int64_t(f), Face_defect::too_large),
                           Mesh_error::Element::face, std::int64_t(f));
      if(!internal::triangulate_polygon(poly, soup.points, tris))
        fail("is a polygon with " + std::to_string(poly.size()) + " vertices that cannot be triangulated");
    }
    for(std::size_t k = before; k < tris.size(); ++k) {
      const auto& t = tris[k];
      const Face_defect d =
        lapmesh::internal::face_defect(soup.points[t[0]].data(), soup.points[t[1]].data(), soup.points[t[2]].data());
      if(d == Face_defect::zero_area)
        ++rep.zero_area_faces;
      else if(d != Face_defect::none)
        throw Mesh_error(lapmesh::internal::out_of_range_message(std::int64_t(f), d), Mesh_error::Element::face,
                         std::int64_t(f));
    }
  }
  if(tris.empty())
    throw Mesh_error("the mesh has no faces (its " + std::to_string(rep.dropped_faces) +
                     " face(s) each use a vertex twice)");
  // Vertices in no face are counted; the topology check below numbers the others densely.
  std::vector<lapmesh::internal::Index> dense(n, -1);
  for(const auto& t : tris)
    for(std::size_t v : t) dense[v] = 0;
  lapmesh::internal::Index used = 0;
  for(std::size_t i = 0; i < n; ++i)
    if(dense[i] == 0) dense[i] = used++;
  rep.isolated_vertices = n - std::size_t(used);

  // Fast path: lapmesh's corner topology finds consistently oriented manifold edges (its
  // `manifold` is the full topology's, without building the sparsity pattern).
  lapmesh::internal::Working_array<lapmesh::internal::Index> flat;
  flat.reserve(3 * tris.size());
  for(const auto& t : tris)
    for(std::size_t v : t) flat.push_back(dense[v]);
  if(!lapmesh::internal::build_corner_topology(used, std::move(flat)).manifold)
    rep.flipped_faces = internal::orient_consistently(tris, rep);
  if(report) *report = rep;
  return tris;
}

} // namespace io
} // namespace lapmesh

#endif
