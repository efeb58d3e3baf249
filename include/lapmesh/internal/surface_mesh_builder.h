// Internal: a CGAL::Surface_mesh built at once from triangles that form a manifold surface.
//
// Adding faces one at a time with CGAL::Euler::add_face() looks up each edge by circulating
// around its vertex and re-links the border as the surface grows; on a mesh of a million
// vertices that took longer than any computation lapmesh runs on it. When the triangles form
// a manifold surface, consistently oriented, the halfedges can be paired up front from each
// vertex's corners and the connectivity written in one pass. The result is the mesh that
// add_face() builds from the same triangles in the same order: the same vertices, faces,
// edges and halfedges (numbered in the order add_face() creates them), the same cycle and
// first halfedge for each face, and the same halfedge for each vertex (for a vertex on the
// border, its border halfedge coming in).
#ifndef LAPMESH_INTERNAL_SURFACE_MESH_BUILDER_H
#define LAPMESH_INTERNAL_SURFACE_MESH_BUILDER_H

#include <lapmesh/internal/topology.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace lapmesh {
namespace internal {

/// Builds `g` (emptied first) from triangles over the points, vertex i = point i, and returns
/// true; when the triangles are not a consistently oriented manifold surface (an edge with
/// two faces on one side or more than two faces, a vertex whose faces form several fans),
/// leaves `g` empty and returns false, for the caller to add the faces one at a time.
/// Preconditions: indices in range, no face with a repeated vertex.
template <typename SurfaceMesh>
bool build_manifold_surface_mesh(const std::vector<std::array<double, 3>>& points,
                                 const std::vector<std::array<std::size_t, 3>>& triangles, SurfaceMesh& g)
{
  using Point = typename SurfaceMesh::Point;
  using size_type = typename SurfaceMesh::size_type;
  using Vertex = typename SurfaceMesh::Vertex_index;
  using Halfedge = typename SurfaceMesh::Halfedge_index;
  using Face = typename SurfaceMesh::Face_index;
  g.clear();
  // Halfedges are numbered up to twice the corners: beyond Index's range, add_face() builds it.
  constexpr std::size_t index_limit = std::size_t(std::numeric_limits<Index>::max());
  if(points.size() > index_limit || triangles.size() > index_limit / 6) return false;
  const Index n = Index(points.size()), corners = Index(3 * triangles.size());
  const auto vertex_of = [&](Index c) { return Index(triangles[std::size_t(c) / 3][std::size_t(c) % 3]); };

  // Each vertex's corners, in corner order.
  std::vector<Index> begin(std::size_t(n) + 1);
  std::vector<Index> vertex_corners(static_cast<std::size_t>(corners));
  counting_sort_corners(n, std::size_t(corners), [&vertex_of](std::size_t c) { return vertex_of(Index(c)); },
                        begin.data(), vertex_corners.data());

  // The halfedge of corner c runs from its vertex a to the next corner's, b. Its opposite runs
  // from b to a: the halfedge of the corner before a corner of a whose previous vertex is b.
  // So each vertex's own corners pair its halfedges up, and show whether its faces form one fan
  // (turning around a, the face after the one of corner k is the one whose previous vertex is
  // k's next vertex). Until the halfedges are numbered below, corner_halfedge holds
  // -2 - (the opposite corner), or -1 where there is none.
  std::vector<Index> corner_halfedge(std::size_t(corners), -1);
  // Around vertex a, which of its corners k has b as its next vertex: next_of[b] = {a, k}.
  // Looking the neighbours up there keeps a vertex of any degree linear.
  std::vector<std::array<Index, 2>> next_of(std::size_t(n), {-1, -1});
  std::vector<Index> ring_after;
  std::vector<char> has_before;
  for(Index a = 0; a < n; ++a) {
    const Index first = begin[std::size_t(a)], degree = begin[std::size_t(a) + 1] - first;
    if(degree == 0) continue;
    const Index* ring = &vertex_corners[std::size_t(first)];
    ring_after.assign(std::size_t(degree), -1);
    has_before.assign(std::size_t(degree), 0);
    for(Index k = 0; k < degree; ++k) {
      const Index b = vertex_of(next_corner(ring[k]));
      if(next_of[std::size_t(b)][0] == a) return false;  // a -> b twice
      next_of[std::size_t(b)] = {a, k};
    }
    for(Index j = 0; j < degree; ++j) {
      const Index b = vertex_of(prev_corner(ring[j]));
      if(next_of[std::size_t(b)][0] != a) continue;
      const Index k = next_of[std::size_t(b)][1];  // face j follows face k around a
      Index& after = ring_after[std::size_t(k)];
      if(after >= 0) return false;  // b -> a twice
      after = j;
      has_before[std::size_t(j)] = 1;
    }
    Index open_fans = 0, fan_start = 0;
    for(Index k = 0; k < degree; ++k) {
      const Index after = ring_after[std::size_t(k)];
      if(after >= 0) corner_halfedge[std::size_t(ring[k])] = -2 - prev_corner(ring[after]);
      if(!has_before[std::size_t(k)]) {
        ++open_fans;
        fan_start = k;
      }
    }
    // One fan, open or closed: turning from where it starts (anywhere in a closed one) meets
    // every face of the vertex.
    if(open_fans > 1) return false;
    Index met = 1;
    for(Index k = ring_after[std::size_t(fan_start)]; k >= 0 && k != fan_start && met < degree;
        k = ring_after[std::size_t(k)])
      ++met;
    if(met != degree) return false;
  }

  // Edges are numbered as add_face() creates them: in face order, the halfedge of the face
  // that meets the edge first is the even one. (An opposite corner comes later in corner
  // order, or it would have numbered this one.)
  std::vector<char> on_border(std::size_t(corners), 0);
  Index edges = 0;
  for(Index c = 0; c < corners; ++c) {
    const Index state = corner_halfedge[std::size_t(c)];
    if(state >= 0) continue;
    corner_halfedge[std::size_t(c)] = 2 * edges;
    if(state == -1)
      on_border[std::size_t(c)] = 1;
    else
      corner_halfedge[std::size_t(-2 - state)] = 2 * edges + 1;
    ++edges;
  }

  // A halfedge with no opposite face has a border halfedge as its opposite. A vertex of a
  // manifold surface has at most one border halfedge coming in and one going out.
  std::vector<Index> border_in(std::size_t(n), -1), border_out(std::size_t(n), -1);
  for(Index c = 0; c < corners; ++c) {
    if(!on_border[std::size_t(c)]) continue;
    const Index border = corner_halfedge[std::size_t(c)] ^ 1;
    const Index to = vertex_of(c), from = vertex_of(next_corner(c));
    if(border_in[std::size_t(to)] >= 0 || border_out[std::size_t(from)] >= 0) return false;
    border_in[std::size_t(to)] = border;
    border_out[std::size_t(from)] = border;
  }
  for(Index v = 0; v < n; ++v)
    if((border_in[std::size_t(v)] >= 0) != (border_out[std::size_t(v)] >= 0)) return false;

  g.reserve(size_type(n), size_type(edges), size_type(triangles.size()));
  for(const auto& p : points) g.add_vertex(Point(p[0], p[1], p[2]));
  for(Index e = 0; e < edges; ++e) g.add_edge();
  const auto halfedge = [](Index h) { return Halfedge(size_type(h)); };
  for(std::size_t f = 0; f < triangles.size(); ++f) {
    const Face face = g.add_face();
    for(Index k = 0; k < 3; ++k) {
      const Index c = Index(3 * f) + k, c_next = next_corner(c);
      const Halfedge h = halfedge(corner_halfedge[std::size_t(c)]);
      g.set_target(h, Vertex(size_type(vertex_of(c_next))));
      g.set_face(h, face);
      g.set_next(h, halfedge(corner_halfedge[std::size_t(c_next)]));
    }
    g.set_halfedge(face, halfedge(corner_halfedge[3 * f + 2]));  // the one into the face's first vertex
  }
  for(Index v = 0; v < n; ++v) {
    if(border_in[std::size_t(v)] >= 0) {
      const Halfedge border = halfedge(border_in[std::size_t(v)]);
      g.set_target(border, Vertex(size_type(v)));
      g.set_next(border, halfedge(border_out[std::size_t(v)]));
      g.set_halfedge(Vertex(size_type(v)), border);
    } else if(begin[std::size_t(v)] < begin[std::size_t(v) + 1]) {
      // add_face() leaves an inner vertex with the halfedge into it of the face that closed its
      // umbrella: its last face.
      const Index last = vertex_corners[std::size_t(begin[std::size_t(v) + 1] - 1)];
      g.set_halfedge(Vertex(size_type(v)), halfedge(corner_halfedge[std::size_t(prev_corner(last))]));
    }
  }

  return true;
}

/// The mean number of faces around a vertex, weighted by that number, above which adding the
/// faces one at a time (CGAL::Euler::add_face(), whose cost grows with it) is not tried.
constexpr std::uint64_t max_face_by_face_degree = 64;

/// Whether CGAL::Euler::add_face() takes time linear in the size of the mesh for these
/// triangles: the sum over the vertices of the square of their number of faces is at most
/// max_face_by_face_degree times the number of corners (a usual mesh has about 6).
inline bool face_by_face_is_affordable(std::size_t num_points, const std::vector<std::array<std::size_t, 3>>& triangles)
{
  std::vector<std::uint32_t> faces_at(num_points, 0);
  for(const auto& t : triangles)
    for(std::size_t v : t) ++faces_at[v];
  std::uint64_t squares = 0;
  for(std::uint32_t d : faces_at) squares += std::uint64_t(d) * d;
  return squares <= max_face_by_face_degree * 3 * std::uint64_t(triangles.size());
}

} // namespace internal
} // namespace lapmesh

#endif
