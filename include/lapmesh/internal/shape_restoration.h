// Internal: enclosed volume, surface area and their centroids, and the restoration of the
// initial volume or area (and centroid) after each step of a shrinking flow.
#ifndef LAPMESH_INTERNAL_SHAPE_RESTORATION_H
#define LAPMESH_INTERNAL_SHAPE_RESTORATION_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/topology.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>

namespace lapmesh {
namespace internal {

/// Signed enclosed volume (divergence theorem) and volume centroid of a closed mesh.
inline void volume_and_centroid(const Mesh_topology& t, const Positions& P, double& volume, Eigen::Vector3d& centroid)
{
  double V = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for(Index f = 0; f < t.num_faces; ++f) {
    const auto [a, b, d] = face_points(t, P, f);
    const double v6 = a.dot(b.cross(d));  // 6 x volume of the tetrahedron (0, a, b, d)
    V += v6;
    c += v6 * (a + b + d);
  }
  volume = V / 6.0;
  centroid = V != 0 ? Eigen::Vector3d(c / (4.0 * V)) : Eigen::Vector3d::Zero();
}

/// Surface area and area centroid (area-weighted mean of the face centroids).
inline void area_and_centroid(const Mesh_topology& t, const Positions& P, double& area, Eigen::Vector3d& centroid)
{
  double A = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for(Index f = 0; f < t.num_faces; ++f) {
    const auto [a, b, d] = face_points(t, P, f);
    const double af = 0.5 * (b - a).cross(d - a).norm();
    A += af;
    c += af * (a + b + d) / 3.0;
  }
  area = A;
  centroid = A > 0 ? Eigen::Vector3d(c / A) : Eigen::Vector3d::Zero();
}

/// Undoes the shrinkage of a flow after each step: a uniform scaling about the current centroid
/// back to the initial enclosed volume (closed meshes) or surface area, and a translation back
/// to the initial centroid. It moves every vertex, so it needs a mesh without fixed vertices.
class Shape_restoration
{
public:
  enum class Measure { none, volume, area };

  Shape_restoration(Measure measure, const Mesh_topology& t, const Positions& P) : m_measure(measure)
  {
    if(m_measure == Measure::none) return;
    measure_of(t, P, m_measure0, m_centroid0);
    if(!(std::abs(m_measure0) > 0))
      throw Mesh_error(m_measure == Measure::volume ? "volume restoration: the mesh encloses no volume"
                                                    : "area restoration: the mesh has no area");
  }

  /// False when apply() leaves the positions as they are.
  bool rescales() const { return m_measure != Measure::none; }

  void apply(const Mesh_topology& t, Positions& P) const
  {
    if(m_measure == Measure::none) return;
    double value;
    Eigen::Vector3d c;
    measure_of(t, P, value, c);
    const double f = m_measure == Measure::volume ? std::cbrt(m_measure0 / value) : std::sqrt(m_measure0 / value);
    for(Index i = 0; i < P.rows(); ++i) P.row(i) = (P.row(i) - c.transpose()) * f + m_centroid0.transpose();
  }

private:
  void measure_of(const Mesh_topology& t, const Positions& P, double& value, Eigen::Vector3d& c) const
  {
    if(m_measure == Measure::volume)
      volume_and_centroid(t, P, value, c);
    else
      area_and_centroid(t, P, value, c);
  }
  Measure m_measure;
  double m_measure0 = 0;
  Eigen::Vector3d m_centroid0 = Eigen::Vector3d::Zero();
};

} // namespace internal
} // namespace lapmesh

#endif
