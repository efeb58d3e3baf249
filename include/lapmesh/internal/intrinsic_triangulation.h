// Internal: the intrinsic Delaunay triangulation of a triangle mesh, from edge lengths only.
//
// The mesh's faces are kept as an abstract triangulation (3 vertex indices per face, in the
// face's orientation) with a length per halfedge; positions are read once, for the initial
// lengths. Flipping an edge replaces the diagonal of the quad formed by its two triangles
// with the other diagonal, whose length comes from laying the two triangles out in the plane:
// the surface (a cone metric) is unchanged, only its triangulation. Flipping every interior
// edge whose opposite angles sum to more than pi (cot alpha + cot beta < 0) ends in the
// intrinsic Delaunay triangulation, on which every cotangent weight is >= 0 (Bobenko and
// Springborn 2007; Sharp and Crane 2020 for the nonmanifold and mollified setting).
//
// Mollification (Sharp and Crane 2020): every length is raised by the smallest epsilon >= 0
// that makes each triangle satisfy l_i + l_j >= l_k + delta, so that zero-area and
// near-degenerate triangles get finite angles; delta is small against the mean edge length.
//
// Conventions as internal/topology.h: halfedge h = 3f + a of face f runs from the vertex of
// corner a to the vertex of corner a+1 (mod 3), and is opposite corner a+2 (mod 3).
#ifndef LAPMESH_INTERNAL_INTRINSIC_TRIANGULATION_H
#define LAPMESH_INTERNAL_INTRINSIC_TRIANGULATION_H

#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/row_sort.h>
#include <lapmesh/internal/topology.h>
#include <lapmesh/types.h>

#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace lapmesh {
namespace internal {

/// The area of a triangle with side lengths a, b, c (Kahan's stable form of Heron's
/// formula); 0 when the lengths violate the triangle inequality.
inline double triangle_area_from_lengths(double a, double b, double c)
{
  if(a < b) std::swap(a, b);
  if(a < c) std::swap(a, c);
  if(b < c) std::swap(b, c);  // a >= b >= c
  const double p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
  return p > 0 ? 0.25 * std::sqrt(p) : 0.0;
}

/// What building the intrinsic Delaunay triangulation did.
struct Intrinsic_delaunay_stats
{
  long long flips = 0;          ///< edge flips performed
  double mollification = 0;     ///< epsilon added to every edge length
  long long non_delaunay_before = 0;  ///< interior edges with cot alpha + cot beta < 0 at the start
};

class Intrinsic_triangulation
{
public:
  /// The triangulation of `t` with the edge lengths of the positions `P`: the faces of `t`
  /// themselves on a closed manifold mesh, else its tufted cover (every face twice, front
  /// and back, the copies glued so that every edge has exactly two faces: a boundary edge
  /// joins a face's two sides, the faces around a non-manifold edge are glued in their
  /// angular order around it). The cover is closed, so every edge can be flipped; operators
  /// of the cover count every face twice (sheets() == 2).
  template <typename Positions>
  Intrinsic_triangulation(const Mesh_topology& t, const Positions& P)
    : m_num_vertices(t.num_vertices), m_sheets(t.manifold && t.num_boundary_edges == 0 ? 1 : 2)
  {
    const std::size_t front = t.triangles.size();
    m_tri.resize(m_sheets * front);
    std::copy(t.triangles.begin(), t.triangles.end(), m_tri.begin());
    if(m_sheets == 2)
      for(std::size_t f = 0; f < front / 3; ++f) {  // the back of (a, b, c) is (a, c, b)
        m_tri[front + 3 * f] = t.triangles[3 * f];
        m_tri[front + 3 * f + 1] = t.triangles[3 * f + 2];
        m_tri[front + 3 * f + 2] = t.triangles[3 * f + 1];
      }
    m_twin.assign(m_tri.size(), -1);
    m_length.resize(m_tri.size());
    for(std::size_t h = 0; h < m_tri.size(); ++h) {
      const Index a = m_tri[h], b = m_tri[next_of(Index(h))];
      m_length[h] = (P.row(a) - P.row(b)).norm();
    }
    auto glue = [&](Index h, Index g) {
      m_twin[h] = g;
      m_twin[g] = h;
    };
    // Twins through the topology's slots: slot (i, j) knows the corners opposite i->j and j->i.
    std::vector<char> fan(m_sheets == 2 && !t.manifold ? t.inner.size() : 0, 0);
    for(Index s : t.fan_slot) fan[s] = 1;
    for(Index i = 0; i < t.num_vertices; ++i)
      for(Index s = t.outer[i]; s < t.outer[i + 1]; ++s) {
        const auto& c = t.slot_corners[s];
        if(t.inner[s] <= i || (!fan.empty() && fan[s])) continue;  // each edge once; fans below
        if(c[0] >= 0 && c[1] >= 0) {
          const Index h = halfedge_opposite(c[0]), g = halfedge_opposite(c[1]);
          glue(h, g);
          if(m_sheets == 2) glue(back_of(h), back_of(g));
        } else if(m_sheets == 2) {  // a boundary edge: the face's front meets its back
          const Index h = halfedge_opposite(c[0] >= 0 ? c[0] : c[1]);
          glue(h, back_of(h));
        }
      }
    for(std::size_t e = 0; e + 1 < t.fan_begin.size(); ++e)
      glue_fan(P, &t.fan_corners[t.fan_begin[e]], &t.fan_corners[t.fan_begin[e + 1]]);
    update_areas();
  }

