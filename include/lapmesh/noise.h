// lapmesh — reproducible Gaussian vertex noise.
//
// Each vertex moves by sigma * g, g a standard normal 3-vector (isotropic), or by
// sigma * g * n_i, g a standard normal scalar and n_i the area-weighted unit vertex normal
// (along the normal); sigma = level * mean edge length (each edge once; default) or
// level * bounding-box diagonal.
//
// Reproducibility: the generator is std::mt19937_64, whose output the C++ standard fixes;
// uniforms are taken from its top 53 bits and the normals come from the Marsaglia polar
// method written here (std::normal_distribution differs between standard libraries).
// Vertices are visited in vertex-index order, three draws per vertex (isotropic) or one.
#ifndef LAPMESH_NOISE_H
#define LAPMESH_NOISE_H

#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/mesh_extraction.h>
#include <lapmesh/parameters.h>
#include <lapmesh/types.h>

#include <cmath>
#include <cstdint>
#include <random>

namespace lapmesh {

/// Noise_direction; default isotropic.
LAPMESH_NAMED_PARAMETER(noise_direction)
/// Noise_scale; default mean_edge_length.
LAPMESH_NAMED_PARAMETER(noise_scale)
/// std::uint64_t, the seed of the draws with all its 64 bits (CGAL's `random_seed` is an
/// unsigned int); when given, it takes precedence over `random_seed`.
LAPMESH_NAMED_PARAMETER(noise_seed)

/// Standard normal samples from std::mt19937_64, identical on every platform (Marsaglia polar).
class Normal_sampler
{
public:
  /// Seeds the generator.
  explicit Normal_sampler(std::uint64_t seed) : m_rng(seed) {}

  /// Uniform in [0, 1) from the top 53 bits.
  double uniform() { return double(m_rng() >> 11) * (1.0 / 9007199254740992.0); }

  /// The next standard normal sample.
  double operator()()
  {
    if(m_has_spare) {
      m_has_spare = false;
      return m_spare;
    }
    double u, v, s;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      s = u * u + v * v;
    } while(s >= 1.0 || s == 0.0);
    const double f = std::sqrt(-2.0 * std::log(s) / s);
    m_spare = v * f;
    m_has_spare = true;
    return u * f;
  }

private:
  std::mt19937_64 m_rng;
  double m_spare = 0;
  bool m_has_spare = false;
};

namespace internal {

inline double noise_sigma(const Mesh_topology& t, const Positions& P, double level, Noise_scale scale)
{
  if(scale == Noise_scale::mean_edge_length) return level * mean_edge_length(t, P);
  const Eigen::RowVector3d lo = P.colwise().minCoeff(), hi = P.colwise().maxCoeff();
  return level * (hi - lo).norm();
}

/// Area-weighted unit vertex normals for normal noise. A face of zero area has no normal and
/// weighs nothing, so it is passed over (a vertex with no other face gets no normal and stays
/// in place) instead of refusing the mesh; a face out of the representable range is refused.
inline Positions noise_normals(const Mesh_topology& t, const Positions& P)
{
  return vertex_normals_of_faces(t, false, [&](Index f, Eigen::Vector3d& cross) {
    if(face_cross_in_range(t, P, f, cross)) return true;
    const Face_defect d = refused_face_defect(t, P, f);
    if(d != Face_defect::zero_area) throw_face_defect(f, d);
    return false;
  });
}

/// Adds noise to P in place; returns sigma.
inline double add_noise(const Mesh_topology& t, Positions& P, double level, Noise_direction direction,
                        Noise_scale scale, std::uint64_t seed)
{
  if(!(level >= 0) || !std::isfinite(level))
    throw std::invalid_argument("the noise level must be a finite number >= 0 (got " + message_number(level) + ")");
  const double sigma = noise_sigma(t, P, level, scale);
  Normal_sampler g(seed);
  if(direction == Noise_direction::isotropic) {
    for(Index i = 0; i < t.num_vertices; ++i) {
      const double x = g(), y = g(), z = g();
      P(i, 0) += sigma * x;
      P(i, 1) += sigma * y;
      P(i, 2) += sigma * z;
    }
    return sigma;
  }
  const Positions N = noise_normals(t, P);
  for(Index i = 0; i < t.num_vertices; ++i) P.row(i) += sigma * g() * N.row(i);
  return sigma;
}

} // namespace internal

/// \ingroup PkgLapmeshNoise
/// @brief adds seeded Gaussian noise to the vertex positions of `tm`; returns sigma.
///
/// @param tm the mesh; positions are written through the vertex point map
/// @param level sigma = level * mean edge length (or * bounding-box diagonal)
/// @param np named parameters:
///   - `CGAL::parameters::random_seed` (unsigned; default 0)
///   - `lapmesh::parameters::noise_seed` (std::uint64_t; takes precedence over `random_seed`)
///   - `lapmesh::parameters::noise_direction` (default isotropic)
///   - `lapmesh::parameters::noise_scale` (default mean_edge_length)
///   - `CGAL::parameters::vertex_point_map`, `vertex_index_map` (the order of the draws)
/// The same seed gives the same displacements on every platform.
template <typename TriangleMesh, typename NamedParameters = CGAL::parameters::Default_named_parameters>
double add_noise(TriangleMesh& tm, double level, const NamedParameters& np = CGAL::parameters::default_values())
{
  using CGAL::parameters::choose_parameter;
  using CGAL::parameters::get_parameter;
  auto mesh = internal::extract_mesh(tm, np);
  const std::uint64_t seed = std::uint64_t(choose_parameter(
    get_parameter(np, internal_np::noise_seed),
    std::uint64_t(choose_parameter(get_parameter(np, CGAL::internal_np::random_seed), 0u))));
  const double sigma = internal::add_noise(
    mesh.topology, mesh.positions, level,
    choose_parameter(get_parameter(np, internal_np::noise_direction), Noise_direction::isotropic),
    choose_parameter(get_parameter(np, internal_np::noise_scale), Noise_scale::mean_edge_length), seed);
  using Vpm = typename CGAL::GetVertexPointMap<TriangleMesh, NamedParameters>::type;
  Vpm vpm = choose_parameter(get_parameter(np, CGAL::internal_np::vertex_point), get_property_map(CGAL::vertex_point, tm));
  using Point = typename boost::property_traits<Vpm>::value_type;
  mesh.for_each_vertex([&](auto v, internal::Index i) {
    const auto r = mesh.positions.row(i);
    put(vpm, v, Point(r[0], r[1], r[2]));
  });
  return sigma;
}

} // namespace lapmesh

#endif
