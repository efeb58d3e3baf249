// lapmesh — discrete curvatures of a triangle mesh (doc/conventions.md).
//
// Every output is pointwise (a density, not integrated over the vertex area) and per vertex:
//  - mean curvature H_i = 1/2 |(L x)_i| s_i, signed with the area-weighted vertex normal so
//    that a sphere of radius r with outward-oriented faces has H = +1/r. With the uniform
//    Laplacian, H is the seed's graph-Laplacian quantity: it depends on the sampling and is
//    not scale-correct (it scales like a length, not an inverse length).
//    With the cotangent Laplacian and the barycentric area (the default), H does not converge
//    at irregular vertices (about 15% error at valence-5 vertices of an icosphere at every
//    refinement): use Vertex_area::mixed for accuracy.
//  - Gaussian curvature K_i = (2 pi - sum of angles) / A_i (interior), (pi - sum) / A_i
//    (boundary); sum_i K_i A_i = 2 pi chi exactly (Gauss–Bonnet) on a closed mesh.
//  - principal curvatures k1,2 = H ± sqrt(max(H^2 - K, 0)), k1 >= k2.
// On boundary vertices H and k1,2 are not curvatures of the surface (the Laplacian there
// measures the boundary's pull, not the surface's bending): do not read them as such.
#ifndef LAPMESH_CURVATURE_H
#define LAPMESH_CURVATURE_H

#include <lapmesh/laplacian.h>

#include <CGAL/boost/graph/named_params_helper.h>

#include <cmath>
#include <limits>