  Index num_vertices() const { return m_num_vertices; }
  /// 1 for the faces of the mesh, 2 for its tufted cover (each face twice).
  int sheets() const { return m_sheets; }
  Index num_faces() const { return Index(m_tri.size() / 3); }
  const std::vector<Index>& triangles() const { return m_tri; }
  const std::vector<Index>& twins() const { return m_twin; }
  const std::vector<double>& lengths() const { return m_length; }

  /// Mean length over the edges (each interior edge once).
  double mean_edge_length() const
  {
    double sum = 0;
    std::size_t count = 0;
    for(std::size_t h = 0; h < m_length.size(); ++h)
      if(m_twin[h] < Index(h)) {  // boundary halfedges, and the first of each twin pair
        sum += m_length[h];
        ++count;
      }
    return count ? sum / double(count) : 0.0;
  }

  /// Raises every length by the smallest epsilon >= 0 after which every triangle has
  /// l_i + l_j - l_k >= delta; returns epsilon.
  double mollify(double delta)
  {
    double epsilon = 0;
    for(Index f = 0; f < num_faces(); ++f) {
      const double* l = &m_length[3 * std::size_t(f)];
      const double slack = std::min({l[0] + l[1] - l[2], l[1] + l[2] - l[0], l[2] + l[0] - l[1]});
      epsilon = std::max(epsilon, delta - slack);
    }
    if(epsilon > 0) {
      for(double& l : m_length) l += epsilon;
      update_areas();
    }
    return std::max(epsilon, 0.0);
  }

  /// cot of the angle at corner c (from the lengths of its face).
  double corner_cotangent(Index c) const { return corner_cotangent(c, face_area(c / 3)); }

  /// The same, given the area of c's face (one area for the three corners of a face).
  double corner_cotangent(Index c, double area) const
  {
    const Index f = c / 3;
    const double opposite = m_length[halfedge_opposite(c)];
    const double b = m_length[3 * f + (c % 3)], d = m_length[3 * f + (c % 3 + 2) % 3];  // the two sides at c
    return (b * b + d * d - opposite * opposite) / (4.0 * area);
  }

  /// The area of face f from its lengths (kept with them: the Delaunay test needs two per edge).
  double face_area(Index f) const { return m_area[f]; }

  /// cot alpha + cot beta of the interior edge of halfedge h (alpha, beta the opposite angles).
  double cotangent_sum(Index h) const
  {
    return corner_cotangent(corner_opposite(h)) + corner_cotangent(corner_opposite(m_twin[h]));
  }

