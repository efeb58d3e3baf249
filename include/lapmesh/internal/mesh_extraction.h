// Internal: reads a CGAL FaceGraph once into lapmesh's flat arrays.
//
// Vertex numbering (the row order of every matrix and vector lapmesh returns): the values of
// the `vertex_index_map` named parameter when one is given (it must be a bijection onto
// 0..n-1), otherwise the position of the vertex in `vertices(tm)`. For a Surface_mesh without
// removed elements this is `v.idx()`; with removed, not yet collected elements it is the
// compacted order, so garbage never shows up as rows.
#ifndef LAPMESH_INTERNAL_MESH_EXTRACTION_H
#define LAPMESH_INTERNAL_MESH_EXTRACTION_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/topology.h>

#include <CGAL/Dynamic_property_map.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/boost/graph/iterator.h>
#include <CGAL/boost/graph/named_params_helper.h>
#include <CGAL/number_utils.h>

#include <CGAL/boost/graph/properties.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

namespace lapmesh {
namespace internal {

/// Positions and triangles as read, before any topology is built (what writing a mesh needs).
template <typename TriangleMesh>
struct Extracted_arrays
{
  using vertex_descriptor = typename boost::graph_traits<TriangleMesh>::vertex_descriptor;
  Positions positions;
  std::vector<Index> triangles;             ///< 3 vertex indices per face, in face order
  std::vector<vertex_descriptor> vertices;  ///< vertex of each index
};

template <typename TriangleMesh>
struct Extracted_mesh
{
  using vertex_descriptor = typename boost::graph_traits<TriangleMesh>::vertex_descriptor;
  Mesh_topology topology;
  Positions positions;
  std::vector<vertex_descriptor> vertices;  ///< vertex of each index
};

template <typename TriangleMesh, typename VertexIndexMap, typename VertexPointMap>
Extracted_arrays<TriangleMesh> read_with_index_map(const TriangleMesh& tm, VertexIndexMap vim, VertexPointMap vpm)
{
  using GT = boost::graph_traits<TriangleMesh>;
  Extracted_arrays<TriangleMesh> out;
  const Index n = static_cast<Index>(vertices(tm).size());
  out.vertices.resize(n);
  out.positions.resize(n, 3);
  std::vector<char> seen(n, 0);
  for(typename GT::vertex_descriptor v : vertices(tm)) {
    const auto id = static_cast<long long>(get(vim, v));
    if(id < 0 || id >= n || seen[id])
      throw Mesh_error("the vertex index map is not a bijection onto [0, " + std::to_string(n) + ")");
    seen[id] = 1;
    out.vertices[id] = v;
    const auto& p = get(vpm, v);
    const double x = CGAL::to_double(p.x()), y = CGAL::to_double(p.y()), z = CGAL::to_double(p.z());
    if(!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
      throw Mesh_error("vertex " + std::to_string(id) + " has a non-finite coordinate",
                       Mesh_error::Element::vertex, id);
    out.positions.row(id) << x, y, z;
  }
  std::vector<Index>& triangles = out.triangles;
  triangles.reserve(3 * faces(tm).size());
  Index f_index = 0;
  for(typename GT::face_descriptor f : faces(tm)) {
    const typename GT::halfedge_descriptor h = halfedge(f, tm);
    if(next(next(next(h, tm), tm), tm) != h)
      throw Mesh_error("face " + std::to_string(f_index) + " is not a triangle",
                       Mesh_error::Element::face, f_index);
    triangles.push_back(static_cast<Index>(get(vim, target(h, tm))));
    triangles.push_back(static_cast<Index>(get(vim, target(next(h, tm), tm))));
    triangles.push_back(static_cast<Index>(get(vim, target(next(next(h, tm), tm), tm))));
    ++f_index;
  }
  return out;
}

/// Readable property map: an internal index with holes, mapped to 0..n-1.
template <typename InternalIndexMap>
struct Compacted_index_map
{
  using key_type = typename boost::property_traits<InternalIndexMap>::key_type;
  using value_type = Index;
  using reference = Index;
  using category = boost::readable_property_map_tag;
  InternalIndexMap internal;
  const std::vector<Index>* dense;
  friend Index get(const Compacted_index_map& m, const key_type& k) { return (*m.dense)[get(m.internal, k)]; }
};

/// Reads the positions and triangles of `tm` (named parameters: vertex_point_map,
/// vertex_index_map). Throws Mesh_error on non-triangle faces and non-finite coordinates.
template <typename TriangleMesh, typename NamedParameters>
Extracted_arrays<TriangleMesh> extract_arrays(const TriangleMesh& tm, const NamedParameters& np)
{
  using CGAL::parameters::choose_parameter;
  using CGAL::parameters::get_parameter;
  using CGAL::parameters::is_default_parameter;

  auto vpm = choose_parameter(get_parameter(np, CGAL::internal_np::vertex_point),
                              get_const_property_map(CGAL::vertex_point, tm));
  constexpr bool has_index_map =
    !is_default_parameter<NamedParameters, CGAL::internal_np::vertex_index_t>::value;
  if constexpr(has_index_map) {
    return read_with_index_map(tm, get_parameter(np, CGAL::internal_np::vertex_index), vpm);
  } else if constexpr(CGAL::graph_has_property<TriangleMesh, boost::vertex_index_t>::value) {
    // The internal index (Surface_mesh: v.idx()) may have holes left by removed elements:
    // compact it. (CGAL's dynamic maps on a const Surface_mesh are sized num_vertices() and
    // indexed by idx(), which overflows when there is garbage, so they are not used here.)
    auto internal = get(boost::vertex_index, tm);
    std::size_t bound = 0;
    for(auto v : vertices(tm)) bound = std::max<std::size_t>(bound, std::size_t(get(internal, v)) + 1);
    std::vector<Index> dense(bound, -1);
    Index i = 0;
    for(auto v : vertices(tm)) dense[get(internal, v)] = i++;
    return read_with_index_map(tm, Compacted_index_map<decltype(internal)>{internal, &dense}, vpm);
  } else {
    using vertex_descriptor = typename boost::graph_traits<TriangleMesh>::vertex_descriptor;
    auto dense = get(CGAL::dynamic_vertex_property_t<Index>(), tm);
    Index i = 0;
    for(vertex_descriptor v : vertices(tm)) put(dense, v, i++);
    return read_with_index_map(tm, dense, vpm);
  }
}

/// Extracts the connectivity and positions of `tm` (named parameters: vertex_point_map,
/// vertex_index_map). Throws Mesh_error on non-triangle faces, non-finite coordinates,
/// isolated vertices and non-manifold edges.
template <typename TriangleMesh, typename NamedParameters>
Extracted_mesh<TriangleMesh> extract_mesh(const TriangleMesh& tm, const NamedParameters& np)
{
  Extracted_arrays<TriangleMesh> arrays = extract_arrays(tm, np);
  Extracted_mesh<TriangleMesh> out;
  out.topology = build_topology(Index(arrays.vertices.size()), std::move(arrays.triangles));
  out.positions = std::move(arrays.positions);
  out.vertices = std::move(arrays.vertices);
  return out;
}

/// Writes per-vertex values (indexed like the extraction) into a vertex property map.
template <typename VertexDescriptors, typename Values, typename PropertyMap>
void write_vertex_values(const VertexDescriptors& vertices, const Values& values, PropertyMap map)
{
  using Value = typename boost::property_traits<PropertyMap>::value_type;
  for(std::size_t i = 0; i < vertices.size(); ++i) put(map, vertices[i], static_cast<Value>(values[i]));
}

} // namespace internal
} // namespace lapmesh

#endif
