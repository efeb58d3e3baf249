// Internal: the connectivity of a triangle mesh as flat arrays, built once per mesh.
//
// Why arrays and not halfedge circulation in the hot loops: every operator of lapmesh is a
// streaming pass over the faces (per-corner geometry) followed by a gather per vertex. The
// sparsity pattern of the Laplacians is known from the connectivity (a vertex's row is its
// one-ring plus itself), so it is built here once, already sorted and compressed, and each
// assembly only writes values into it: no triplets, no sort, no duplicate collapsing.
//
// Conventions. Face f has corners 3f, 3f+1, 3f+2 at the vertices triangles[3f + a], in the
// face's orientation. The edge opposite corner c = 3f+a runs from the vertex of corner
// next(c) to the vertex of corner prev(c); it is the halfedge of face f on that edge.
#ifndef LAPMESH_INTERNAL_TOPOLOGY_H
#define LAPMESH_INTERNAL_TOPOLOGY_H

#include <lapmesh/errors.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace lapmesh {
namespace internal {

/// Index type of vertices, corners and matrix slots; Eigen's default StorageIndex.
using Index = int;

inline Index next_corner(Index c) { return c % 3 == 2 ? c - 2 : c + 1; }
inline Index prev_corner(Index c) { return c % 3 == 0 ? c + 2 : c - 1; }

/// A face whose doubled area is at most this fraction of its longest squared edge has
/// numerically undefined angles (its smallest angle is below ~1e-12 rad): lapmesh reports
/// it instead of letting infinite cotangents turn into NaN.
constexpr double degenerate_face_tolerance = 1e-12;

/// The range of a face's longest squared edge in which its squared lengths, dot products,
/// areas and their sums over a vertex's faces are finite normal doubles with room to spare
/// (edge lengths between 1e-145 and 1e145). Outside it a face is refused as "out of the
/// representable range" rather than computed wrong (overflow) or called degenerate
/// (underflow).
constexpr double min_squared_edge = 1e-290;
constexpr double max_squared_edge = 1e290;

/// |c| for a cross product c of two edges, without the overflow or underflow of squaring
/// its components when they are beyond 1e154 or below 1e-154.
inline double cross_norm(double x, double y, double z)
{
  const double sq = x * x + y * y + z * z;
  if(sq >= 2.2250738585072014e-308 && sq <= 1.7976931348623157e308) return std::sqrt(sq);
  const double s = std::max(std::abs(x), std::max(std::abs(y), std::abs(z)));
  if(!(s > 0) || !std::isfinite(s)) return std::sqrt(sq);  // 0, or NaN/inf: nothing to rescue
  const double a = x / s, b = y / s, c = z / s;
  return s * std::sqrt(a * a + b * b + c * c);
}

/// What is wrong with a face.
enum class Face_defect { none, zero_area, too_large, too_small };

/// True when a face with this longest squared edge and doubled area is fine: the test of
/// the hot loops; face_defect() says what is wrong with one that is not.
inline bool face_in_range(double longest_squared_edge, double doubled_area)
{
  return longest_squared_edge <= max_squared_edge && longest_squared_edge >= min_squared_edge &&
         doubled_area > degenerate_face_tolerance * longest_squared_edge;
}

/// What is wrong with the triangle (p0, p1, p2), if anything. A face too large (an edge
/// above 1e145, or an overflowing coordinate difference) or too small (every edge below
/// about 1e-145, however well shaped) is out of the representable range; a face in range
/// whose angles are numerically undefined (also one with a NaN) has zero area.
inline Face_defect face_defect(const double* p0, const double* p1, const double* p2)
{
  double longest = 0, extent = 0, e[3][3];
  for(int c = 0; c < 3; ++c) {
    e[0][c] = p1[c] - p0[c];
    e[1][c] = p2[c] - p1[c];
    e[2][c] = p0[c] - p2[c];
  }
  for(const auto& v : e) {
    longest = std::max(longest, v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for(double x : v) extent = std::max(extent, std::abs(x));
  }
  if(longest > max_squared_edge) return Face_defect::too_large;  // also +inf
  if(extent > 0 && extent * extent < min_squared_edge) return Face_defect::too_small;
  const double cx = e[0][1] * -e[2][2] - e[0][2] * -e[2][1], cy = e[0][2] * -e[2][0] - e[0][0] * -e[2][2],
               cz = e[0][0] * -e[2][1] - e[0][1] * -e[2][0];
  if(!(cross_norm(cx, cy, cz) > degenerate_face_tolerance * longest)) return Face_defect::zero_area;  // NaN too
  return longest < min_squared_edge ? Face_defect::too_small : Face_defect::none;
}

/// The message of a face that is not zero-area but out of the representable range.
inline std::string out_of_range_message(std::int64_t f, Face_defect d)
{
  return "face " + std::to_string(f) + " has coordinates out of the representable range (" +
         (d == Face_defect::too_large ? "an edge longer than 1e145" : "all edges shorter than about 1e-145") +
         "; rescale the mesh)";
}

struct Mesh_topology
{
  Index num_vertices = 0;
  Index num_faces = 0;
  Index num_edges = 0;
  Index num_boundary_edges = 0;

  /// 3 vertex indices per face, in the face's orientation.
  std::vector<Index> triangles;

  /// The corners incident to vertex v are vertex_corners[corner_begin[v] .. corner_begin[v+1]).
  std::vector<Index> corner_begin;
  std::vector<Index> vertex_corners;

  /// Symmetric sparsity pattern, diagonal included, sorted within each row. Because it is
  /// symmetric, it is at once the CSR and the CSC (Eigen column-major) structure.
  std::vector<Index> outer;  // num_vertices + 1
  std::vector<Index> inner;  // number of non-zeros
  std::vector<Index> diagonal_slot;

  /// For the slot (i, j), j != i: the corner opposite the halfedge i->j and the corner
  /// opposite the halfedge j->i (-1 where that side has no face, i.e. on the boundary).
  /// The diagonal slots hold {-1, -1}.
  std::vector<std::array<Index, 2>> slot_corners;

  std::vector<char> on_boundary;

  /// False when some edge has more than two faces, or two faces on the same side (faces
  /// that disagree in orientation). The slots of such an edge hold the first face of each
  /// side; `edge_fans` holds all of them. Only the intrinsic Delaunay Laplacian, through the
  /// tufted cover, takes such a mesh (require_manifold()).
  bool manifold = true;
  /// For each non-manifold edge (i < j): its slot in row i, then the corners opposite every
  /// halfedge on it. Flattened: fan_begin[e] .. fan_begin[e+1] index fan_corners.
  std::vector<Index> fan_slot, fan_begin{0}, fan_corners;

  Index num_nonzeros() const { return static_cast<Index>(inner.size()); }
  /// False for a topology of corners only (build_corner_topology()): no pattern, no slots.
  bool has_pattern() const { return !outer.empty(); }
  Index degree(Index v) const { return outer[v + 1] - outer[v] - 1; }
};

/// The part of every topology that a pass over the corners needs: the triangles, checked, and
/// each vertex's incident corners, by a counting sort (ascending corner index per vertex).
/// Throws Mesh_error for an index out of range, a face with a repeated vertex and a vertex in
/// no face.
inline Mesh_topology build_corner_incidence(Index num_vertices, std::vector<Index> triangles)
{
  Mesh_topology t;
  t.num_vertices = num_vertices;
  t.num_faces = static_cast<Index>(triangles.size() / 3);
  t.triangles = std::move(triangles);
  const Index n = num_vertices, m = t.num_faces;
  const std::vector<Index>& tri = t.triangles;

  for(Index f = 0; f < m; ++f) {
    const Index a = tri[3 * f], b = tri[3 * f + 1], c = tri[3 * f + 2];
    if(a < 0 || b < 0 || c < 0 || a >= n || b >= n || c >= n)
      throw Mesh_error("face " + std::to_string(f) + " has a vertex index out of range [0, " +
                         std::to_string(n) + ")",
                       Mesh_error::Element::face, f);
    if(a == b || b == c || a == c)
      throw Mesh_error("face " + std::to_string(f) + " uses the same vertex twice",
                       Mesh_error::Element::face, f);
  }

  t.corner_begin.assign(n + 1, 0);
  for(Index c = 0; c < 3 * m; ++c) ++t.corner_begin[tri[c] + 1];
  for(Index v = 0; v < n; ++v) {
    if(t.corner_begin[v + 1] == 0)
      throw Mesh_error("vertex " + std::to_string(v) + " is in no face",
                       Mesh_error::Element::vertex, v);
    t.corner_begin[v + 1] += t.corner_begin[v];
  }
  t.vertex_corners.resize(3 * std::size_t(m));
  {
    std::vector<Index> fill(t.corner_begin.begin(), t.corner_begin.end() - 1);
    for(Index c = 0; c < 3 * m; ++c) t.vertex_corners[fill[tri[c]]++] = c;
  }
  return t;
}

/// Builds the topology from a triangle list over vertices 0..n-1.
/// Throws Mesh_error for an index out of range, a face with a repeated vertex and a vertex
/// in no face. An edge with two faces on the same side (three or more faces around an edge,
/// or two neighbouring faces with opposite orientations) makes the topology non-manifold
/// (`manifold` false, the edge in `edge_fans`).
inline Mesh_topology build_topology(Index num_vertices, std::vector<Index> triangles)
{
  Mesh_topology t = build_corner_incidence(num_vertices, std::move(triangles));
  const Index n = num_vertices;
  const std::vector<Index>& tri = t.triangles;

  // Rows of the one-ring pattern. Each incident corner of i contributes two halfedges:
  // i->q (its face's halfedge leaving i, opposite the corner at r) and r->i (opposite q).
  // They are packed as (neighbour << 33 | side << 32 | corner) so that a plain integer
  // insertion sort (rows hold ~12 entries) orders them by neighbour, then side.
  std::vector<std::uint64_t> ring;
  t.outer.resize(n + 1);
  t.diagonal_slot.resize(n);
  t.on_boundary.assign(n, 0);
  t.inner.reserve(7 * std::size_t(n));
  t.slot_corners.reserve(7 * std::size_t(n));
  t.outer[0] = 0;
  for(Index i = 0; i < n; ++i) {
    ring.clear();
    for(Index k = t.corner_begin[i]; k < t.corner_begin[i + 1]; ++k) {
      const Index c = t.vertex_corners[k];
      const Index cq = next_corner(c), cr = prev_corner(c);
      ring.push_back(std::uint64_t(tri[cq]) << 33 | std::uint64_t(cr));
      ring.push_back(std::uint64_t(tri[cr]) << 33 | std::uint64_t(1) << 32 | std::uint64_t(cq));
    }
    for(std::size_t a = 1; a < ring.size(); ++a) {
      const std::uint64_t key = ring[a];
      std::size_t b = a;
      for(; b > 0 && ring[b - 1] > key; --b) ring[b] = ring[b - 1];
      ring[b] = key;
    }
    bool diagonal_done = false;
    auto emit_diagonal = [&] {
      t.diagonal_slot[i] = static_cast<Index>(t.inner.size());
      t.inner.push_back(i);
      t.slot_corners.push_back({-1, -1});
      diagonal_done = true;
    };
    for(std::size_t k = 0; k < ring.size();) {
      const Index j = static_cast<Index>(ring[k] >> 33);
      if(!diagonal_done && j > i) emit_diagonal();
      std::array<Index, 2> corners = {-1, -1};
      const std::size_t first = k;
      bool fan = false;
      for(; k < ring.size() && static_cast<Index>(ring[k] >> 33) == j; ++k) {
        const Index corner = static_cast<Index>(ring[k] & 0xffffffffu);
        Index& slot = corners[(ring[k] >> 32) & 1u];
        if(slot != -1)
          fan = true;
        else
          slot = corner;
      }
      if(fan) {
        t.manifold = false;
        if(j > i) {
          t.fan_slot.push_back(static_cast<Index>(t.inner.size()));
          for(std::size_t r = first; r < k; ++r) t.fan_corners.push_back(static_cast<Index>(ring[r] & 0xffffffffu));
          t.fan_begin.push_back(static_cast<Index>(t.fan_corners.size()));
        }
      }
      if(corners[0] == -1 || corners[1] == -1) {
        t.on_boundary[i] = 1;
        if(j > i) ++t.num_boundary_edges;
      }
      if(j > i) ++t.num_edges;
      t.inner.push_back(j);
      t.slot_corners.push_back(corners);
    }
    if(!diagonal_done) emit_diagonal();
    t.outer[i + 1] = static_cast<Index>(t.inner.size());
  }
  return t;
}

/// The topology that per-corner passes and their gathers need (angles, areas, Gaussian
/// curvature): build_corner_incidence(), the boundary vertices and the edge counts, without
/// the sparsity pattern and its slots (has_pattern() false), which cost most of
/// build_topology(). Every field it fills equals build_topology()'s. A non-manifold mesh gets
/// the full topology, whose edge fans name the edge in require_manifold()'s message.
inline Mesh_topology build_corner_topology(Index num_vertices, std::vector<Index> triangles)
{
  Mesh_topology t = build_corner_incidence(num_vertices, std::move(triangles));
  const Index n = num_vertices;
  const std::vector<Index>& tri = t.triangles;
  t.on_boundary.assign(n, 0);
  // Around vertex i each corner gives a halfedge i->q (out) and one r->i (in). An edge is on
  // the boundary when only one of its halfedges exists; a halfedge seen twice (two faces on one
  // side of an edge) is what build_topology calls non-manifold. Each neighbour is stamped with
  // the vertex that saw it last, so no per-vertex list is sorted or cleared.
  std::vector<Index> out_seen(n, -1), in_seen(n, -1);
  Index edges = 0, boundary_edges = 0;
  for(Index i = 0; i < n; ++i) {
    const Index begin = t.corner_begin[i], end = t.corner_begin[i + 1];
    Index out_above = 0, both = 0, both_above = 0, in_only_above = 0;
    for(Index k = begin; k < end; ++k) {
      const Index j = tri[next_corner(t.vertex_corners[k])];
      if(out_seen[j] == i) return build_topology(n, std::move(t.triangles));
      out_seen[j] = i;
      out_above += j > i;
    }
    for(Index k = begin; k < end; ++k) {
      const Index j = tri[prev_corner(t.vertex_corners[k])];
      if(in_seen[j] == i) return build_topology(n, std::move(t.triangles));
      in_seen[j] = i;
      if(out_seen[j] == i) {
        ++both;
        both_above += j > i;
      } else {
        in_only_above += j > i;
      }
    }
    if(both != end - begin) t.on_boundary[i] = 1;
    edges += out_above + in_only_above;
    boundary_edges += out_above - both_above + in_only_above;
  }
  t.num_edges = edges;
  t.num_boundary_edges = boundary_edges;
  return t;
}

/// Throws Mesh_error naming the first non-manifold edge: the operators built on the edge
/// slots (cotangent, uniform) need at most one face on each side of an edge.
inline void require_manifold(const Mesh_topology& t, const char* operator_name)
{
  if(t.manifold) return;
  const Index slot = t.fan_slot.front();
  const Index j = t.inner[slot];
  const Index i = Index(std::upper_bound(t.outer.begin(), t.outer.end(), slot) - t.outer.begin()) - 1;
  const Index faces = t.fan_begin[1] - t.fan_begin[0], f = t.fan_corners.front() / 3;
  throw Mesh_error("edge (" + std::to_string(i) + ", " + std::to_string(j) + ") at face " + std::to_string(f) +
                     " is non-manifold (" + std::to_string(faces) +
                     " faces, or two faces with opposite orientations): the " + operator_name +
                     " Laplacian needs a manifold mesh; the intrinsic-delaunay Laplacian takes it",
                   Mesh_error::Element::face, f);
}

/// Number of connected components (through edges), by union–find over the faces.
inline Index count_connected_components(const Mesh_topology& t)
{
  std::vector<Index> parent(t.num_vertices);
  for(Index v = 0; v < t.num_vertices; ++v) parent[v] = v;
  auto find = [&](Index v) {
    while(parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for(Index f = 0; f < t.num_faces; ++f)
    for(int a = 1; a < 3; ++a) {
      const Index x = find(t.triangles[3 * f]), y = find(t.triangles[3 * f + a]);
      if(x != y) parent[std::max(x, y)] = std::min(x, y);
    }
  Index count = 0;
  for(Index v = 0; v < t.num_vertices; ++v) count += (find(v) == v);
  return count;
}

} // namespace internal
} // namespace lapmesh

#endif