  /// Flips interior edges until every one is Delaunay (cot alpha + cot beta >= -tolerance).
  Intrinsic_delaunay_stats flip_to_delaunay(double tolerance = 1e-12)
  {
    Intrinsic_delaunay_stats stats;
    std::vector<Index> queue;
    std::vector<char> queued(m_tri.size(), 0);
    // Only the edges that are not Delaunay now: a Delaunay edge can become non-Delaunay only
    // when a neighbouring face changes, and every flip queues the four edges around it.
    for(Index h = 0; h < Index(m_tri.size()); ++h)
      if(m_twin[h] > h && h / 3 != m_twin[h] / 3 && cotangent_sum(h) < -tolerance) {
        ++stats.non_delaunay_before;
        queue.push_back(h);
        queued[h] = 1;
      }
    // In exact arithmetic each flip decreases a finite energy; the cap guards round-off cycles.
    const long long max_flips = 100 * (long long)m_tri.size() + 1000;
    while(!queue.empty() && stats.flips < max_flips) {
      const Index h = queue.back();
      queue.pop_back();
      queued[h] = 0;
      const Index g = m_twin[h];
      // A boundary edge, or a face glued to itself. A new diagonal may be a loop (both
      // triangles opposite the same vertex, as across a boundary edge of the tufted cover):
      // it is a valid intrinsic edge that adds nothing to L x.
      if(g < 0 || h / 3 == g / 3 || cotangent_sum(h) >= -tolerance) continue;
      flip(h);
      ++stats.flips;
      // The four outer edges of the new pair of triangles may have become non-Delaunay.
      for(Index f : {h / 3, g / 3})
        for(Index k = 0; k < 3; ++k) {
          Index e = 3 * f + k;
          if(m_twin[e] < 0) continue;
          if(m_twin[e] < e) e = m_twin[e];
          if(!queued[e]) {
            queued[e] = 1;
            queue.push_back(e);
          }
        }
    }
    return stats;
  }

  /// True when every interior edge satisfies cot alpha + cot beta >= -tolerance.
  bool is_delaunay(double tolerance = 1e-12) const
  {
    for(Index h = 0; h < Index(m_tri.size()); ++h)
      if(m_twin[h] > h && cotangent_sum(h) < -tolerance) return false;
    return true;
  }

  static Index next_of(Index h) { return h % 3 == 2 ? h - 2 : h + 1; }
  static Index prev_of(Index h) { return h % 3 == 0 ? h + 2 : h - 1; }
  /// The halfedge opposite corner c, and the corner opposite halfedge h.
  static Index halfedge_opposite(Index c) { return next_of(c); }
  static Index corner_opposite(Index h) { return prev_of(h); }

private:
  void update_areas()
  {
    m_area.resize(m_tri.size() / 3);
    for(std::size_t f = 0; f < m_area.size(); ++f)
      m_area[f] = triangle_area_from_lengths(m_length[3 * f], m_length[3 * f + 1], m_length[3 * f + 2]);
  }

  /// The halfedge of the back copy of a front face that runs the other way along h's edge.
  Index back_of(Index h) const
  {
    const Index front = Index(m_tri.size() / 2);
    return front + 3 * (h / 3) + (2 - h % 3);
  }

