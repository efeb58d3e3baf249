// Internal: the distance from a point to a triangle mesh, and the sampled one-sided Hausdorff
// distance between two meshes that the denoising study measures.
//
// A hierarchy of axis-aligned boxes prunes badly where many long thin faces meet at one vertex
// (a fan): every face's box reaches that vertex, so a query anywhere near the fan's middle visits
// a fixed share of its faces, and sampling the fan costs the square of its size. The faces of a
// vertex of many faces are therefore kept apart, in a hierarchy of their directions seen from
// that vertex: a point at distance rho from it, whose direction is a chord c away from every
// direction a face takes, is at least rho * min(c / sqrt(2), 1) away from those faces.
#ifndef LAPMESH_INTERNAL_SURFACE_DISTANCE_H
#define LAPMESH_INTERNAL_SURFACE_DISTANCE_H

#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/parallel.h>
#include <lapmesh/internal/topology.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace lapmesh {
namespace internal {

inline double squared_distance_to_segment(const Point3& p, const Point3& a, const Point3& b)
{
  const Point3 ab = b - a;
  const double length_sq = ab.squaredNorm();
  const double t = length_sq > 0 ? std::clamp((p - a).dot(ab) / length_sq, 0.0, 1.0) : 0.0;
  return (p - a - t * ab).squaredNorm();
}

/// The squared distance from p to the triangle abc, by the Voronoi region of p (vertex, edge or
/// face). A triangle without area is measured as its three sides.
inline double squared_distance_to_triangle(const Point3& p, const Point3& a, const Point3& b, const Point3& c)
{
  const Point3 ab = b - a, ac = c - a;
  const auto sides = [&] {
    return std::min({squared_distance_to_segment(p, a, b), squared_distance_to_segment(p, b, c),
                     squared_distance_to_segment(p, c, a)});
  };
  if(!(ab.cross(ac).squaredNorm() > 0)) return sides();
  const Point3 ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if(d1 <= 0 && d2 <= 0) return ap.squaredNorm();
  const Point3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if(d3 >= 0 && d4 <= d3) return bp.squaredNorm();
  const double vc = d1 * d4 - d3 * d2;
  if(vc <= 0 && d1 >= 0 && d3 <= 0) return (ap - d1 / (d1 - d3) * ab).squaredNorm();
  const Point3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if(d6 >= 0 && d5 <= d6) return cp.squaredNorm();
  const double vb = d5 * d2 - d1 * d6;
  if(vb <= 0 && d2 >= 0 && d6 <= 0) return (ap - d2 / (d2 - d6) * ac).squaredNorm();
  const double va = d3 * d6 - d5 * d4;
  if(va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return (bp - (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)).squaredNorm();
  // Inside: the barycentric weights from the sub-areas. Rounding on a nearly flat triangle can
  // leave them outside [0, 1]; its sides are then the answer.
  const double sum = va + vb + vc, v = vb / sum, w = vc / sum;
  if(!(sum > 0) || !(v >= 0 && w >= 0 && v + w <= 1)) return sides();
  return (ap - v * ab - w * ac).squaredNorm();
}

/// (Morton code, index) of each centre, in the order of the codes, on the centres' bounding box.
inline std::vector<std::pair<std::uint64_t, std::int32_t>> sorted_morton_keys(const std::vector<Point3>& centres)
{
  Box3 bounds;
  for(const Point3& c : centres) bounds.extend(c);
  std::vector<std::pair<std::uint64_t, std::int32_t>> keys(centres.size());
  for(std::size_t i = 0; i < keys.size(); ++i) keys[i] = {morton_code(centres[i], bounds), std::int32_t(i)};
  std::sort(keys.begin(), keys.end());
  return keys;
}

/// A binary hierarchy over items: each node's box holds its items', a leaf holds at most four.
/// The items are put in order along a Morton curve through their centres (one sort) and split
/// where the codes' highest differing bit changes, as the cells of an octree; every item is read
/// once, for its leaf. Leaves hold positions [begin, end) of that order, in which the caller keeps
/// its items so that a leaf reads one stretch of memory.
struct Box_hierarchy
{
  struct Node
  {
    Box3 box;
    std::int32_t begin = 0, end = 0;  // positions [begin, end) of a leaf
    std::int32_t right = -1;          // the second child (the first is the next node); -1: a leaf
  };
  std::vector<Node> nodes;

  /// The items in Morton order of their centres (the item at each position).
  std::vector<std::int32_t> order(const std::vector<Point3>& centres)
  {
    const auto keys = sorted_morton_keys(centres);
    std::vector<std::int32_t> items(keys.size());
    m_codes.resize(keys.size());
    for(std::size_t k = 0; k < keys.size(); ++k) {
      items[k] = keys[k].second;
      m_codes[k] = keys[k].first;
    }
    return items;
  }

  /// The nodes over the items of the last order(); box_of(k): the box of the item at position k.
  template <typename BoxOf>
  void build(const BoxOf& box_of)
  {
    nodes.clear();
    nodes.reserve(2 * m_codes.size());  // leaves of one to four items: fewer than 2n nodes
    if(!m_codes.empty()) build_node(box_of, 0, std::int32_t(m_codes.size()));
    m_codes = {};
  }

  /// The boxes again, for items that have moved; the tree is kept. box_of(k) as for build().
  template <typename BoxOf>
  void refit(const BoxOf& box_of)
  {
    // A node's children follow it: from the last node back, every child is fitted before its parent.
    for(std::size_t n = nodes.size(); n-- > 0;) {
      Node& node = nodes[n];
      Box3 box;
      if(node.right < 0) {
        for(std::int32_t k = node.begin; k < node.end; ++k) box.extend(box_of(std::size_t(k)));
      } else {
        box = nodes[n + 1].box;
        box.extend(nodes[std::size_t(node.right)].box);
      }
      node.box = box;
    }
  }

private:
  template <typename BoxOf>
  std::int32_t build_node(const BoxOf& box_of, std::int32_t begin, std::int32_t end)
  {
    const std::int32_t index = std::int32_t(nodes.size());
    nodes.emplace_back();
    if(end - begin <= 4) {
      Box3 box;
      for(std::int32_t k = begin; k < end; ++k) box.extend(box_of(std::size_t(k)));
      nodes[index].box = box;
      nodes[index].begin = begin;
      nodes[index].end = end;
      return index;
    }
    // Items of one code (one cell of the finest grid) are split by count.
    std::int32_t middle = begin + (end - begin) / 2;
    const std::uint64_t differing = m_codes[std::size_t(begin)] ^ m_codes[std::size_t(end) - 1];
    if(differing != 0) {
      std::uint64_t bit = std::uint64_t(1) << 63;
      while(!(differing & bit)) bit >>= 1;
      middle = std::int32_t(std::partition_point(m_codes.begin() + begin, m_codes.begin() + end,
                                                 [&](std::uint64_t c) { return !(c & bit); }) -
                            m_codes.begin());
    }
    build_node(box_of, begin, middle);
    const std::int32_t right = build_node(box_of, middle, end);
    Box3 box = nodes[std::size_t(index) + 1].box;
    box.extend(nodes[std::size_t(right)].box);
    nodes[index].box = box;
    nodes[index].right = right;
    return index;
  }

  std::vector<std::uint64_t> m_codes;  // of the items in order, between order() and build()
};

/// The box of a triangle's corners.
inline Box3 triangle_box(const std::array<Point3, 3>& t)
{
  Box3 b;
  for(const Point3& p : t) b.extend(p);
  return b;
}

/// Squared distances from points to the faces of a triangle mesh (any: with borders, non-manifold,
/// with faces without area). Faces around a vertex of at least `fan_faces` faces go into that
/// vertex's fan (the vertex of most faces among the three), searched by direction. A mesh whose
/// vertices move (the same faces) is refitted, not built again: the hierarchies keep their trees
/// and take new boxes, and the distances found are the same as those of a new build.
class Surface_distance
{
public:
  static constexpr Index fan_faces = 32;
  using Corners = std::array<Index, 3>;

  Surface_distance() = default;
  Surface_distance(const Positions& P, const Working_array<Index>& triangles)
  {
    const std::size_t num_faces = triangles.size() / 3;
    std::vector<Index> faces_of(std::size_t(P.rows()), 0);
    for(Index v : triangles) ++faces_of[std::size_t(v)];
    // A face's corners from its apex, the corner of most faces.
    const auto apex_first = [&](std::size_t f) -> Corners {
      const Index* c = &triangles[3 * f];
      int apex = 0;
      for(int k = 1; k < 3; ++k)
        if(faces_of[std::size_t(c[k])] > faces_of[std::size_t(c[apex])]) apex = k;
      return {c[apex], c[(apex + 1) % 3], c[(apex + 2) % 3]};
    };
    const auto centre = [&](std::size_t f) { return triangle_box(triangle_at(P, apex_first(f))).center(); };

    // The faces in no fan, and each fan's faces.
    std::vector<std::int32_t> loose;
    loose.reserve(num_faces);
    std::vector<std::vector<std::int32_t>> fan_faces_of;
    std::vector<std::int32_t> fan_of_vertex(std::size_t(P.rows()), -1);
    for(std::size_t f = 0; f < num_faces; ++f) {
      const Index apex = apex_first(f)[0];
      if(faces_of[std::size_t(apex)] < fan_faces) {
        loose.push_back(std::int32_t(f));
        continue;
      }
      std::int32_t& fan = fan_of_vertex[std::size_t(apex)];
      if(fan < 0) {
        fan = std::int32_t(fan_faces_of.size());
        fan_faces_of.emplace_back();
      }
      fan_faces_of[std::size_t(fan)].push_back(std::int32_t(f));
    }
    m_face_places.resize(num_faces);

    m_fans.resize(fan_faces_of.size());
    for(std::size_t g = 0; g < m_fans.size(); ++g) {
      Fan& fan = m_fans[g];
      const std::vector<std::int32_t>& faces = fan_faces_of[g];
      std::vector<Point3> centres(faces.size());
      for(std::size_t i = 0; i < faces.size(); ++i) centres[i] = centre(std::size_t(faces[i]));
      const std::vector<std::int32_t> order = fan.hierarchy.order(centres);
      fan.corners.resize(faces.size());
      for(std::size_t k = 0; k < order.size(); ++k) {
        const std::size_t f = std::size_t(faces[std::size_t(order[k])]);
        m_face_places[f] = {std::int32_t(g), std::int32_t(k)};
        fan.corners[k] = apex_first(f);
      }
      place(fan, P);
      fan.hierarchy.build([&](std::size_t k) { return triangle_box(fan.triangles[k]); });
      fit_node_directions(fan);
    }

    // The loose faces and the fans as items of one hierarchy, in its order.
    std::vector<Point3> centres(loose.size() + m_fans.size());
    for(std::size_t i = 0; i < loose.size(); ++i) centres[i] = centre(std::size_t(loose[i]));
    for(std::size_t g = 0; g < m_fans.size(); ++g) centres[loose.size() + g] = m_fans[g].hierarchy.nodes.front().box.center();
    const std::vector<std::int32_t> order = m_hierarchy.order(centres);
    m_items.resize(order.size());
    m_corners.reserve(loose.size());
    for(std::size_t k = 0; k < order.size(); ++k) {
      const std::size_t item = std::size_t(order[k]);
      if(item < loose.size()) {
        m_items[k] = std::int32_t(m_corners.size());
        m_face_places[std::size_t(loose[item])] = {-1, std::int32_t(m_corners.size())};
        m_corners.push_back(apex_first(std::size_t(loose[item])));
      } else {
        m_items[k] = -1 - std::int32_t(item - loose.size());
      }
    }
    m_triangles.resize(m_corners.size());
    for(std::size_t i = 0; i < m_corners.size(); ++i) m_triangles[i] = triangle_at(P, m_corners[i]);
    m_hierarchy.build([&](std::size_t k) { return item_box(k); });
  }

  /// The same faces at positions P (of as many vertices as the mesh built on); the fans' faces
  /// in parallel when `parallel`.
  void refit(const Positions& P, bool parallel = false)
  {
    for_each_index(m_triangles.size(), parallel, [&](std::size_t i) { m_triangles[i] = triangle_at(P, m_corners[i]); });
    for_each_index(m_fans.size(), parallel, [&](std::size_t g) {
      Fan& fan = m_fans[g];
      place(fan, P);
      fan.hierarchy.refit([&](std::size_t k) { return triangle_box(fan.triangles[k]); });
      fit_node_directions(fan);
    }, std::size_t(1));
    m_hierarchy.refit([&](std::size_t k) { return item_box(k); });
  }

  /// The squared distance from p to the nearest face, or any value of at most `enough` once one
  /// face is found that near (a caller after a maximum of distances needs no more); infinity
  /// without faces.
  double squared_distance(const Point3& p, double enough = -1) const
  {
    double best = std::numeric_limits<double>::infinity();
    search(m_hierarchy, p, best, enough, [&](std::int32_t item, double& best_so_far) {
      const std::int32_t i = m_items[std::size_t(item)];
      if(i >= 0) {
        const auto& t = m_triangles[std::size_t(i)];
        best_so_far = std::min(best_so_far, squared_distance_to_triangle(p, t[0], t[1], t[2]));
      } else {
        search_fan(m_fans[std::size_t(-1 - i)], p, best_so_far, enough);
      }
    });
    return best;
  }

  /// The squared distance from p to face f of the triangles the search was built on, computed as
  /// the search computes it: no less than squared_distance(p), a bound of it for the cost of one face.
  double squared_distance_to_face(std::size_t f, const Point3& p) const
  {
    const Face_place place = m_face_places[f];
    const auto& t = place.fan < 0 ? m_triangles[std::size_t(place.index)]
                                  : m_fans[std::size_t(place.fan)].triangles[std::size_t(place.index)];
    return squared_distance_to_triangle(p, t[0], t[1], t[2]);
  }

  std::size_t face_count() const { return m_face_places.size(); }
  std::size_t fan_count() const { return m_fans.size(); }

private:
  struct Fan
  {
    Point3 apex;
    std::vector<Corners> corners;                   // of each face, apex first
    std::vector<std::array<Point3, 3>> triangles;  // apex first
    std::vector<Box3> directions;                   // of each face: its unit directions from the apex
    Box_hierarchy hierarchy;                        // over the faces, kept in its order
    std::vector<Box3> node_directions;              // of each node of the hierarchy
  };

  static std::array<Point3, 3> triangle_at(const Positions& P, const Corners& c)
  {
    return {P.row(c[0]).transpose(), P.row(c[1]).transpose(), P.row(c[2]).transpose()};
  }

  // The fan's apex, faces and their directions at positions P.
  static void place(Fan& fan, const Positions& P)
  {
    fan.apex = P.row(fan.corners.front()[0]).transpose();
    fan.triangles.resize(fan.corners.size());
    fan.directions.resize(fan.corners.size());
    for(std::size_t k = 0; k < fan.corners.size(); ++k) {
      fan.triangles[k] = triangle_at(P, fan.corners[k]);
      fan.directions[k] = direction_box(fan.triangles[k]);
    }
  }

  // The box of the item at position k of the hierarchy's order: a loose face, or a fan's root.
  Box3 item_box(std::size_t k) const
  {
    const std::int32_t i = m_items[k];
    return i >= 0 ? triangle_box(m_triangles[std::size_t(i)]) : m_fans[std::size_t(-1 - i)].hierarchy.nodes.front().box;
  }

  // Each fan node also bounds the directions of its faces.
  static void fit_node_directions(Fan& fan)
  {
    fan.node_directions.resize(fan.hierarchy.nodes.size());
    for(std::size_t n = fan.hierarchy.nodes.size(); n-- > 0;) {
      const auto& node = fan.hierarchy.nodes[n];
      Box3 d;
      if(node.right < 0) {
        for(std::int32_t k = node.begin; k < node.end; ++k) d.extend(fan.directions[std::size_t(k)]);
      } else {
        d = fan.node_directions[n + 1];
        d.extend(fan.node_directions[std::size_t(node.right)]);
      }
      fan.node_directions[n] = d;
    }
  }

  // A box holding the unit directions from the apex t[0] to the points of the face: the arc of the
  // unit circle between the directions of the two other corners. The arc lies within its sagitta
  // of the chord. The margin covers the rounding of the bound.
  static Box3 direction_box(const std::array<Point3, 3>& t)
  {
    const Point3 a = t[1] - t[0], b = t[2] - t[0];
    const double la = a.norm(), lb = b.norm();
    Box3 d;
    if(!(la > 0) && !(lb > 0)) {  // the face is its apex: every direction
      d.extend(Point3::Constant(-1.0));
      d.extend(Point3::Constant(1.0));
      return d;
    }
    const Point3 ua = la > 0 ? Point3(a / la) : Point3(b / lb), ub = lb > 0 ? Point3(b / lb) : ua;
    d.extend(ua);
    d.extend(ub);
    const double sagitta = 1 - std::sqrt(std::max(0.0, 0.5 * (1 + ua.dot(ub))));
    const double margin = sagitta + 1e-9;
    d.lo.array() -= margin;
    d.hi.array() += margin;
    return d;
  }

  void search_fan(const Fan& fan, const Point3& p, double& best, double enough) const
  {
    const Point3 d = p - fan.apex;
    const double rho = d.norm();
    const Point3 direction = rho > 0 ? Point3(d / rho) : Point3::Zero();
    const auto direction_bound = [&](const Box3& directions) {
      if(!(rho > 0)) return 0.0;
      const double chord_sq = directions.squared_distance(direction);
      return rho * rho * std::min(0.5 * chord_sq, 1.0);
    };
    search(fan.hierarchy, p, best, enough,
           [&](std::int32_t item, double& best_so_far) {
             const auto& t = fan.triangles[std::size_t(item)];
             if(direction_bound(fan.directions[std::size_t(item)]) < best_so_far)
               best_so_far = std::min(best_so_far, squared_distance_to_triangle(p, t[0], t[1], t[2]));
           },
           [&](std::size_t node) { return direction_bound(fan.node_directions[node]); });
  }

  // Depth first, the nearer child first; a node is skipped when its bound is no less than the
  // best distance so far, and the search stops once that is at most `enough`.
  template <typename VisitItem, typename ExtraBound>
  static void search(const Box_hierarchy& h, const Point3& p, double& best, double enough, const VisitItem& visit,
                     const ExtraBound& extra_bound)
  {
    if(h.nodes.empty()) return;
    const auto bound = [&](std::size_t n) { return std::max(h.nodes[n].box.squared_distance(p), extra_bound(n)); };
    struct Entry
    {
      std::size_t node;
      double bound;
    };
    Entry stack[128];
    int top = 0;
    stack[top++] = {0, bound(0)};
    while(top > 0) {
      const Entry e = stack[--top];
      if(e.bound >= best) continue;
      const auto& node = h.nodes[e.node];
      if(node.right < 0) {
        for(std::int32_t k = node.begin; k < node.end; ++k) {
          visit(k, best);
          if(best <= enough) return;
        }
        continue;
      }
      const std::size_t left = e.node + 1, right = std::size_t(node.right);
      const double bl = bound(left), br = bound(right);
      // The depth is at most 63 splits by bit and 31 by count: the stack holds one entry per level and one more.
      if(bl <= br) {
        if(br < best) stack[top++] = {right, br};
        if(bl < best) stack[top++] = {left, bl};
      } else {
        if(bl < best) stack[top++] = {left, bl};
        if(br < best) stack[top++] = {right, br};
      }
    }
  }

  template <typename VisitItem>
  static void search(const Box_hierarchy& h, const Point3& p, double& best, double enough, const VisitItem& visit)
  {
    search(h, p, best, enough, visit, [](std::size_t) { return 0.0; });
  }

  struct Face_place
  {
    std::int32_t fan, index;  // fan -1: m_triangles[index]; otherwise m_fans[fan].triangles[index]
  };
  std::vector<Face_place> m_face_places;            // of each face, by its index in the triangles
  std::vector<Corners> m_corners;                   // the faces in no fan
  std::vector<std::array<Point3, 3>> m_triangles;  // their corners' positions
  std::vector<std::int32_t> m_items;  // in the hierarchy's order: >= 0 a face of m_triangles, < 0 fan -1 - item
  std::vector<Fan> m_fans;
  Box_hierarchy m_hierarchy;
};

// The grid's steps: equal parts of the edge ab, and the steps of the face grid from p0 (its third
// corner) along its two sides.
inline double edge_parts(const Point3& a, const Point3& b, double spacing) { return std::ceil((b - a).norm() / spacing); }
inline double face_grid_steps(const Point3& p0, const Point3& p1, const Point3& p2, double spacing)
{
  return std::max(edge_parts(p0, p1, spacing), edge_parts(p0, p2, spacing));
}

/// The fewest samples a mesh may always take, and how many per corner beyond them.
constexpr double grid_sample_floor = double(1 << 20);
constexpr double grid_samples_per_corner = 16;

/// The grid samples of the faces of a mesh at a spacing: every vertex in a face, the points that
/// split each edge into ceil(length / spacing) equal parts, and the inner points of each face's
/// barycentric grid, of ceil(longest of two sides / spacing) steps from its third corner. This is
/// the sampling of CGAL's `sample_triangle_mesh()` with grid sampling on a `Surface_mesh` built
/// face by face (whose faces begin at their third corner), so that the two can be compared.
///
/// The samples are made face by face, where they are visited, each vertex and edge with the first
/// face that holds it, and the faces in the Morton order of their centres at the positions given
/// to the constructor: samples that follow one another lie close together, so that their searches
/// share a path through a hierarchy and find it in cache, with no sample stored or sorted, and
/// threads take runs of faces. The connectivity is fixed; the positions sampled may change.
class Grid_samples
{
public:
  Grid_samples() = default;
  Grid_samples(const Mesh_topology& t, const Positions& P)
  {
    const std::size_t num_faces = std::size_t(t.num_faces);
    std::vector<Point3> centres(num_faces);
    for(std::size_t f = 0; f < num_faces; ++f) centres[f] = triangle_box(face_points(t, P, Index(f))).center();
    const auto keys = sorted_morton_keys(centres);
    m_faces.resize(num_faces);
    m_face_indices.resize(num_faces);
    m_owned.resize(num_faces);
    std::vector<char> vertex_taken(std::size_t(t.num_vertices), 0), edge_taken(t.inner.size(), 0);
    for(std::size_t k = 0; k < num_faces; ++k) {
      const Index* c = &t.triangles[3 * std::size_t(keys[k].second)];
      m_faces[k] = {c[0], c[1], c[2]};
      m_face_indices[k] = Index(keys[k].second);
      unsigned char owned = 0;
      for(int m = 0; m < 3; ++m) {
        char& taken = vertex_taken[std::size_t(c[m])];
        if(!taken) taken = 1, owned |= vertex_bit(m);
        const auto [i, j] = edge(m_faces[k], m);
        if(i == j) continue;  // a face without area: its repeated corner is no edge
        const Index* row = t.inner.data() + t.outer[i];
        const Index* end = t.inner.data() + t.outer[i + 1];
        char& edge = edge_taken[std::size_t(std::lower_bound(row, end, j) - t.inner.data())];
        if(!edge) edge = 1, owned |= edge_bit(m);
      }
      m_owned[k] = owned;
    }
  }

  std::size_t num_faces() const { return m_faces.size(); }

  /// Calls visit(point, face) for the samples of the faces at positions [begin, end) of the
  /// order, with the index of the face that holds each.
  template <typename Visit>
  void visit(const Positions& P, double spacing, std::size_t begin, std::size_t end, const Visit& visit) const
  {
    const auto point = [&](Index i) -> Point3 { return P.row(i).transpose(); };
    for(std::size_t k = begin; k < end; ++k) {
      const std::array<Index, 3>& c = m_faces[k];
      const std::size_t face = std::size_t(m_face_indices[k]);
      const unsigned owned = m_owned[k];
      for(int m = 0; m < 3; ++m)
        if(owned & vertex_bit(m)) visit(point(c[std::size_t(m)]), face);
      for(int m = 0; m < 3; ++m) {
        if(!(owned & edge_bit(m))) continue;
        const auto [i, j] = edge(c, m);
        const Point3 a = point(i);
        const double parts = edge_parts(a, point(j), spacing);
        if(!(parts > 1)) continue;
        const Point3 step = (point(j) - a) * (1 / parts);
        for(double s = 1; s < parts; ++s) visit(Point3(a + s * step), face);
      }
      const Point3 p0 = point(c[2]), p1 = point(c[0]), p2 = point(c[1]);
      const double n = face_grid_steps(p0, p1, p2, spacing);
      for(double i = 1; i < n; ++i)
        for(double j = 1; j < n - i; ++j) {
          const double c0 = 1 - (i + j) / n, c1 = i / n, c2 = j / n;
          visit(Point3(c0 * p0 + c1 * p1 + c2 * p2), face);
        }
    }
  }

  /// How many points visit() would visit over all faces, without visiting them.
  double count(const Positions& P, double spacing, bool parallel = false) const
  {
    const auto point = [&](Index i) -> Point3 { return P.row(i).transpose(); };
    std::vector<double> counts(part_count(m_faces.size(), faces_per_part), 0.0);
    for_each_part(m_faces.size(), faces_per_part, parallel, [&](std::size_t part, std::size_t begin, std::size_t end) {
      double count = 0;  // whole numbers: the sum does not depend on how the faces are split
      for(std::size_t k = begin; k < end; ++k) {
        const std::array<Index, 3>& c = m_faces[k];
        const unsigned owned = m_owned[k];
        for(int m = 0; m < 3; ++m) {
          if(owned & vertex_bit(m)) count += 1;
          if(owned & edge_bit(m)) {
            const auto [i, j] = edge(c, m);
            count += std::max(0.0, edge_parts(point(i), point(j), spacing) - 1);
          }
        }
        const double n = face_grid_steps(point(c[2]), point(c[0]), point(c[1]), spacing);
        if(n > 2) count += (n - 1) * (n - 2) / 2;
      }
      counts[part] = count;
    });
    double total = 0;
    for(double c : counts) total += c;
    return total;
  }

  /// `spacing`, or a coarser one if the grid would hold more than grid_sample_floor or
  /// grid_samples_per_corner samples per corner: the work of a sampled distance stays bounded on a
  /// mesh of a few faces far larger than the rest, or for a spacing asked far below the edges.
  double bounded_spacing(const Positions& P, double spacing, bool parallel = false) const
  {
    const double limit = std::max(grid_sample_floor, grid_samples_per_corner * 3.0 * double(m_faces.size()));
    for(int attempt = 0; attempt < 64; ++attempt) {
      const double count = this->count(P, spacing, parallel);
      if(count <= limit) return spacing;
      // The face grids grow as the square of 1 / spacing: the square root of the excess and a
      // little more brings them under the limit in a step or two.
      spacing *= 1.05 * std::sqrt(count / limit);
    }
    return spacing;
  }

  /// The largest distance from a sample at positions P to `surface`; runs of faces are sampled
  /// and searched by several threads when `parallel` (and TBB is available), with the same result.
  double largest_distance(const Positions& P, double spacing, const Surface_distance& surface,
                          bool parallel = false) const
  {
    // Each run of faces starts from the largest distance found so far. The maximum does not
    // depend on which runs saw which: a sample is only cut short at or below a distance found.
    // The surface's face of the same index (the same face, on a mesh of the same connectivity,
    // and near the sample when the two meshes are close) is tried first: at most the largest
    // distance so far from it, the sample cannot raise the maximum and needs no search.
    const std::size_t surface_faces = surface.face_count();
    std::atomic<double> largest_sq{0.0};
    for_each_part(m_faces.size(), faces_per_part, parallel, [&](std::size_t, std::size_t begin, std::size_t end) {
      double largest_here = largest_sq.load(std::memory_order_relaxed);
      visit(P, spacing, begin, end, [&](const Point3& p, std::size_t face) {
        if(face < surface_faces && surface.squared_distance_to_face(face, p) <= largest_here) return;
        largest_here = std::max(largest_here, surface.squared_distance(p, largest_here));
      });
      double seen = largest_sq.load(std::memory_order_relaxed);
      while(largest_here > seen && !largest_sq.compare_exchange_weak(seen, largest_here, std::memory_order_relaxed)) {}
    });
    return std::sqrt(largest_sq.load());
  }

private:
  static constexpr std::size_t faces_per_part = 256;
  static constexpr unsigned vertex_bit(int m) { return 1u << m; }      // the corner c[m] is this face's
  static constexpr unsigned edge_bit(int m) { return 8u << m; }        // the edge c[m] c[m + 1] is this face's

  // The edge c[m] c[m + 1], from its lower vertex: CGAL steps along an edge of a mesh built in this
  // vertex order from there.
  static std::pair<Index, Index> edge(const std::array<Index, 3>& c, int m)
  {
    const Index a = c[std::size_t(m)], b = c[std::size_t(m + 1) % 3];
    return {std::min(a, b), std::max(a, b)};
  }

  std::vector<std::array<Index, 3>> m_faces;  // in the order of their samples
  std::vector<Index> m_face_indices;          // of each, in the mesh's triangles
  std::vector<unsigned char> m_owned;         // of each face: vertex_bit()s and edge_bit()s
};

/// Calls visit(point) for the grid samples (Grid_samples) of the faces of (t, P) at `spacing`.
template <typename Visit>
void for_each_grid_sample(const Mesh_topology& t, const Positions& P, double spacing, const Visit& visit)
{
  const Grid_samples samples(t, P);
  samples.visit(P, spacing, 0, samples.num_faces(), [&](const Point3& p, std::size_t) { visit(p); });
}

/// How many points for_each_grid_sample() visits, without visiting them.
inline double grid_sample_count(const Mesh_topology& t, const Positions& P, double spacing)
{
  return Grid_samples(t, P).count(P, spacing);
}

/// Grid_samples::bounded_spacing() of (t, P).
inline double bounded_grid_spacing(const Mesh_topology& t, const Positions& P, double spacing)
{
  return Grid_samples(t, P).bounded_spacing(P, spacing);
}

/// The largest distance from a grid sample of (t, P) to the surface, at `spacing`.
inline double sampled_one_sided_distance(const Mesh_topology& t, const Positions& P, double spacing,
                                         const Surface_distance& surface, bool parallel = false)
{
  return Grid_samples(t, P).largest_distance(P, spacing, surface, parallel);
}

} // namespace internal
} // namespace lapmesh

#endif // LAPMESH_INTERNAL_SURFACE_DISTANCE_H
