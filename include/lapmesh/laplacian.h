// lapmesh — Laplacian operators of a triangle mesh: stiffness matrices and lumped masses.
//
// Conventions (doc/conventions.md, which also compares them with libigl, pmp and CGAL):
//  - Stiffness matrices are negative semidefinite, with zero row sums (S·1 = 0):
//      cotangent  C_ij = 1/2 (cot alpha_ij + cot beta_ij),  C_ii = -sum_j C_ij
//      uniform    W = A - D  (adjacency minus degrees)
//    The pointwise Laplacian is L = M^-1 S, i.e. (L x)_i = 1/A_i sum_j C_ij (x_j - x_i).
//  - Masses are lumped (diagonal) and returned as vectors: the vertex areas A_i for
//    `cotangent`, the vertex degrees for `uniform`.
//  - Row/column i is vertex i of the vertex numbering (see vertex_index_map below).
#ifndef LAPMESH_LAPLACIAN_H
#define LAPMESH_LAPLACIAN_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/laplacian_assembly.h>
#include <lapmesh/internal/mesh_extraction.h>
#include <lapmesh/internal/uniform_from_edges.h>
#include <lapmesh/parameters.h>
#include <lapmesh/types.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <string>

namespace lapmesh {

namespace internal {

/// laplacian_pencil() through the extraction (the general path), into `out`.
template <typename ConcurrencyTag, typename TriangleMesh, typename NamedParameters>
void assemble_extracted_pencil(const TriangleMesh& tm, const NamedParameters& np, Laplacian_pencil& out)
{
  const bool parallel = is_parallel<ConcurrencyTag>();
  // The cotangent rows are written into the matrix as they are built, so no pattern is kept
  // beside it.
  const bool by_rows = choose_laplacian(np) == Laplacian::cotangent;
  auto mesh = extract_mesh(tm, np, by_rows ? Topology_detail::incidence : Topology_detail::pattern, parallel);
  // What the matrix's fill does not read is freed before the matrix is allocated, which the cache
  // of working arrays could not serve: large arrays go back to the system, small ones stay cached
  // for the next call (release_to_system()).
  const auto release_positions_and_vertices = [&] {
    mesh.positions = Positions();
    release_to_system(mesh.vertices);
    release_to_system(mesh.vertex_rows);
  };
  if(by_rows) {
    const std::size_t max_nonzeros = std::size_t(mesh.topology.num_vertices) + 2 * graph_edge_count(tm);
    assemble_cotangent_pencil_by_rows(mesh.topology, mesh.positions, choose_vertex_area(np), max_nonzeros, parallel,
                                      out, release_positions_and_vertices);
  } else {
    const auto release_geometry_inputs = [&] {
      release_positions_and_vertices();
      release_to_system(mesh.topology.triangles);
      mesh.topology.release_corner_lists();
    };
    assemble_pencil(mesh.topology, mesh.positions, choose_laplacian(np), choose_vertex_area(np), parallel, out,
                    choose_mollification(np), release_geometry_inputs);
  }
  if(mesh.num_rows_in_no_face() > 0) {  // their rows and columns are zero, their mass too
    mesh.move_to_rows(out.stiffness);
    out.mass = mesh.to_rows(out.mass, 0.0);
  }
}

} // namespace internal

/// \ingroup PkgLapmeshOperators
/// @brief assembles the stiffness matrix and the lumped mass of a Laplacian of `tm`.
///
/// @tparam ConcurrencyTag `CGAL::Sequential_tag` or `CGAL::Parallel_tag` (TBB)
/// @tparam TriangleMesh a model of `FaceListGraph` whose faces are triangles
/// @param tm the mesh: no zero-area face and manifold edges, except for the intrinsic
///   Delaunay Laplacian, which takes any triangles. Vertices in no face get zero rows,
///   columns and mass.
/// @param np optional named parameters:
///   - `lapmesh::parameters::laplacian` (`Laplacian`, default `cotangent`)
///   - `lapmesh::parameters::vertex_area` (`Vertex_area`, default `barycentric`)
///   - `lapmesh::parameters::mollification_factor` (double, default 1e-5; intrinsic Delaunay only)
///   - `CGAL::parameters::vertex_point_map` (default: the internal point map of `tm`)
///   - `CGAL::parameters::vertex_index_map` (onto 0..n-1; vertices with the same index are
///     welded into one; default: the position of the vertex in `vertices(tm)`, which is
///     `v.idx()` for a Surface_mesh without garbage)
/// @return (S, M) with row i = vertex i of that numbering
/// @throws Mesh_error naming the vertex or face for invalid or degenerate input
/// @warning computed in double precision whatever the kernel's number type.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Laplacian_pencil laplacian_pencil(const TriangleMesh& tm,
                                  const NamedParameters& np = CGAL::parameters::default_values())
{
  Laplacian_pencil out;
  // The uniform operator needs no geometry: read straight off the graph's edges, unless
  // a vertex_index_map may weld vertices.
  if(internal::choose_laplacian(np) == Laplacian::uniform && internal::uniform_pencil_from_edges(tm, np, out))
    return out;
  internal::assemble_extracted_pencil<ConcurrencyTag>(tm, np, out);
  return out;
}