  /// Glues the faces around one non-manifold edge u-v (u < v; the corners [first, last)
  /// are opposite its halfedges): sorted by the angle of their third vertex around the
  /// edge, the side of each face that looks towards the next one meets that one's side
  /// that looks back. The copy of a face that runs u->v is its side towards increasing angle.
  template <typename Positions>
  void glue_fan(const Positions& P, const Index* first, const Index* last)
  {
    const Index h0 = halfedge_opposite(*first);
    Index u = m_tri[h0], v = m_tri[next_of(h0)];
    if(u > v) std::swap(u, v);
    const Eigen::Vector3d pu = P.row(u), axis = (Eigen::Vector3d(P.row(v)) - pu).normalized();
    struct Side
    {
      double angle;
      Index up, down;  // the halfedges of the face's copies running u->v and v->u
    };
    std::vector<Side> sides;
    Eigen::Vector3d x_axis = Eigen::Vector3d::Zero();
    for(const Index* c = first; c != last; ++c) {
      const Index h = halfedge_opposite(*c), b = back_of(h);
      Eigen::Vector3d r = Eigen::Vector3d(P.row(m_tri[*c])) - pu;
      r -= r.dot(axis) * axis;
      if(x_axis.squaredNorm() == 0 && r.squaredNorm() > 0) x_axis = r.normalized();
      const Eigen::Vector3d y_axis = axis.cross(x_axis);
      const double angle = std::atan2(r.dot(y_axis), r.dot(x_axis));
      sides.push_back(m_tri[h] == u ? Side{angle, h, b} : Side{angle, b, h});
    }
    std::stable_sort(sides.begin(), sides.end(), [](const Side& a, const Side& b) { return a.angle < b.angle; });
    for(std::size_t k = 0; k < sides.size(); ++k) {
      const Index up = sides[k].up, down = sides[(k + 1) % sides.size()].down;
      m_twin[up] = down;
      m_twin[down] = up;
    }
  }

  /// Replaces the edge of h (a->b in face (a, b, c), twin b->a in face (b, a, d)) by c-d:
  /// the faces become (d, b, c) and (c, a, d), in the same orientation.
  void flip(Index h)
  {
    const Index g = m_twin[h];
    const Index f0 = h / 3, f1 = g / 3;
    const Index hb = next_of(h), hc = prev_of(h);  // b->c, c->a
    const Index ga = next_of(g), gd = prev_of(g);  // a->d, d->b
    const Index a = m_tri[h], b = m_tri[hb], c = m_tri[hc], d = m_tri[gd];
    const double l_ab = m_length[h], l_bc = m_length[hb], l_ca = m_length[hc], l_ad = m_length[ga],
                 l_db = m_length[gd];
    // Layout: a at the origin, b on the x axis, c above it, d below it.
    const double cx = (l_ab * l_ab + l_ca * l_ca - l_bc * l_bc) / (2 * l_ab);
    const double cy = 2 * m_area[f0] / l_ab;
    const double dx = (l_ab * l_ab + l_ad * l_ad - l_db * l_db) / (2 * l_ab);
    const double dy = -2 * m_area[f1] / l_ab;
    const double l_cd = std::hypot(cx - dx, cy - dy);
    // f0 = (d, b, c): halfedges d->b, b->c, c->d; f1 = (c, a, d): c->a, a->d, d->c.
    const Index n0 = 3 * f0, n1 = 3 * f1;
    // Where the four outer halfedges go. An outer edge may be glued to another outer edge of
    // the same quad (a face of the tufted cover whose two boundary edges meet at a vertex):
    // its twin moves with it.
    auto moved = [&](Index old) {
      return old == hb ? n0 + 1 : old == hc ? n1 : old == ga ? n1 + 1 : old == gd ? n0 : old;
    };
    const Index t_bc = moved(m_twin[hb]), t_ca = moved(m_twin[hc]), t_ad = moved(m_twin[ga]),
                t_db = moved(m_twin[gd]);

    m_tri[n0] = d; m_tri[n0 + 1] = b; m_tri[n0 + 2] = c;
    m_tri[n1] = c; m_tri[n1 + 1] = a; m_tri[n1 + 2] = d;
    auto set = [&](Index half, double length, Index twin) {
      m_length[half] = length;
      m_twin[half] = twin;
      if(twin >= 0) m_twin[twin] = half;
    };
    set(n0, l_db, t_db);
    set(n0 + 1, l_bc, t_bc);
    set(n1, l_ca, t_ca);
    set(n1 + 1, l_ad, t_ad);
    m_length[n0 + 2] = m_length[n1 + 2] = l_cd;
    m_twin[n0 + 2] = n1 + 2;
    m_twin[n1 + 2] = n0 + 2;
    m_area[f0] = triangle_area_from_lengths(l_db, l_bc, l_cd);
    m_area[f1] = triangle_area_from_lengths(l_ca, l_ad, l_cd);
  }

