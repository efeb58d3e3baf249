// The vertex numbering of the operations layer's meshes, private to src/operations.
//
// A mesh read with its faces stored apart (non-manifold edges or vertices, see
// io::triangles_to_mesh) carries the input vertex of each of its vertices in a property map;
// every library call gets it as the `vertex_index_map`, which welds the copies back, so that
// results are indexed by the input's vertices whatever the storage.
#ifndef LAPMESH_SRC_OPERATIONS_NUMBERING_H
#define LAPMESH_SRC_OPERATIONS_NUMBERING_H

#include "operations.h"

#include <CGAL/Named_function_parameters.h>

namespace lapmesh_ops {

/// The name of the property map holding the input vertex of each vertex.
inline const char* input_vertex_property() { return "v:lapmesh_input_vertex"; }

/// Calls f with the named parameters that number `mesh`'s vertices as its input's.
template <typename F>
decltype(auto) with_numbering(const Mesh& mesh, F&& f)
{
  const auto [map, found] = mesh.property_map<Mesh::Vertex_index, int>(input_vertex_property());
  if(found) return f(CGAL::parameters::vertex_index_map(map));
  return f(CGAL::parameters::default_values());
}

} // namespace lapmesh_ops

#endif
