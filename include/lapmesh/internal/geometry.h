// Internal: per-corner geometry of a triangle mesh and its sums at the vertices.
//
// One streaming pass over the faces computes, for every corner, the cotangent of its angle and
// its share of the vertex area, summed at its vertex (and, on request, the angle and the face
// normal, summed likewise). This is the single canonical place where cotangent weights and
// vertex areas are defined (doc/conventions.md); every operator and curvature of lapmesh is
// built on these.
#ifndef LAPMESH_INTERNAL_GEOMETRY_H
#define LAPMESH_INTERNAL_GEOMETRY_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/parallel.h>
#include <lapmesh/internal/topology.h>
#include <lapmesh/parameters.h>
#include <lapmesh/types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>


namespace lapmesh {
namespace internal {

/// n x 3 vertex positions; row-major so that a vertex's coordinates are contiguous.
using Positions = Vertex_vectors;

using Point3 = Eigen::Vector3d;

struct Box3
{
  Point3 lo = Point3::Constant(std::numeric_limits<double>::infinity());
  Point3 hi = Point3::Constant(-std::numeric_limits<double>::infinity());

  void extend(const Point3& p)
  {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void extend(const Box3& b)
  {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  Point3 center() const { return 0.5 * (lo + hi); }
  double squared_distance(const Point3& p) const
  {
    return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).squaredNorm();
  }
};

// The position of a point of `box` along a Morton curve of 2^21 cells a side.
inline std::uint64_t morton_code(const Point3& p, const Box3& box)
{
  const auto spread = [](std::uint64_t x) {  // the 21 low bits of x to every third bit
    x &= 0x1fffff;
    x = (x | x << 32) & 0x1f00000000ffffULL;
    x = (x | x << 16) & 0x1f0000ff0000ffULL;
    x = (x | x << 8) & 0x100f00f00f00f00fULL;
    x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
    x = (x | x << 2) & 0x1249249249249249ULL;
    return x;
  };
  std::uint64_t code = 0;
  for(int k = 0; k < 3; ++k) {
    const double extent = box.hi[k] - box.lo[k];
    const double u = extent > 0 ? (p[k] - box.lo[k]) / extent : 0.0;
    code |= spread(std::uint64_t((u > 0 ? std::min(u, 1.0) : 0.0) * 2097151.0)) << k;  // NaN: cell 0
  }
  return code;
}

/// The i-th of the vectors held three values each, side by side, in `values`.
inline Eigen::Map<const Eigen::Vector3d> vector3_at(const Working_array<double>& values, Index i)
{
  return Eigen::Map<const Eigen::Vector3d>(&values[3 * std::size_t(i)]);
}

/// The corner cotangents of a mesh and the per-vertex sums of its corners' geometry.
struct Corner_geometry
{
  /// cot of the corner angle, 3 per face (want_cotangents). A working array: resize() leaves it
  /// uninitialised, which saves a zeroing pass that the face pass overwrites anyway.
  Working_array<double> cot;
  /// Where the cotangents go instead when not null (3 per face; `cot` then stays empty): memory
  /// that a caller lends for the call, such as a factor's values that nothing reads until a
  /// factorisation rewrites them.
  double* lent_cot = nullptr;
  const double* cot_values() const { return lent_cot ? lent_cot : cot.data(); }
  Eigen::VectorXd vertex_area;  ///< A_i, the sum of the shares of i's corners
  /// The sum of i's corner angles (want_angles). This sum and the next never leave a call as
  /// they are, so they live in working arrays, whose pages the next call finds mapped.
  Working_array<double> angle_sum;
  /// The sum of the cross products (2 * area * unit normal) of i's faces, three values per
  /// vertex (want_face_normals).
  Working_array<double> face_normal_sum;