/// @brief returns the cotangent stiffness matrix C (doc/conventions.md), negative semidefinite.
/// Named parameters: `vertex_point_map`, `vertex_index_map` (as in laplacian_pencil()).
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Eigen::SparseMatrix<double> cotangent_stiffness_matrix(const TriangleMesh& tm,
                                                       const NamedParameters& np = CGAL::parameters::default_values())
{
  Eigen::SparseMatrix<double> stiffness;  // swapped out of the pencil: returning the member would copy it
  laplacian_pencil<ConcurrencyTag>(tm, parameters::laplacian(Laplacian::cotangent, np)).stiffness.swap(stiffness);
  return stiffness;
}

/// @brief returns the uniform stiffness matrix W = A - D (graph adjacency minus degrees).
template <typename TriangleMesh, typename NamedParameters = CGAL::parameters::Default_named_parameters>
Eigen::SparseMatrix<double> uniform_stiffness_matrix(const TriangleMesh& tm,
                                                     const NamedParameters& np = CGAL::parameters::default_values())
{
  Eigen::SparseMatrix<double> stiffness;  // as in cotangent_stiffness_matrix()
  // Off the graph's edges as in laplacian_pencil(), without the degrees that the pencil's mass
  // holds; where that declines, the general path alone (not the edges a second time).
  if(internal::uniform_stiffness_on_default_rows(tm, np, stiffness)) return stiffness;
  Laplacian_pencil pencil;
  internal::assemble_extracted_pencil<CGAL::Sequential_tag>(tm, parameters::laplacian(Laplacian::uniform, np), pencil);
  pencil.stiffness.swap(stiffness);
  return stiffness;
}

/// @brief returns the vertex areas A_i (the lumped cotangent mass) of the kind chosen by
/// `lapmesh::parameters::vertex_area` (default barycentric). They are areas (not densities):
/// barycentric and mixed areas sum to the surface area; Voronoi areas can be <= 0.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Eigen::VectorXd vertex_areas(const TriangleMesh& tm, const NamedParameters& np = CGAL::parameters::default_values())
{
  const auto mesh =
    internal::extract_mesh(tm, np, internal::Topology_detail::corners, internal::is_parallel<ConcurrencyTag>());
  return mesh.to_rows(internal::vertex_areas(mesh.topology, mesh.positions, internal::choose_vertex_area(np),
                                             internal::is_parallel<ConcurrencyTag>()),
                      0.0);
}

/// @brief writes the vertex areas A_i into the writable vertex property map `area_map`.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh, typename VertexAreaMap,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
void compute_vertex_areas(const TriangleMesh& tm, VertexAreaMap area_map,
                          const NamedParameters& np = CGAL::parameters::default_values())
{
  const auto mesh =
    internal::extract_mesh(tm, np, internal::Topology_detail::corners, internal::is_parallel<ConcurrencyTag>());
  internal::write_row_values(mesh.vertex_rows,
                             mesh.to_rows(internal::vertex_areas(mesh.topology, mesh.positions,
                                                                 internal::choose_vertex_area(np),
                                                                 internal::is_parallel<ConcurrencyTag>()),
                                          0.0),
                             area_map);
}

} // namespace lapmesh

#endif