namespace lapmesh {

namespace internal {

/// The sign factor s_i of doc/conventions.md: -1 when L x points along the normal beyond round-off.
inline double mean_curvature_sign(const Eigen::Vector3d& Lx, const Eigen::Vector3d& n)
{
  return Lx.dot(n) > 1e-10 * Lx.norm() ? -1.0 : 1.0;
}

/// The Gaussian curvature density of vertex v: its angle deficit over its area.
inline double gaussian_curvature_at(const Mesh_topology& t, Index v, double angle_sum, double area)
{
  return ((t.on_boundary[v] ? M_PI : 2.0 * M_PI) - angle_sum) / area;
}

/// K from the angle sums (one per vertex) and the areas in `out`, then k1, k2 from K and the
/// mean curvature.
inline void set_gaussian_and_principal(const Mesh_topology& t, const double* angle_sum, bool parallel,
                                       Vertex_curvatures& out)
{
  const Index n = t.num_vertices;
  out.gaussian.resize(n);
  out.k1.resize(n);
  out.k2.resize(n);
  for_each_index(n, parallel, [&](Index v) {
    const double K = gaussian_curvature_at(t, v, angle_sum[v], out.area[v]), H = out.mean[v];
    const double root = std::sqrt(std::max(H * H - K, 0.0));
    out.gaussian[v] = K;
    out.k1[v] = H + root;
    out.k2[v] = H - root;
  });
}

/// All curvatures with the intrinsic Delaunay Laplacian: its operator applied to the input
/// positions (L x = M^-1 S x), its mass as the vertex area, the cone angles of the intrinsic
/// metric for K, and the input's area-weighted normals for the sign.
inline Vertex_curvatures compute_intrinsic_curvatures(const Mesh_topology& t, const Positions& P, Vertex_area area,
                                                      bool with_gaussian, bool parallel,
                                                      double mollification = default_mollification_factor)
{
  const Intrinsic_triangulation it = intrinsic_delaunay_triangulation(t, P, mollification);
  Vertex_curvatures out;
  Eigen::SparseMatrix<double> S;
  assemble_intrinsic_pencil(it, area, S, out.area);
  require_positive_mass(out.area, area);
  const Index n = t.num_vertices;
  out.normal = Positions::Zero(n, 3);
  for(Index f = 0; f < t.num_faces; ++f) {
    const Index* v = &t.triangles[3 * std::size_t(f)];
    const Eigen::Vector3d p0 = P.row(v[0]), p1 = P.row(v[1]), p2 = P.row(v[2]);
    const Eigen::RowVector3d cross = (p1 - p0).cross(p2 - p0).transpose();  // 2 x area x unit normal
    for(int a = 0; a < 3; ++a) out.normal.row(v[a]) += cross;
  }
  for(Index i = 0; i < n; ++i) {
    const double length = out.normal.row(i).norm();
    if(length > 0) out.normal.row(i) /= length;
  }
  out.laplacian = S * P;
  out.mean.resize(n);
  for_each_index(n, parallel, [&](Index v) {
    out.laplacian.row(v) /= out.area[v];
    const Eigen::Vector3d Lx = out.laplacian.row(v), nv = out.normal.row(v);
    out.mean[v] = 0.5 * Lx.norm() * mean_curvature_sign(Lx, nv);
  });
  if(!with_gaussian) return out;
  set_gaussian_and_principal(t, vertex_angle_sums(it).data(), parallel, out);
  return out;
}

inline void require_positive_vertex_areas(const Eigen::VectorXd& areas, Vertex_area area)
{
  for(Index v = 0; v < Index(areas.size()); ++v)
    if(!(areas[v] > 0))
      throw Mesh_error("vertex " + std::to_string(v) + " has a non-positive " + to_string(area) +
                         " area, so its curvature is undefined: " + non_positive_area_remedy(area),
                       Mesh_error::Element::vertex, v);
}

/// All curvatures from the flat arrays; `with_gaussian` = false skips the angles.
inline Vertex_curvatures compute_curvatures(const Mesh_topology& t, const Positions& P, Laplacian laplacian,
                                            Vertex_area area, bool with_gaussian, bool parallel,
                                            double mollification = default_mollification_factor)
{
  if(laplacian == Laplacian::intrinsic_delaunay)
    return compute_intrinsic_curvatures(t, P, area, with_gaussian, parallel, mollification);
  require_manifold(t, to_string(laplacian));
  Corner_geometry g;
  compute_corner_geometry(t, P, Corner_request{area, with_gaussian, true}, parallel, g);

  Vertex_curvatures out;
  out.area = std::move(g.vertex_area);
  out.normal = vertex_normals(g.face_normal_sum, parallel);
  if(laplacian == Laplacian::cotangent || with_gaussian) require_positive_vertex_areas(out.area, area);

  if(laplacian == Laplacian::cotangent) {
    out.laplacian = cotangent_laplacian_sums(t, g, P, parallel);
    for_each_index(t.num_vertices, parallel, [&](Index v) { out.laplacian.row(v) /= out.area[v]; });
  } else {
    out.laplacian = uniform_laplacian_sums(t, P, parallel);
    for_each_index(t.num_vertices, parallel, [&](Index v) { out.laplacian.row(v) /= double(t.degree(v)); });
  }

  const Index n = t.num_vertices;
  out.mean.resize(n);
  for_each_index(n, parallel, [&](Index v) {
    const Eigen::Vector3d Lx = out.laplacian.row(v), nv = out.normal.row(v);
    out.mean[v] = 0.5 * Lx.norm() * mean_curvature_sign(Lx, nv);
  });
  if(!with_gaussian) return out;

  set_gaussian_and_principal(t, g.angle_sum.data(), parallel, out);
  return out;
}

/// H alone, as compute_curvatures() computes it (bitwise). With the cotangent Laplacian each
/// vertex's row of L x and its normal are used where they are formed, not kept as n x 3 arrays.
inline Eigen::VectorXd compute_mean_curvature_only(const Mesh_topology& t, const Positions& P, Laplacian laplacian,
                                                   Vertex_area area, bool parallel, double mollification)
{
  if(laplacian != Laplacian::cotangent)
    return compute_curvatures(t, P, laplacian, area, false, parallel, mollification).mean;
  require_manifold(t, to_string(laplacian));
  Corner_geometry g;
  compute_corner_geometry(t, P, Corner_request{area, false, true}, parallel, g);
  require_positive_vertex_areas(g.vertex_area, area);
  Eigen::VectorXd mean(t.num_vertices);
  for_each_cotangent_laplacian_row(t, g, P, parallel, [&](Index v, const Eigen::Vector3d& row) {
    const Eigen::Vector3d Lx = row / g.vertex_area[v];
    const Eigen::Vector3d nv = unit_vertex_normal(g.face_normal_sum_of(v));
    mean[v] = 0.5 * Lx.norm() * mean_curvature_sign(Lx, nv);
  });
  return mean;
}

/// K alone, as compute_curvatures() computes it (bitwise), without the Laplacian of the
/// positions, the normals and the principal curvatures: the angle sums and the vertex areas.
inline Eigen::VectorXd compute_gaussian_curvature_only(const Mesh_topology& t, const Positions& P, Laplacian laplacian,
                                                       Vertex_area area, bool parallel, double mollification)
{
  if(laplacian == Laplacian::intrinsic_delaunay)  // its mass comes with its stiffness
    return compute_intrinsic_curvatures(t, P, area, true, parallel, mollification).gaussian;
  require_manifold(t, to_string(laplacian));
  Corner_geometry g;
  compute_corner_geometry(t, P, Corner_request{area, true, false, false}, parallel, g);
  require_positive_vertex_areas(g.vertex_area, area);
  Eigen::VectorXd K(t.num_vertices);
  for_each_index(t.num_vertices, parallel,
                 [&](Index v) { K[v] = gaussian_curvature_at(t, v, g.angle_sum[v], g.vertex_area[v]); });
  return K;
}

/// The mesh that curvatures_of() and the mean curvature alone compute on.
template <typename ConcurrencyTag, typename TriangleMesh, typename NamedParameters>
auto extract_for_curvatures(const TriangleMesh& tm, const NamedParameters& np)
{
  // The cotangent sums and the angles need the corners only; the uniform Laplacian walks the
  // pattern's rows and the intrinsic triangulation flips its edges.
  const bool cotangent = choose_laplacian(np) == Laplacian::cotangent;
  return extract_mesh(tm, np, cotangent ? Topology_detail::corners : Topology_detail::pattern,
                      is_parallel<ConcurrencyTag>(), cotangent ? Vertex_order::local_if_scattered : Vertex_order::as_read);
}

template <typename ConcurrencyTag, typename TriangleMesh, typename NamedParameters>
auto curvatures_of(const TriangleMesh& tm, const NamedParameters& np, bool with_gaussian)
{
  const Laplacian laplacian = choose_laplacian(np);
  auto mesh = extract_for_curvatures<ConcurrencyTag>(tm, np);
  Vertex_curvatures c = mesh.naming_input_vertices([&] {
    return compute_curvatures(mesh.topology, mesh.positions, laplacian, choose_vertex_area(np), with_gaussian,
                              is_parallel<ConcurrencyTag>(), choose_mollification(np));
  });
  if(!mesh.rows_are_topology_vertices()) {  // renumbered, or rows in no face: NaN there, and a zero area
    const double nan = std::numeric_limits<double>::quiet_NaN();
    c.mean = mesh.to_rows(c.mean, nan);
    c.area = mesh.to_rows(c.area, 0.0);
    c.normal = mesh.to_rows(c.normal, nan);
    c.laplacian = mesh.to_rows(c.laplacian, nan);
    if(with_gaussian) {
      c.gaussian = mesh.to_rows(c.gaussian, nan);
      c.k1 = mesh.to_rows(c.k1, nan);
      c.k2 = mesh.to_rows(c.k2, nan);
    }
  }
  return std::make_pair(std::move(mesh.vertex_rows), std::move(c));
}

template <typename Tag, typename NamedParameters, typename VertexRows, typename Values>
void write_if_given(const NamedParameters& np, Tag tag, const VertexRows& vertex_rows, const Values& values)
{
  if constexpr(!CGAL::parameters::is_default_parameter<NamedParameters, Tag>::value)
    write_row_values(vertex_rows, values, CGAL::parameters::get_parameter(np, tag));
}

} // namespace internal

/// \ingroup PkgLapmeshCurvature
/// @brief computes all per-vertex curvatures of `tm` and returns them as arrays indexed by
/// the vertex numbering (see laplacian_pencil()).
///
/// One pass over the faces and one gather per vertex; no matrix is assembled.
/// @tparam ConcurrencyTag `CGAL::Sequential_tag` (default) or `CGAL::Parallel_tag`
/// @tparam TriangleMesh a model of `FaceListGraph` whose faces are triangles
/// @param tm the mesh: no zero-area face and manifold edges, except for the intrinsic
///   Delaunay Laplacian, which takes any triangles. Vertices in no face get NaN curvatures,
///   NaN normals and a zero area.
/// @param np an optional sequence of named parameters among the ones below
///
/// | named parameter | description | type | default |
/// |---|---|---|---|
/// | `lapmesh::parameters::laplacian` | the Laplacian of H | `lapmesh::Laplacian` | `Laplacian::cotangent` |
/// | `lapmesh::parameters::vertex_area` | the area A_i dividing the cotangent sums and the angle deficit | `lapmesh::Vertex_area` | `Vertex_area::barycentric` (use `mixed` for accuracy) |
/// | `CGAL::parameters::vertex_point_map` | the positions | readable vertex map to a point with `x()`, `y()`, `z()` | `get(CGAL::vertex_point, tm)` |
/// | `CGAL::parameters::vertex_index_map` | the vertex numbering onto 0..n-1 (equal indices weld vertices) | readable vertex map to an integer | the position in `vertices(tm)` |
///
/// @return the curvatures, normals, areas and Laplacians, entry i = vertex i
/// @warning computed in double precision whatever the kernel's number type.
/// @throws Mesh_error for a zero-area face, a vertex with non-positive area, non-manifold edges
///   (except with the intrinsic Delaunay Laplacian) or non-finite coordinates, naming the element
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Vertex_curvatures vertex_curvatures(const TriangleMesh& tm, const NamedParameters& np = CGAL::parameters::default_values())
{
  return internal::curvatures_of<ConcurrencyTag>(tm, np, true).second;
}

/// @brief computes the curvatures of `tm` and writes each one into the vertex property map
/// given by its named parameter: `lapmesh::parameters::vertex_mean_curvature_map`,
/// `vertex_gaussian_curvature_map`, `vertex_max_curvature_map` (k1),
/// `vertex_min_curvature_map` (k2), `vertex_area_map`; plus CGAL's `vertex_normal_map`
/// (value type constructible from three doubles, e.g. the kernel's Vector_3).
/// Outputs without a map are not written. Other parameters as in vertex_curvatures().
/// @param tm the mesh
/// @param np named parameters: the output maps below, plus those of vertex_curvatures()
///
/// | named parameter | description | type | default |
/// |---|---|---|---|
/// | `lapmesh::parameters::vertex_mean_curvature_map` | receives H | writable vertex map, value from `double` | not written |
/// | `lapmesh::parameters::vertex_gaussian_curvature_map` | receives K | writable vertex map, value from `double` | not written |
/// | `lapmesh::parameters::vertex_max_curvature_map` | receives k1 | writable vertex map, value from `double` | not written |
/// | `lapmesh::parameters::vertex_min_curvature_map` | receives k2 | writable vertex map, value from `double` | not written |
/// | `lapmesh::parameters::vertex_area_map` | receives A_i | writable vertex map, value from `double` | not written |
/// | `CGAL::parameters::vertex_normal_map` | receives the unit area-weighted normal | writable vertex map, value constructible from three doubles | not written |
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh, typename NamedParameters>
void compute_vertex_curvatures(const TriangleMesh& tm, const NamedParameters& np)
{
  namespace inp = lapmesh::internal_np;
  const auto [vertices, c] = internal::curvatures_of<ConcurrencyTag>(tm, np, true);
  internal::write_if_given(np, inp::vertex_mean_curvature_map, vertices, c.mean);
  internal::write_if_given(np, inp::vertex_gaussian_curvature_map, vertices, c.gaussian);
  internal::write_if_given(np, inp::vertex_max_curvature_map, vertices, c.k1);
  internal::write_if_given(np, inp::vertex_min_curvature_map, vertices, c.k2);
  internal::write_if_given(np, inp::vertex_area_map, vertices, c.area);
  if constexpr(!CGAL::parameters::is_default_parameter<NamedParameters, CGAL::internal_np::vertex_normal_map_t>::value) {
    auto normals = CGAL::parameters::get_parameter(np, CGAL::internal_np::vertex_normal_map);
    using Vector = typename boost::property_traits<decltype(normals)>::value_type;
    for(const auto& [v, r] : vertices) put(normals, v, Vector(c.normal(r, 0), c.normal(r, 1), c.normal(r, 2)));
  }
}

/// @brief writes the signed mean curvature H into `mean_curvature_map` (skips the angle pass,
/// and keeps no per-vertex Laplacian or normal).
/// @param tm the mesh
/// @param mean_curvature_map writable vertex map receiving H
/// @param np named parameters as in vertex_curvatures()
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh, typename VertexCurvatureMap,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
void compute_mean_curvature(const TriangleMesh& tm, VertexCurvatureMap mean_curvature_map,
                            const NamedParameters& np = CGAL::parameters::default_values())
{
  const auto mesh = internal::extract_for_curvatures<ConcurrencyTag>(tm, np);
  Eigen::VectorXd mean = mesh.naming_input_vertices([&] {
    return internal::compute_mean_curvature_only(mesh.topology, mesh.positions, internal::choose_laplacian(np),
                                                 internal::choose_vertex_area(np),
                                                 internal::is_parallel<ConcurrencyTag>(),
                                                 internal::choose_mollification(np));
  });
  internal::write_row_values(mesh.vertex_rows, mesh.to_rows(std::move(mean), std::numeric_limits<double>::quiet_NaN()),
                             mean_curvature_map);
}

/// @brief writes the angle-deficit Gaussian curvature K into `gaussian_curvature_map`.
/// @param tm the mesh
/// @param gaussian_curvature_map writable vertex map receiving K (a density: deficit / A_i)
/// @param np named parameters as in vertex_curvatures()
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh, typename VertexCurvatureMap,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
void compute_gaussian_curvature(const TriangleMesh& tm, VertexCurvatureMap gaussian_curvature_map,
                                const NamedParameters& np = CGAL::parameters::default_values())
{
  // The angle deficit needs the corners only; the intrinsic triangulation flips edges of the pattern.
  const Laplacian laplacian = internal::choose_laplacian(np);
  const auto mesh = internal::extract_mesh(tm, np,
                                           laplacian == Laplacian::intrinsic_delaunay
                                             ? internal::Topology_detail::pattern
                                             : internal::Topology_detail::corners,
                                           internal::is_parallel<ConcurrencyTag>());
  Eigen::VectorXd K = mesh.naming_input_vertices([&] {
    return internal::compute_gaussian_curvature_only(mesh.topology, mesh.positions, laplacian,
                                                     internal::choose_vertex_area(np),
                                                     internal::is_parallel<ConcurrencyTag>(),
                                                     internal::choose_mollification(np));
  });
  internal::write_row_values(mesh.vertex_rows, mesh.to_rows(std::move(K), std::numeric_limits<double>::quiet_NaN()),
                             gaussian_curvature_map);
}

/// @brief writes the principal curvatures k1 >= k2 into the two maps.
/// @param tm the mesh
/// @param max_curvature_map writable vertex map receiving k1
/// @param min_curvature_map writable vertex map receiving k2
/// @param np named parameters as in vertex_curvatures()
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh, typename VertexCurvatureMap,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
void compute_principal_curvatures(const TriangleMesh& tm, VertexCurvatureMap max_curvature_map,
                                  VertexCurvatureMap min_curvature_map,
                                  const NamedParameters& np = CGAL::parameters::default_values())
{
  compute_vertex_curvatures<ConcurrencyTag>(
    tm, parameters::vertex_min_curvature_map(min_curvature_map, parameters::vertex_max_curvature_map(max_curvature_map, np)));
}

} // namespace lapmesh

#endif