  /// face_normal_sum of vertex i.
  Eigen::Map<const Eigen::Vector3d> face_normal_sum_of(Index i) const { return vector3_at(face_normal_sum, i); }
};

struct Corner_request
{
  Vertex_area area = Vertex_area::barycentric;
  bool want_angles = false;
  bool want_face_normals = false;
  bool want_cotangents = true;
};

/// Per-vertex sums of values that a pass over the faces produces per corner. Serially
/// (`Scatter`) the pass adds each value to its vertex as it goes, so no per-corner array is
/// held; in parallel the values are kept per corner and each vertex gathers its own (no two
/// threads write one sum). Both add a vertex's values in ascending corner order, the order of
/// its corner list (sort_corners_by_vertex()), so the sums are the same, bitwise. `PerFace`: one
/// value per face, added to each of its three vertices. `Sums`: an Eigen array for sums that
/// leave the call in a result, or a Working_array<double> (Width values per vertex) for those
/// that do not.
template <bool Scatter, int Width, bool PerFace = false,
          typename Sums = std::conditional_t<Width == 1, Eigen::VectorXd, Positions>>
class Corner_value_sums
{
  static constexpr bool in_working_array = std::is_same<Sums, Working_array<double>>::value;

  /// Sums for `vertices` vertices, not initialised.
  static Sums sized_for(Index vertices)
  {
    if constexpr(in_working_array)
      return Sums(std::size_t(Width) * std::size_t(vertices));
    else
      return Sums(vertices, Width);
  }

public:
  /// `wanted` false: nothing is allocated and add_face() must not be called.
  explicit Corner_value_sums(const Mesh_topology& t, bool wanted = true) : m_tri(t.triangles.data())
  {
    if(!wanted) return;
    if constexpr(Scatter) {
      m_sums = sized_for(t.num_vertices);
      if constexpr(!in_working_array) prepare_for_writing(m_sums);
      std::fill_n(m_sums.data(), std::size_t(Width) * std::size_t(t.num_vertices), 0.0);
      m_out = m_sums.data();
    } else {
      m_values.resize(std::size_t(Width) * (PerFace ? 1 : 3) * std::size_t(t.num_faces));
      m_out = m_values.data();
    }
  }
  /// Fetches the sums of face f's vertices ahead of add_face().
  void prefetch_face(Index f) const
  {
    if constexpr(Scatter)
      for(Index a = 0; a < 3; ++a) prefetch(m_out + std::size_t(Width) * std::size_t(m_tri[3 * f + a]));
  }
  /// Adds the values of face f's corners (Width doubles each, side by side), or with
  /// PerFace the face's value to each corner.
  void add_face(Index f, const double* values)
  {
    if constexpr(Scatter) {
      for(Index a = 0; a < 3; ++a) {
        double* sum = m_out + std::size_t(Width) * std::size_t(m_tri[3 * f + a]);
        const double* value = values + (PerFace ? 0 : Width * a);
        for(int k = 0; k < Width; ++k) sum[k] += value[k];
      }
    } else {
      constexpr std::size_t count = std::size_t(Width) * (PerFace ? 1 : 3);
      std::copy(values, values + count, m_out + count * std::size_t(f));
    }
  }
  /// The sums (once, after the pass); the per-corner values, if any, are released.
  Sums finish(const Mesh_topology& t, bool parallel)
  {
    if constexpr(Scatter) {
      return std::move(m_sums);
    } else {
      Sums out = sized_for(t.num_vertices);
      if constexpr(!in_working_array) prepare_for_writing(out, parallel);
      for_each_index(t.num_vertices, parallel, [&](Index v) {
        double s[Width] = {};
        for(Index k = t.corner_begin[v]; k < t.corner_begin[v + 1]; ++k) {
          const Index c = t.vertex_corners[k];
          const double* value = &m_values[std::size_t(Width) * std::size_t(PerFace ? c / 3 : c)];
          for(int j = 0; j < Width; ++j) s[j] += value[j];
        }
        std::copy(s, s + Width, out.data() + std::size_t(Width) * std::size_t(v));
      });
      Working_array<double>().swap(m_values);
      return out;
    }
  }

private:
  const Index* m_tri;
  double* m_out = nullptr;
  Sums m_sums;                     // Scatter
  Working_array<double> m_values;  // not Scatter
};

/// Calls pass(std::bool_constant<Scatter>()) with Scatter = !parallel: a pass over the faces
/// compiled once per way of summing (Corner_value_sums), so that neither branches per corner.
template <typename Pass>
void with_corner_sums_for(bool parallel, const Pass& pass)
{
  if(parallel)
    pass(std::false_type());
  else
    pass(std::true_type());
}

/// The three corners' shares of a face's area for the lumped mass of kind `area`, from the
/// corner cotangents and the squared lengths of the sides opposite each corner: a third each
/// (barycentric), the circumcentric (Voronoi) shares, or Meyer et al.'s mixed shares.
inline void lumped_corner_areas(Vertex_area area, double face_area, const double cot[3], const double l2[3],
                                double out[3])
{
  const bool obtuse = cot[0] < 0 || cot[1] < 0 || cot[2] < 0;
  if(area == Vertex_area::barycentric) {
    out[0] = out[1] = out[2] = face_area / 3.0;
  } else if(area == Vertex_area::mixed && obtuse) {
    for(int a = 0; a < 3; ++a) out[a] = cot[a] < 0 ? 0.5 * face_area : 0.25 * face_area;
  } else {
    // Voronoi share of corner a: 1/8 of (|edge|^2 cot(opposite angle)) over its two edges.
    out[0] = 0.125 * (l2[2] * cot[2] + l2[1] * cot[1]);
    out[1] = 0.125 * (l2[0] * cot[0] + l2[2] * cot[2]);
    out[2] = 0.125 * (l2[1] * cot[1] + l2[0] * cot[0]);
  }
}

inline void throw_degenerate_face(Index f)
{
  throw Mesh_error("face " + std::to_string(f) +
                     " has zero area (its angles and cotangent weights are undefined; the "
                     "intrinsic-delaunay Laplacian takes it)",
                   Mesh_error::Element::face, f);
}

/// Throws the Mesh_error of a face that face_defect() refused.
inline void throw_face_defect(Index f, Face_defect d)
{
  if(d == Face_defect::zero_area) throw_degenerate_face(f);
  throw Mesh_error(out_of_range_message(f, d), Mesh_error::Element::face, f);
}

/// The three corner positions of face f.
inline std::array<Eigen::Vector3d, 3> face_points(const Mesh_topology& t, const Positions& P, Index f)
{
  return {P.row(t.triangles[3 * f]).transpose(), P.row(t.triangles[3 * f + 1]).transpose(),
          P.row(t.triangles[3 * f + 2]).transpose()};
}

/// Sets `cross` to (p1 - p0) x (p2 - p0) of face f (twice its area times its unit normal) and
/// says whether face_in_range() takes the face: the test of compute_corner_geometry().
inline bool face_cross_in_range(const Mesh_topology& t, const Positions& P, Index f, Eigen::Vector3d& cross)
{
  const auto [p0, p1, p2] = face_points(t, P, f);
  cross = (p1 - p0).cross(p2 - p0);
  const double longest = std::max({(p1 - p0).squaredNorm(), (p2 - p1).squaredNorm(), (p0 - p2).squaredNorm()});
  return face_in_range(longest, cross_norm(cross.x(), cross.y(), cross.z()));
}

/// What is wrong with face f, which face_in_range() refused: zero area, or out of range.
inline Face_defect refused_face_defect(const Mesh_topology& t, const Positions& P, Index f)
{
  const auto [p0, p1, p2] = face_points(t, P, f);
  const Face_defect d = face_defect(p0.data(), p1.data(), p2.data());
  return d == Face_defect::none ? Face_defect::zero_area : d;
}

/// Throws the Mesh_error of face f, which face_in_range() refused.
inline void throw_refused_face(const Mesh_topology& t, const Positions& P, Index f)
{
  throw_face_defect(f, refused_face_defect(t, P, f));
}

/// Throws the Mesh_error of the first face that compute_corner_geometry() would refuse (zero
/// area, or out of the representable range), without computing anything else.
inline void require_faces_in_range(const Mesh_topology& t, const Positions& P, bool parallel)
{
  First_index<Index> first_refused;
  for_each_index(t.num_faces, parallel, [&](Index f) {
    Eigen::Vector3d cross;
    if(!face_cross_in_range(t, P, f, cross)) first_refused.record(f);
  });
  if(!first_refused.empty()) throw_refused_face(t, P, first_refused.get());
}

/// Fills `g` from the positions. Throws Mesh_error naming the first degenerate face.
inline void compute_corner_geometry(const Mesh_topology& t, const Positions& P,
                                    const Corner_request& request, bool parallel,
                                    Corner_geometry& g)
{
  const Index m = t.num_faces;
  if(request.want_cotangents && !g.lent_cot) g.cot.resize(3 * std::size_t(m));
  double* const cot_out = g.lent_cot ? g.lent_cot : g.cot.data();
  // How many faces ahead the positions of a face's corners are prefetched.
  constexpr Index prefetch_distance = 16;
  const Index* tri = t.triangles.data();

  with_corner_sums_for(parallel, [&](auto scatter) {
    constexpr bool Scatter = decltype(scatter)::value;
    Corner_value_sums<Scatter, 1> area_sums(t);
    Corner_value_sums<Scatter, 1, false, Working_array<double>> angle_sums(t, request.want_angles);
    Corner_value_sums<Scatter, 3, true, Working_array<double>> normal_sums(t, request.want_face_normals);
    First_index<Index> first_degenerate;
    for_each_index(m, parallel, [&](Index f) {
      if(f + prefetch_distance < m) {
        for(Index a = 0; a < 3; ++a) prefetch(&P(tri[3 * (f + prefetch_distance) + a], 0));
        area_sums.prefetch_face(f + prefetch_distance);
        if(request.want_angles) angle_sums.prefetch_face(f + prefetch_distance);
        if(request.want_face_normals) normal_sums.prefetch_face(f + prefetch_distance);
      }
      const Eigen::Vector3d p0 = P.row(tri[3 * f]), p1 = P.row(tri[3 * f + 1]),
                            p2 = P.row(tri[3 * f + 2]);
      // e[a] is the edge opposite corner a.
      const Eigen::Vector3d e0 = p2 - p1, e1 = p0 - p2, e2 = p1 - p0;
      const Eigen::Vector3d cross = e2.cross(-e1);
      // Not cross.norm(): squaring the components overflows for edges beyond ~1e77 and
      // underflows below ~1e-77, well inside the range of representable squared lengths.
      const double dbl_area = cross_norm(cross.x(), cross.y(), cross.z());
      const double l0 = e0.squaredNorm(), l1 = e1.squaredNorm(), l2 = e2.squaredNorm();
      const double dot0 = -e2.dot(e1), dot1 = -e0.dot(e2), dot2 = -e1.dot(e0);

      if(!face_in_range(std::max(l0, std::max(l1, l2)), dbl_area)) {
        first_degenerate.record(f);
        return;
      }
      const double inv = 1.0 / dbl_area;
      const double cot[3] = {dot0 * inv, dot1 * inv, dot2 * inv};
      if(request.want_cotangents) std::copy(cot, cot + 3, cot_out + 3 * std::size_t(f));

      const double squared[3] = {l0, l1, l2};
      double share[3];
      lumped_corner_areas(request.area, 0.5 * dbl_area, cot, squared, share);
      area_sums.add_face(f, share);
      if(request.want_angles) {
        // The angle opposite the longest edge is pi minus the other two: one atan2 fewer,
        // and the three angles of every face sum to pi, which makes Gauss–Bonnet exact.
        double angle[3];
        const int largest = l0 >= l1 ? (l0 >= l2 ? 0 : 2) : (l1 >= l2 ? 1 : 2);
        const double dots[3] = {dot0, dot1, dot2};
        const int a1 = (largest + 1) % 3, a2 = (largest + 2) % 3;
        angle[a1] = std::atan2(dbl_area, dots[a1]);
        angle[a2] = std::atan2(dbl_area, dots[a2]);
        angle[largest] = M_PI - angle[a1] - angle[a2];
        angle_sums.add_face(f, angle);
      }
      if(request.want_face_normals) normal_sums.add_face(f, cross.data());
    });
    if(!first_degenerate.empty()) throw_refused_face(t, P, first_degenerate.get());
    g.vertex_area = area_sums.finish(t, parallel);
    if(request.want_angles) g.angle_sum = angle_sums.finish(t, parallel);
    if(request.want_face_normals) g.face_normal_sum = normal_sums.finish(t, parallel);
  });
}

/// The unit vector along a vertex's sum of incident face cross products; zero where the sum is
/// zero, not a number where it is not finite.
inline Eigen::Vector3d unit_vertex_normal(const Eigen::Vector3d& face_normal_sum)
{
  const double len = face_normal_sum.norm();
  return len == 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(face_normal_sum / len);
}

/// Area-weighted unit vertex normals from the sums of the incident face cross products, three
/// values per vertex (Corner_geometry::face_normal_sum).
inline Positions vertex_normals(const Working_array<double>& face_normal_sums, bool parallel)
{
  Positions normals(Index(face_normal_sums.size() / 3), 3);
  prepare_for_writing(normals, parallel);
  for_each_index(Index(normals.rows()), parallel, [&](Index v) {
    normals.row(v) = unit_vertex_normal(vector3_at(face_normal_sums, v)).transpose();
  });
  return normals;
}

/// vertex_normals() from the faces' cross products, which `face_cross(f, cross)` sets for face f;
/// a face for which it returns false adds nothing. For callers with their own rule for faces
/// that compute_corner_geometry() would refuse.
template <typename Face_cross>
Positions vertex_normals_of_faces(const Mesh_topology& t, bool parallel, Face_cross&& face_cross)
{
  Corner_value_sums<true, 3, true, Working_array<double>> sums(t);
  Eigen::Vector3d cross;
  for(Index f = 0; f < t.num_faces; ++f)
    if(face_cross(f, cross)) sums.add_face(f, cross.data());
  return vertex_normals(sums.finish(t, false), parallel);
}

/// Calls row(i, r) for every vertex i with r = (S X)_i = sum_j S_ij (x_j - x_i), for the
/// cotangent stiffness S = C, computed from the corners without a matrix: corner c at i gives
/// 1/2 (cot_r (x_q - x_i) + cot_q (x_r - x_i)).
template <typename RowSink>
void for_each_cotangent_laplacian_row(const Mesh_topology& t, const Corner_geometry& g, const Positions& P,
                                      bool parallel, const RowSink& row)
{
  const Index* tri = t.triangles.data();
  const double* cot = g.cot_values();
  const Index n = t.num_vertices;
  // The triangles and cotangents of a vertex's corners are fetched twice as far ahead as the
  // positions they name, which can only be read once the triangles have arrived.
  constexpr Index ahead = corner_prefetch_distance;
  for_each_index(n, parallel, [&](Index i) {
    if(i + 2 * ahead < n)
      for(Index k = t.corner_begin[i + 2 * ahead]; k < t.corner_begin[i + 2 * ahead + 1]; ++k) {
        prefetch(&tri[t.vertex_corners[k]]);
        prefetch(&cot[t.vertex_corners[k]]);
      }
    if(i + ahead < n)
      for(Index k = t.corner_begin[i + ahead]; k < t.corner_begin[i + ahead + 1]; ++k) {
        const Index c = t.vertex_corners[k];
        prefetch(&P(tri[next_corner(c)], 0));
        prefetch(&P(tri[prev_corner(c)], 0));
      }
    const Eigen::Vector3d xi = P.row(i);
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for(Index k = t.corner_begin[i]; k < t.corner_begin[i + 1]; ++k) {
      const Index c = t.vertex_corners[k], cq = next_corner(c), cr = prev_corner(c);
      s += cot[cr] * (P.row(tri[cq]).transpose() - xi) + cot[cq] * (P.row(tri[cr]).transpose() - xi);
    }
    row(i, Eigen::Vector3d(0.5 * s));
  });
}

/// (S X) row by row (for_each_cotangent_laplacian_row()), as an n x 3 array.
inline Positions cotangent_laplacian_sums(const Mesh_topology& t, const Corner_geometry& g,
                                          const Positions& P, bool parallel)
{
  Positions out(t.num_vertices, 3);
  for_each_cotangent_laplacian_row(t, g, P, parallel,
                                   [&](Index i, const Eigen::Vector3d& r) { out.row(i) = r.transpose(); });
  return out;
}

/// sum_{j in N(i)} (x_j - x_i), the uniform stiffness W applied to the positions.
inline Positions uniform_laplacian_sums(const Mesh_topology& t, const Positions& P, bool parallel)
{
  Positions out(t.num_vertices, 3);
  for_each_index(t.num_vertices, parallel, [&](Index i) {
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for(Index k = t.outer[i]; k < t.outer[i + 1]; ++k) s += P.row(t.inner[k]);  // diagonal included
    out.row(i) = s - double(t.degree(i) + 1) * P.row(i).transpose();
  });
  return out;
}

/// C_ij = 1/2 (cot alpha + cot beta) of the corners opposite the halfedges i->j and j->i (-1 where
/// that side has no face).
inline double cotangent_weight(const double* cot, const std::array<Index, 2>& c)
{
  return 0.5 * ((c[0] >= 0 ? cot[c[0]] : 0.0) + (c[1] >= 0 ? cot[c[1]] : 0.0));
}

/// Writes the cotangent stiffness C (C_ij = 1/2 (cot alpha + cot beta), C_ii = -sum)
/// into the values of the pattern of `t`, one row at a time (rows are independent).
inline void fill_cotangent_stiffness(const Mesh_topology& t, const Corner_geometry& g, double* values,
                                     bool parallel)
{
  const double* cot = g.cot_values();
  for_each_index(t.num_vertices, parallel, [&](Index i) {
    double diagonal = 0;
    for(Index s = t.outer[i]; s < t.outer[i + 1]; ++s) {
      if(s == t.diagonal_slot[i]) continue;
      const double w = cotangent_weight(cot, t.slot_corners[s]);
      values[s] = w;
      diagonal -= w;
    }
    values[t.diagonal_slot[i]] = diagonal;
  });
}

/// The writer of build_pattern_rows() that puts the cotangent stiffness straight into a slice of
/// a matrix's arrays, room for at most `capacity` entries at `inner` and `values`, each row
/// appended after the one before, so that neither the pattern's corner slots nor a second copy of
/// its indices lies beside the matrix. Row i's end goes to outer[i + 1], counted from the slice's
/// start. Each entry is the value fill_cotangent_stiffness() writes there, the diagonal added up
/// in the same order. Rows that would overrun the capacity are only counted; `size` is then the
/// number of entries the slice needs. With `on_boundary`, a boundary vertex's flag
/// is set there.
class Cotangent_rows : public Pattern_row_counts
{
public:
  Cotangent_rows(const double* cot, Index* outer, Index* inner, double* values, std::size_t capacity,
                 char* on_boundary = nullptr)
      : m_cot(cot), m_outer(outer), m_inner(inner), m_values(values), m_capacity(capacity), m_on_boundary(on_boundary)
  {}

