// Internal: the uniform stiffness W = A - D read straight off a halfedge graph's edges.
//
// Why: W needs the one-ring pattern only, no geometry. Its rows come from one pass over the
// graph's edges into the compressed arrays: no face soup, no corner topology, no triplets.
// The result equals the general path's (extract_mesh + build_topology) entry for entry; where
// the graph holds something that path would name (two edges between the same vertices, a
// loop), this one declines and the caller takes the general path, which reports it.
#ifndef LAPMESH_INTERNAL_UNIFORM_FROM_EDGES_H
#define LAPMESH_INTERNAL_UNIFORM_FROM_EDGES_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/mesh_extraction.h>
#include <lapmesh/internal/row_sort.h>
#include <lapmesh/internal/topology.h>
#include <lapmesh/types.h>

#include <CGAL/number_utils.h>

#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace lapmesh {
namespace internal {

/// From how many entries of W on uniform_stiffness_from_edges() sorts each row where it lies. The
/// counting sort by the other end makes a second pass of scattered writes over the whole
/// pattern: cheap while the pattern stays in the caches, a miss at nearly every write on a mesh
/// of a million vertices, where sorting each row (most by a sorting network) is the quicker
/// (doc/benchmarks-history.md).
constexpr std::size_t uniform_rows_sorted_in_place_from = std::size_t(1) << 20;

/// The values of row r of W, ascending at row[0 .. degree] with r among them: 1, and -degree on
/// the diagonal. False where a neighbour comes twice (two edges between the same vertices).
inline bool write_uniform_values(const Index* row, double* value, Index degree, Index r)
{
  for(Index a = 0; a <= degree; ++a) {
    if(a > 0 && row[a - 1] == row[a]) return false;
    value[a] = row[a] == r ? -double(degree) : 1.0;
  }
  return true;
}

/// Row r of W from its `degree` neighbours at row[0 .. degree), in any order, and a slot after
/// them: sorts them with r among them and writes the values beside them (1, and -degree on the
/// diagonal). False where a neighbour comes twice (two edges between the same vertices).
inline bool finish_uniform_row(Index* row, double* value, Index degree, Index r)
{
  constexpr Index short_row = 8, above_all = std::numeric_limits<Index>::max();
  if(degree < short_row) {
    Index keys[short_row];
    for(Index a = 0; a < short_row; ++a) keys[a] = a < degree ? row[a] : a == degree ? r : above_all;
    sort_short_row(keys);
    bool repeated = false;
    for(Index a = 1; a < short_row; ++a) repeated |= (a <= degree) & (keys[a - 1] == keys[a]);
    if(repeated) return false;
    for(Index a = 0; a <= degree; ++a) {
      row[a] = keys[a];
      value[a] = keys[a] == r ? -double(degree) : 1.0;
    }
    return true;
  }
  row[degree] = r;
  sort_row(row, std::size_t(degree) + 1);
  return write_uniform_values(row, value, degree, r);
}

/// Writes W for `tm` into `W` (rows numbered by `row_of`, which must give the vertices of
/// `vertices(tm)` the rows 0, 1, ... in that order) and returns true; returns false, with `W`
/// unspecified, where the general path must decide. Throws Mesh_error as extract_mesh does: a
/// non-finite coordinate, a face that is not a triangle, no face, a face with a repeated vertex.
/// A vertex in no face gets an empty row and column.
///
/// The rows are a counting sort of the edges by their ends, then by the other end, or, from
/// `sorted_in_place_from` entries of W on (counted with every edge of the graph), each row sorted
/// where it lies: the graph's own arrays are read in storage order. (Circulating around each
/// vertex instead jumps through the halfedges, which on a mesh of poor locality made this slower
/// than the general path once the caches were cold.)
template <typename TriangleMesh, typename RowMap, typename VertexPointMap>
bool uniform_stiffness_from_edges(const TriangleMesh& tm, RowMap row_of, VertexPointMap vpm,
                                  Eigen::SparseMatrix<double>& W,
                                  std::size_t sorted_in_place_from = uniform_rows_sorted_in_place_from)
{
  using GT = boost::graph_traits<TriangleMesh>;
  Index n = 0;
  for(typename GT::vertex_descriptor v : vertices(tm)) {
    if(Index(get(row_of, v)) != n) return false;
    if(!point_coordinates(get(vpm, v)).allFinite())
      throw Mesh_error("vertex " + std::to_string(n) + " has a non-finite coordinate", Mesh_error::Element::vertex, n);
    ++n;
  }

  Index f_index = 0, non_triangle = -1, repeated = -1;
  for(typename GT::face_descriptor f : faces(tm)) {
    const typename GT::halfedge_descriptor h = halfedge(f, tm), h1 = next(h, tm), h2 = next(h1, tm);
    if(next(h2, tm) != h) {
      if(non_triangle < 0) non_triangle = f_index;
    } else if(repeated < 0) {
      const auto a = target(h, tm), b = target(h1, tm), c = target(h2, tm);
      if(a == b || b == c || a == c) repeated = f_index;
    }
    ++f_index;
  }
  if(non_triangle >= 0)
    throw Mesh_error("face " + std::to_string(non_triangle) + " is not a triangle", Mesh_error::Element::face,
                     non_triangle);
  if(f_index == 0) throw Mesh_error("the mesh has no faces");
  if(repeated >= 0)
    throw Mesh_error("face " + std::to_string(repeated) + " uses the same vertex twice", Mesh_error::Element::face,
                     repeated);

  // W's arrays are sized for every edge of the graph before the edges are read (an edge in no
  // face is no edge of the triangles, and its room is trimmed at the end): the edges' ends and
  // the counting sort's array then wait in the arrays of W that are written after them, which
  // spares two arrays as large beside W. W cannot come from the cache of working arrays, and the
  // call takes nothing else from it, so the cached mappings (another call's) go back to the system
  // first: freed blocks of glibc's heap could serve W, cached mappings would only lie beside it.
  const std::size_t max_entries = std::size_t(n) + 2 * graph_edge_count(tm);
  if(max_entries > std::size_t(std::numeric_limits<Index>::max())) return false;
  const bool sorted_in_place = max_entries >= sorted_in_place_from;
  W.resize(n, n);
  release_working_memory();
  W.resizeNonZeros(Index(max_entries));
  prepare_for_writing(W);
  Index* const outer = W.outerIndexPtr();
  Index* const inner = W.innerIndexPtr();
  double* const value = W.valuePtr();
  std::fill(outer, outer + n + 1, Index(0));
  // The ends of every edge in a face, and the number of such edges at each vertex in
  // outer[r + 1]. Rows sorted where they lie are scattered into `inner` itself, so the ends wait
  // in `value` (as doubles, exact for indices); the counting sort writes `inner` only after it has
  // read them, so they wait there.
  std::size_t ends = 0;
  for(typename GT::edge_descriptor e : edges(tm)) {
    const typename GT::halfedge_descriptor h = halfedge(e, tm);
    if(is_border(h, tm) && is_border(opposite(h, tm), tm)) continue;
    const Index a = Index(get(row_of, target(h, tm))), b = Index(get(row_of, source(h, tm)));
    if(a == b) return false;  // a loop
    if(sorted_in_place) {
      value[ends] = double(a);
      value[ends + 1] = double(b);
    } else {
      inner[ends] = a;
      inner[ends + 1] = b;
    }
    ends += 2;
    ++outer[a + 1];
    ++outer[b + 1];
  }
  // Row r: its neighbours and, when it has any, the diagonal.
  for(Index r = 0; r < n; ++r) {
    const Index degree = outer[r + 1];
    outer[r + 1] = outer[r] + (degree > 0 ? degree + 1 : 0);
  }
  // Each row's neighbours in the order of the edges, its last slot (the diagonal's) unused.
  std::vector<Index> fill(outer, outer + n);
  if(sorted_in_place) {
    // Then each row sorted where it lies (finish_uniform_row()).
    for(std::size_t k = 0; k < ends; k += 2) {
      const Index a = Index(value[k]), b = Index(value[k + 1]);
      inner[fill[std::size_t(a)]++] = b;
      inner[fill[std::size_t(b)]++] = a;
    }
    for(Index r = 0; r < n; ++r)
      if(outer[r + 1] > outer[r] && !finish_uniform_row(inner + outer[r], value + outer[r], outer[r + 1] - outer[r] - 1, r))
        return false;
  } else {
    // Into `value` (the counting sort's array, as doubles), then every row again in ascending
    // order: row c hands c to its neighbours' rows at step c, a counting sort by the other end.
    for(std::size_t k = 0; k < ends; k += 2) {
      const Index a = inner[k], b = inner[k + 1];
      value[fill[std::size_t(a)]++] = double(b);
      value[fill[std::size_t(b)]++] = double(a);
    }
    std::copy(outer, outer + n, fill.begin());
    for(Index c = 0; c < n; ++c) {
      const Index begin = outer[c], end = outer[c + 1];
      if(begin == end) continue;  // a vertex in no face
      inner[fill[std::size_t(c)]++] = c;
      for(Index a = begin; a + 1 < end; ++a) inner[fill[std::size_t(Index(value[a]))]++] = c;
    }
    for(Index r = 0; r < n; ++r)
      if(outer[r + 1] > outer[r] && !write_uniform_values(inner + outer[r], value + outer[r], outer[r + 1] - outer[r] - 1, r))
        return false;
  }
  W.data().resize(outer[n]);  // where the graph has edges in no face or vertices in none
  return true;
}

/// W of `tm` by uniform_stiffness_from_edges() on the default vertex numbering; false, with `W`
/// left empty, where that declines or a vertex_index_map (which may weld vertices) is given.
/// Named parameters: vertex_point_map.
template <typename TriangleMesh, typename NamedParameters>
bool uniform_stiffness_on_default_rows(const TriangleMesh& tm, const NamedParameters& np, Eigen::SparseMatrix<double>& W)
{
  if constexpr(!CGAL::parameters::is_default_parameter<NamedParameters, CGAL::internal_np::vertex_index_t>::value)
    return false;
  const auto vpm = CGAL::parameters::choose_parameter(CGAL::parameters::get_parameter(np, CGAL::internal_np::vertex_point),
                                                      get_const_property_map(CGAL::vertex_point, tm));
  if(!with_default_vertex_rows(tm, [&](auto rows) { return uniform_stiffness_from_edges(tm, rows, vpm, W); })) {
    release(W);  // no half-written pattern for the general path
    return false;
  }
  return true;
}

/// The uniform pencil (W, the degrees) of `tm` by uniform_stiffness_on_default_rows(); false where that
/// declines. A vertex in no face gets mass 0, as on the general path. On false `out` is left empty.
template <typename TriangleMesh, typename NamedParameters>
bool uniform_pencil_from_edges(const TriangleMesh& tm, const NamedParameters& np, Laplacian_pencil& out)
{
  if(!uniform_stiffness_on_default_rows(tm, np, out.stiffness)) return false;
  const Index n = Index(out.stiffness.rows());
  const Index* outer = out.stiffness.outerIndexPtr();
  out.mass.resize(n);
  for(Index r = 0; r < n; ++r) out.mass[r] = std::max(outer[r + 1] - outer[r] - 1, 0);
  return true;
}

} // namespace internal
} // namespace lapmesh

#endif
