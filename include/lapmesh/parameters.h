// lapmesh — named parameters (the enumerations they take are declared in types.h).
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

#include <lapmesh/types.h>

#include <CGAL/Named_function_parameters.h>
#include <CGAL/boost/graph/named_params_helper.h>

#include <optional>
#include <stdexcept>
#include <string>

namespace lapmesh {

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
/// double >= 0; default `default_mollification_factor`: the intrinsic Delaunay Laplacian
/// raises every edge length by the least epsilon that gives each triangle a triangle-inequality
/// margin of this factor x the mean edge length (0: no mollification).
LAPMESH_NAMED_PARAMETER(mollification_factor)

namespace parameters {
using CGAL::parameters::default_values;
}

} // namespace lapmesh

#endif