  struct Entries
  {
    Index* inner;
    double* values;
    const double* cot;
    void set(Index slot, Index j, std::array<Index, 2> c) const
    {
      inner[slot] = j;
      values[slot] = cotangent_weight(cot, c);
    }
  };

  Entries append(std::size_t count)
  {
    const std::size_t at = size;
    size += count;
    if(size <= m_capacity && !m_overran) return {m_inner + at, m_values + at, m_cot};
    m_overran = true;
    if(m_scratch_inner.size() < count) {
      m_scratch_inner.resize(count);
      m_scratch_values.resize(count);
    }
    return {m_scratch_inner.data(), m_scratch_values.data(), m_cot};
  }
  void push_back(Index j, std::array<Index, 2> corners) { append(1).set(0, j, corners); }
  void end_row(Index i, Index diagonal)
  {
    const std::size_t begin = m_row_begin;
    m_row_begin = size;
    if(m_overran) return;
    double sum = 0;
    for(std::size_t s = begin; s < size; ++s)
      if(s != std::size_t(diagonal)) sum -= m_values[s];
    m_values[diagonal] = sum;
    m_outer[i + 1] = static_cast<Index>(size);
  }
  void mark_boundary(Index i)
  {
    if(m_on_boundary) m_on_boundary[i] = 1;
  }
  /// The cotangents of corner c's face, which the row of c's vertex reads.
  void prefetch_corner(Index c) const { prefetch(m_cot + c); }

private:
  const double* m_cot;
  Index* m_outer;
  Index* m_inner;
  double* m_values;
  std::size_t m_capacity;
  char* m_on_boundary;
  std::size_t m_row_begin = 0;
  bool m_overran = false;
  std::vector<Index> m_scratch_inner;
  std::vector<double> m_scratch_values;
};

/// Writes the uniform stiffness W = A - D into the values of the pattern of `t`.
inline void fill_uniform_stiffness(const Mesh_topology& t, double* values, bool parallel)
{
  for_each_index(t.num_vertices, parallel, [&](Index i) {
    for(Index s = t.outer[i]; s < t.outer[i + 1]; ++s) values[s] = 1.0;
    values[t.diagonal_slot[i]] = -double(t.degree(i));
  });
}

/// A sparse matrix with the pattern of `t`, its values not set: fill_cotangent_stiffness() and
/// fill_uniform_stiffness() each write every slot. Copied row by row, in parallel where asked.
template <typename SparseMatrix>
void make_pattern_matrix(const Mesh_topology& t, SparseMatrix& S, bool parallel)
{
  const Index n = t.num_vertices, nnz = t.num_nonzeros();
  S.resize(n, n);
  S.resizeNonZeros(nnz);
  prepare_for_writing(S, parallel);
  Index* outer = S.outerIndexPtr();
  Index* inner = S.innerIndexPtr();
  outer[0] = 0;
  for_each_index(n, parallel, [&](Index i) {
    outer[i + 1] = t.outer[i + 1];
    std::copy(t.inner.begin() + t.outer[i], t.inner.begin() + t.outer[i + 1], inner + t.outer[i]);
  });
}

/// Mean length of the edges (each edge counted once).
inline double mean_edge_length(const Mesh_topology& t, const Positions& P)
{
  double sum = 0;
  std::size_t count = 0;
  for(Index i = 0; i < t.num_vertices; ++i)
    for(Index k = t.outer[i]; k < t.outer[i + 1]; ++k) {
      const Index j = t.inner[k];
      if(j <= i) continue;
      sum += (P.row(i) - P.row(j)).norm();
      ++count;
    }
  return count ? sum / double(count) : 0.0;
}

} // namespace internal
} // namespace lapmesh

#endif
