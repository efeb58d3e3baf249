// Internal: per-corner geometry of a triangle mesh and the per-vertex gathers built on it.
//
// One streaming pass over the faces computes, for every corner, the cotangent of its angle
// and its share of the vertex area (and, on request, the angle itself and the face normal).
// This is the single canonical place where cotangent weights and vertex areas are defined
// (doc/conventions.md); every operator and curvature of lapmesh is a gather over these arrays.
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
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <vector>


namespace lapmesh {
namespace internal {

/// n x 3 vertex positions; row-major so that a vertex's coordinates are contiguous.
using Positions = Vertex_vectors;

struct Corner_geometry
{
  // Working arrays: resize() leaves them uninitialised, which saves a zeroing pass that the
  // face pass overwrites anyway; large ones get whole huge pages (internal/memory.h).
  Working_array<double> cot;          ///< cot of the corner angle, 3 per face
  Working_array<double> corner_area;  ///< the corner's share of its vertex's area A_i
  Working_array<double> angle;        ///< the corner angle (only with want_angles)
  Working_array<double> face_normal;  ///< 3 per face: cross product = 2 * area * unit normal
                                      ///< (only with want_face_normals)
};

struct Corner_request
{
  Vertex_area area = Vertex_area::barycentric;
  bool want_angles = false;
  bool want_face_normals = false;
};

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

/// Fills `g` from the positions. Throws Mesh_error naming the first degenerate face.
inline void compute_corner_geometry(const Mesh_topology& t, const Positions& P,
                                    const Corner_request& request, bool parallel,
                                    Corner_geometry& g)
{
  const Index m = t.num_faces;
  g.cot.resize(3 * std::size_t(m));
  g.corner_area.resize(3 * std::size_t(m));
  if(request.want_angles) g.angle.resize(3 * std::size_t(m));
  if(request.want_face_normals) g.face_normal.resize(3 * std::size_t(m));
  // How many faces ahead the positions of a face's corners are prefetched.
  constexpr Index prefetch_distance = 16;

  First_index<Index> first_degenerate;
  const Index* tri = t.triangles.data();

  for_each_index(m, parallel, [&](Index f) {
    if(f + prefetch_distance < m)
      for(Index a = 0; a < 3; ++a) prefetch(&P(tri[3 * (f + prefetch_distance) + a], 0));
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
    const double c0 = dot0 * inv, c1 = dot1 * inv, c2 = dot2 * inv;
    double* cot = &g.cot[3 * std::size_t(f)];
    cot[0] = c0; cot[1] = c1; cot[2] = c2;

    const double squared[3] = {l0, l1, l2};
    lumped_corner_areas(request.area, 0.5 * dbl_area, cot, squared, &g.corner_area[3 * std::size_t(f)]);
    if(request.want_angles) {
      // The angle opposite the longest edge is pi minus the other two: one atan2 fewer,
      // and the three angles of every face sum to pi, which makes Gauss–Bonnet exact.
      double* ang = &g.angle[3 * std::size_t(f)];
      const int largest = l0 >= l1 ? (l0 >= l2 ? 0 : 2) : (l1 >= l2 ? 1 : 2);
      const double dots[3] = {dot0, dot1, dot2};
      const int a1 = (largest + 1) % 3, a2 = (largest + 2) % 3;
      ang[a1] = std::atan2(dbl_area, dots[a1]);
      ang[a2] = std::atan2(dbl_area, dots[a2]);
      ang[largest] = M_PI - ang[a1] - ang[a2];
    }
    if(request.want_face_normals) {
      double* n = &g.face_normal[3 * std::size_t(f)];
      n[0] = cross.x(); n[1] = cross.y(); n[2] = cross.z();
    }
  });
  if(!first_degenerate.empty()) {
    const Index f = first_degenerate.get();
    const Eigen::Vector3d p0 = P.row(tri[3 * f]), p1 = P.row(tri[3 * f + 1]), p2 = P.row(tri[3 * f + 2]);
    const Face_defect d = face_defect(p0.data(), p1.data(), p2.data());
    throw_face_defect(f, d == Face_defect::none ? Face_defect::zero_area : d);
  }
}

/// Sum over the corners of each vertex of a per-corner array.
inline Eigen::VectorXd gather_corner_sums(const Mesh_topology& t, const Working_array<double>& per_corner,
                                          bool parallel)
{
  Eigen::VectorXd out(t.num_vertices);
  advise_huge_pages(out);
  for_each_index(t.num_vertices, parallel, [&](Index v) {
    double s = 0;
    for(Index k = t.corner_begin[v]; k < t.corner_begin[v + 1]; ++k) s += per_corner[t.vertex_corners[k]];
    out[v] = s;
  });
  return out;
}

/// Area-weighted vertex normals (normalised sum of the incident face cross products).
inline Positions gather_vertex_normals(const Mesh_topology& t, const Corner_geometry& g, bool parallel)
{
  Positions N(t.num_vertices, 3);
  for_each_index(t.num_vertices, parallel, [&](Index v) {
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for(Index k = t.corner_begin[v]; k < t.corner_begin[v + 1]; ++k) {
      const double* n = &g.face_normal[3 * std::size_t(t.vertex_corners[k] / 3)];
      s += Eigen::Vector3d(n[0], n[1], n[2]);
    }
    const double len = s.norm();
    N.row(v) = len > 0 ? Eigen::Vector3d(s / len) : Eigen::Vector3d::Zero();
  });
  return N;
}

/// (S X) row by row: sum_j S_ij (x_j - x_i), for the cotangent stiffness S = C. Computed from
/// the corners, without a matrix: corner c at i gives 1/2 (cot_r (x_q - x_i) + cot_q (x_r - x_i)).
inline Positions cotangent_laplacian_sums(const Mesh_topology& t, const Corner_geometry& g,
                                          const Positions& P, bool parallel)
{
  Positions out(t.num_vertices, 3);
  const Index* tri = t.triangles.data();
  const Index n = t.num_vertices;
  // The triangles and cotangents of a vertex's corners are fetched twice as far ahead as the
  // positions they name, which can only be read once the triangles have arrived.
  constexpr Index ahead = corner_prefetch_distance;
  for_each_index(n, parallel, [&](Index i) {
    if(i + 2 * ahead < n)
      for(Index k = t.corner_begin[i + 2 * ahead]; k < t.corner_begin[i + 2 * ahead + 1]; ++k) {
        prefetch(&tri[t.vertex_corners[k]]);
        prefetch(&g.cot[t.vertex_corners[k]]);
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
      s += g.cot[cr] * (P.row(tri[cq]).transpose() - xi) + g.cot[cq] * (P.row(tri[cr]).transpose() - xi);
    }
    out.row(i) = 0.5 * s;
  });
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

/// Writes the cotangent stiffness C (C_ij = 1/2 (cot alpha + cot beta), C_ii = -sum)
/// into the values of the pattern of `t`, one row at a time (rows are independent).
inline void fill_cotangent_stiffness(const Mesh_topology& t, const Corner_geometry& g, double* values,
                                     bool parallel)
{
  for_each_index(t.num_vertices, parallel, [&](Index i) {
    double diagonal = 0;
    for(Index s = t.outer[i]; s < t.outer[i + 1]; ++s) {
      const std::array<Index, 2>& c = t.slot_corners[s];
      if(s == t.diagonal_slot[i]) continue;
      const double w = 0.5 * ((c[0] >= 0 ? g.cot[c[0]] : 0.0) + (c[1] >= 0 ? g.cot[c[1]] : 0.0));
      values[s] = w;
      diagonal -= w;
    }
    values[t.diagonal_slot[i]] = diagonal;
  });
}

/// Writes the uniform stiffness W = A - D into the values of the pattern of `t`.
inline void fill_uniform_stiffness(const Mesh_topology& t, double* values, bool parallel)
{
  for_each_index(t.num_vertices, parallel, [&](Index i) {
    for(Index s = t.outer[i]; s < t.outer[i + 1]; ++s) values[s] = 1.0;
    values[t.diagonal_slot[i]] = -double(t.degree(i));
  });
}

/// A sparse matrix with the pattern of `t`, its values not set: fill_cotangent_stiffness() and
/// fill_uniform_stiffness() each write every slot. Copied row by row, in parallel where asked,
/// so that the pages of a large matrix are first touched by several threads.
template <typename SparseMatrix>
void make_pattern_matrix(const Mesh_topology& t, SparseMatrix& S, bool parallel)
{
  const Index n = t.num_vertices, nnz = t.num_nonzeros();
  S.resize(n, n);
  S.resizeNonZeros(nnz);
  advise_huge_pages(S);
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
