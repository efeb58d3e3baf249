// lapmesh — named parameters and the kinds of operator.
//
// lapmesh's options travel in CGAL's Named_function_parameters packs, so they mix with
// CGAL's own tags (vertex_point_map, geom_traits, vertex_index_map, ...). CGAL 5.5 only
// generates member-chaining functions for its own closed list of tags; lapmesh's tags are
// therefore started or appended with free functions:
//
//   namespace LP = lapmesh::parameters;
//   LP::laplacian(lapmesh::Laplacian::uniform).vertex_point_map(vpm)         // start, then chain CGAL's
//   LP::vertex_area(lapmesh::Vertex_area::mixed, CGAL::parameters::geom_traits(k)) // append to a pack
//
// Our tags live in lapmesh::internal_np, never in CGAL::internal_np, so that a future CGAL
// cannot clash with them. test/parameters_test.cpp fails to compile if this stops working.
#ifndef LAPMESH_PARAMETERS_H
#define LAPMESH_PARAMETERS_H

#include <CGAL/Named_function_parameters.h>
#include <CGAL/boost/graph/named_params_helper.h>

#include <optional>
#include <stdexcept>
#include <string>

namespace lapmesh {

/// The discretisation of the Laplacian (doc/conventions.md).
enum class Laplacian {
  uniform,   ///< graph Laplacian: stiffness W = A - D, mass D = diag(degree)
  cotangent  ///< Laplace–Beltrami: stiffness C (halved cotangent weights), mass diag(A_i)
};

/// The vertex area A_i, i.e. the diagonal of the lumped mass matrix (doc/conventions.md).
enum class Vertex_area {
  barycentric,  ///< one third of the incident face areas (default)
  voronoi,      ///< circumcentric cells; can be zero or negative on obtuse meshes
  mixed         ///< Meyer et al. 2003 mixed cells; positive, sums to the surface area
};

/// @brief returns the name of `k` as the CLI spells it (`uniform`, `cotangent`).
inline const char* to_string(Laplacian k) { return k == Laplacian::uniform ? "uniform" : "cotangent"; }
/// @brief returns the name of `a` as the CLI spells it (`barycentric`, `voronoi`, `mixed`).
inline const char* to_string(Vertex_area a)
{
  switch(a) {
    case Vertex_area::barycentric: return "barycentric";
    case Vertex_area::voronoi: return "voronoi";
    default: return "mixed";
  }
}
/// @brief returns the Laplacian named `s`, or nothing for an unknown name.
inline std::optional<Laplacian> parse_laplacian(const std::string& s)
{
  if(s == "uniform") return Laplacian::uniform;
  if(s == "cotangent") return Laplacian::cotangent;
  return std::nullopt;
}
/// @brief returns the vertex area named `s`, or nothing for an unknown name.
inline std::optional<Vertex_area> parse_vertex_area(const std::string& s)
{
  if(s == "barycentric") return Vertex_area::barycentric;
  if(s == "voronoi") return Vertex_area::voronoi;
  if(s == "mixed") return Vertex_area::mixed;
  return std::nullopt;
}

// Declares the tag `internal_np::NAME` and the two free functions `parameters::NAME(value)`
// (start a pack) and `parameters::NAME(value, pack)` (append to an existing pack).
#define LAPMESH_NAMED_PARAMETER(NAME)                                                          \
  namespace internal_np { enum NAME##_t { NAME }; }                                             \
  namespace parameters {                                                                        \
  template <typename K>                                                                         \
  CGAL::Named_function_parameters<K, internal_np::NAME##_t> NAME(const K& k)                    \
  {                                                                                             \
    return CGAL::Named_function_parameters<K, internal_np::NAME##_t>(k);                        \
  }                                                                                             \
  template <typename K, typename T, typename Tag, typename Base>                                \
  CGAL::Named_function_parameters<K, internal_np::NAME##_t,                                     \
                                  CGAL::Named_function_parameters<T, Tag, Base>>                \
  NAME(const K& k, const CGAL::Named_function_parameters<T, Tag, Base>& np)                     \
  {                                                                                             \
    return CGAL::Named_function_parameters<K, internal_np::NAME##_t,                            \
                                           CGAL::Named_function_parameters<T, Tag, Base>>(k, np); \
  }                                                                                             \
  }

/// lapmesh::Laplacian; default Laplacian::cotangent.
LAPMESH_NAMED_PARAMETER(laplacian)
/// lapmesh::Vertex_area; default Vertex_area::barycentric.
LAPMESH_NAMED_PARAMETER(vertex_area)
/// Writable vertex property maps (value convertible from double) for the curvature outputs.
LAPMESH_NAMED_PARAMETER(vertex_mean_curvature_map)
LAPMESH_NAMED_PARAMETER(vertex_gaussian_curvature_map)
LAPMESH_NAMED_PARAMETER(vertex_max_curvature_map)
LAPMESH_NAMED_PARAMETER(vertex_min_curvature_map)
/// Writable vertex property map for the vertex area A_i.
LAPMESH_NAMED_PARAMETER(vertex_area_map)

namespace parameters {
using CGAL::parameters::default_values;
}

} // namespace lapmesh

#endif