  Index m_num_vertices;
  int m_sheets;
  std::vector<Index> m_tri;      // 3 vertices per face
  std::vector<Index> m_twin;     // per halfedge, -1 on the boundary
  std::vector<double> m_length;  // per halfedge (twins agree)
  std::vector<double> m_area;    // per face, from its lengths
};

/// The intrinsic Delaunay triangulation of the positions P on the topology t, its lengths
/// mollified by `delta_factor` x the mean edge length first.
inline Intrinsic_triangulation intrinsic_delaunay_triangulation(const Mesh_topology& t, const Vertex_vectors& P,
                                                                double delta_factor,
                                                                Intrinsic_delaunay_stats* stats = nullptr)
{
  Intrinsic_triangulation it(t, P);
  const double epsilon = it.mollify(delta_factor * it.mean_edge_length());
  Intrinsic_delaunay_stats s = it.flip_to_delaunay();
  s.mollification = epsilon;
  if(stats) *stats = s;
  return it;
}

/// The cotangents and lumped area shares of the three corners of face f.
inline void intrinsic_face_corners(const Intrinsic_triangulation& it, Vertex_area area, Index f, double cot[3],
                                   double share[3])
{
  const double face_area = it.face_area(f);
  double l2[3];
  for(Index a = 0; a < 3; ++a) {
    cot[a] = it.corner_cotangent(3 * f + a, face_area);
    const double l = it.lengths()[Intrinsic_triangulation::halfedge_opposite(3 * f + a)];
    l2[a] = l * l;  // the squared side opposite corner a
  }
  lumped_corner_areas(area, face_area, cot, l2, share);
}

/// The corner cotangents and the vertex areas of an intrinsic triangulation without flips of the
/// manifold mesh `t`: its triangles are t's, in t's corner order.
inline void intrinsic_corner_geometry(const Mesh_topology& t, const Intrinsic_triangulation& it, Vertex_area area,
                                      bool parallel, Corner_geometry& g)
{
  const Index m = t.num_faces;
  g.cot.resize(3 * std::size_t(m));
  with_corner_sums_for(parallel, [&](auto scatter) {
    Corner_value_sums<decltype(scatter)::value, 1> area_sums(t);
    for_each_index(m, parallel, [&](Index f) {
      double share[3];
      intrinsic_face_corners(it, area, f, &g.cot[3 * std::size_t(f)], share);
      area_sums.add_face(f, share);
    });
    g.vertex_area = area_sums.finish(t, parallel);
  });
}

/// The cotangent stiffness and the lumped mass of an intrinsic triangulation, per sheet (a
/// tufted cover's are halved). The pattern is that of its edges, which after flips may join
/// vertices that share no mesh edge; two intrinsic edges between the same vertices add up.
/// Written in compressed columns directly: column i holds one entry per halfedge leaving i
/// (the weight of its edge, from the corners opposite it and its twin) and the diagonal.
inline void assemble_intrinsic_pencil(const Intrinsic_triangulation& it, Vertex_area area,
                                      Eigen::SparseMatrix<double>& stiffness, Eigen::VectorXd& mass)
{
  using T = Intrinsic_triangulation;
  const Index n = it.num_vertices();
  const std::vector<Index>& tri = it.triangles();
  const std::vector<Index>& twin = it.twins();
  const Index halfedges = Index(tri.size());
  const double per_sheet = 1.0 / it.sheets();
  std::vector<double> cot(tri.size());
  mass = Eigen::VectorXd::Zero(n);
  for(Index f = 0; f < it.num_faces(); ++f) {
    double share[3];
    intrinsic_face_corners(it, area, f, &cot[3 * std::size_t(f)], share);
    for(Index a = 0; a < 3; ++a) mass[tri[3 * f + a]] += per_sheet * share[a];
  }

  // A loop edge joins a vertex to itself: no term in L x. An edge without a twin (none in a
  // closed cover, kept for safety) is entered in both of its columns from its one halfedge.
  std::vector<Index> start(std::size_t(n) + 1, 1);  // the diagonal of every column
  start[0] = 0;
  for(Index h = 0; h < halfedges; ++h) {
    const Index i = tri[h], j = tri[T::next_of(h)];
    if(i == j) continue;
    ++start[i + 1];
    if(twin[h] < 0) ++start[j + 1];
  }
  for(Index i = 0; i < n; ++i) start[i + 1] += start[i];
  stiffness.resize(n, n);
  stiffness.resizeNonZeros(start[n]);
  Index* row = stiffness.innerIndexPtr();
  double* value = stiffness.valuePtr();
  std::vector<Index> fill(start.begin(), start.end() - 1);
  for(Index i = 0; i < n; ++i) {
    row[fill[i]] = i;
    value[fill[i]++] = 0;
  }
  for(Index h = 0; h < halfedges; ++h) {
    const Index i = tri[h], j = tri[T::next_of(h)];
    if(i == j) continue;
    const double w = 0.5 * per_sheet *
                     (cot[T::corner_opposite(h)] + (twin[h] >= 0 ? cot[T::corner_opposite(twin[h])] : 0.0));
    row[fill[i]] = j;
    value[fill[i]++] = w;
    if(twin[h] < 0) {
      row[fill[j]] = i;
      value[fill[j]++] = w;
    }
  }
  // Sort each column by row, merge repeated rows, set the diagonal to minus the column's
  // off-diagonal sum, and pack the columns to the front.
  Index* outer = stiffness.outerIndexPtr();
  Index out = 0;
  for(Index i = 0; i < n; ++i) {
    const Index first = start[i], last = start[i + 1];
    sort_row(row + first, std::size_t(last - first), value + first);
    outer[i] = out;
    double off_diagonal = 0;
    Index diagonal = -1;
    for(Index k = first; k < last; ++k) {
      if(row[k] != i) off_diagonal += value[k];
      if(out > outer[i] && row[out - 1] == row[k]) {
        value[out - 1] += value[k];
      } else {
        if(row[k] == i) diagonal = out;
        row[out] = row[k];
        value[out++] = value[k];
      }
    }
    value[diagonal] = -off_diagonal;
  }
  outer[n] = out;
  stiffness.resizeNonZeros(out);
}

/// The sum of the corner angles at each vertex (the cone angle, which flips do not change),
/// per sheet.
inline Eigen::VectorXd vertex_angle_sums(const Intrinsic_triangulation& it)
{
  Eigen::VectorXd sums = Eigen::VectorXd::Zero(it.num_vertices());
  const std::vector<double>& len = it.lengths();
  for(Index f = 0; f < it.num_faces(); ++f) {
    // The angle opposite the longest side is pi minus the other two, so that the angles of
    // every face sum to pi and Gauss–Bonnet holds to round-off.
    const double* l = &len[3 * std::size_t(f)];
    const double opposite[3] = {l[1], l[2], l[0]};  // the side opposite corner a is halfedge a+1
    const double double_area = 2 * it.face_area(f);
    int largest = 0;
    for(int a = 1; a < 3; ++a)
      if(opposite[a] > opposite[largest]) largest = a;
    double angle[3];
    for(int a = 0; a < 3; ++a) {
      if(a == largest) continue;
      const double b = l[a], d = l[(a + 2) % 3];  // the two sides at corner a
      angle[a] = std::atan2(2 * double_area, b * b + d * d - opposite[a] * opposite[a]);
    }
    angle[largest] = M_PI - angle[(largest + 1) % 3] - angle[(largest + 2) % 3];
    for(int a = 0; a < 3; ++a) sums[it.triangles()[3 * f + a]] += angle[a];
  }
  return sums / it.sheets();
}

} // namespace internal
} // namespace lapmesh

#endif
