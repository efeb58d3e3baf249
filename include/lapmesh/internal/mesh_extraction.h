// Internal: reads a CGAL FaceGraph once into lapmesh's flat arrays.
//
// Vertex numbering (the row order of every matrix and vector lapmesh returns): the values of
// the `vertex_index_map` named parameter when one is given, otherwise the position of the
// vertex in `vertices(tm)`. For a Surface_mesh without removed elements this is `v.idx()`;
// with removed, not yet collected elements it is the compacted order, so garbage never shows
// up as rows. A given map must reach every index of 0..n-1; when it gives several vertices
// the same index it welds them into one row (they must share their position): this is how a
// mesh that a FaceGraph cannot hold as it is (non-manifold edges and vertices) is processed,
// its faces stored apart and welded back by their input vertex numbers.
//
// The computation runs on the rows that are in some face (the topology's vertices); rows in
// no face get a documented value in each result (NaN, zero, or their input position).
#ifndef LAPMESH_INTERNAL_MESH_EXTRACTION_H
#define LAPMESH_INTERNAL_MESH_EXTRACTION_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/parallel.h>
#include <lapmesh/internal/topology.h>

#include <CGAL/Dynamic_property_map.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/boost/graph/iterator.h>
#include <CGAL/boost/graph/named_params_helper.h>
#include <CGAL/number_utils.h>

#include <Eigen/SparseCore>

#include <CGAL/boost/graph/properties.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace CGAL {
template <typename Point>
class Surface_mesh;
}

namespace lapmesh {
namespace internal {

template <typename TriangleMesh>
struct is_surface_mesh : std::false_type
{};
template <typename Point>
struct is_surface_mesh<CGAL::Surface_mesh<Point>> : std::true_type
{};

/// The coordinates of a kernel point as doubles: how every extraction reads a vertex, and how
/// the smoothing's write-back tells a vertex that moved from one that did not.
template <typename Point>
Eigen::RowVector3d point_coordinates(const Point& p)
{
  return Eigen::RowVector3d(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
}

/// Positions and triangles as read, before any topology is built (what writing a mesh needs).
template <typename TriangleMesh>
struct Extracted_arrays
{
  using vertex_descriptor = typename boost::graph_traits<TriangleMesh>::vertex_descriptor;
  Positions positions;                        ///< one row per index of the numbering
  Working_array<Index> triangles;             ///< 3 vertex indices per face, in face order
  Working_array<vertex_descriptor> vertices;  ///< the first vertex of each index
  /// Every vertex with its index, in `vertices(tm)` order (welded vertices share one).
  Working_array<std::pair<vertex_descriptor, Index>> vertex_rows;
};

/// A mesh ready for computation: the topology and positions of the rows that are in a face.
template <typename TriangleMesh>
struct Extracted_mesh
{
  using vertex_descriptor = typename boost::graph_traits<TriangleMesh>::vertex_descriptor;
  Mesh_topology topology;
  Positions positions;                        ///< per topology vertex
  Working_array<vertex_descriptor> vertices;  ///< the first vertex of each topology vertex
  Index num_rows = 0;                         ///< rows of the numbering (results' size)
  /// The row of each topology vertex; empty when topology vertex i is row i. Increasing (rows
  /// in no face left out) unless the vertices were renumbered for locality (a corners-only
  /// extraction of a mesh in scattered order, extract_mesh()).
  std::vector<Index> row;
  /// The face, in the order read, of each topology face; empty when that order was kept.
  std::vector<Index> face;
  /// Every vertex with its row, in `vertices(tm)` order.
  Working_array<std::pair<vertex_descriptor, Index>> vertex_rows;

  Index num_rows_in_no_face() const { return row.empty() ? 0 : num_rows - Index(row.size()); }
  /// Whether per-topology-vertex values are already per row (to_rows() returns them as they are).
  bool rows_are_topology_vertices() const { return row.empty(); }

  /// `error` with the topology vertex or face it names replaced by the input's (its row, or
  /// its place in the order read).
  Mesh_error in_rows(const Mesh_error& error) const
  {
    const bool is_vertex = error.element() == Mesh_error::Element::vertex;
    const std::vector<Index>& input = is_vertex ? row : face;
    if(input.empty() || (!is_vertex && error.element() != Mesh_error::Element::face) || error.index() < 0 ||
       error.index() >= std::int64_t(input.size()))
      return error;
    const std::int64_t input_index = input[std::size_t(error.index())];
    const std::string kind = is_vertex ? "vertex " : "face ";
    std::string what = error.what();
    const std::string named = kind + std::to_string(error.index());
    for(std::size_t at = what.find(named); at != std::string::npos; at = what.find(named, at + 1))
      if(at + named.size() == what.size() || !std::isdigit(static_cast<unsigned char>(what[at + named.size()]))) {
        what.replace(at, named.size(), kind + std::to_string(input_index));
        break;
      }
    return Mesh_error(what, error.element(), input_index);
  }

  /// Returns f(); a Mesh_error from it that names a topology vertex or face names the input's
  /// instead (in_rows()): the computations on the topology know only its numbering.
  template <typename F>
  decltype(auto) naming_input_vertices(F&& f) const
  {
    try {
      return f();
    } catch(const Mesh_error& error) {
      throw in_rows(error);
    }
  }

  /// Calls f(vertex, topology vertex) for every vertex in a face (welded copies included).
  template <typename F>
  void for_each_vertex(F f) const
  {
    if(row.empty()) {
      for(const auto& [v, r] : vertex_rows) f(v, r);
      return;
    }
    std::vector<Index> of_row(num_rows, -1);
    for(Index i = 0; i < Index(row.size()); ++i) of_row[row[i]] = i;
    for(const auto& [v, r] : vertex_rows)
      if(of_row[r] >= 0) f(v, of_row[r]);
  }

  /// Per-topology-vertex values as rows of the numbering, `fill` in rows in no face.
  template <typename Matrix>
  Matrix to_rows(const Matrix& values, double fill) const
  {
    if(row.empty()) return values;
    Matrix out = Matrix::Constant(num_rows, values.cols(), fill);
    for(Index i = 0; i < Index(row.size()); ++i) out.row(row[i]) = values.row(i);
    return out;
  }
  Eigen::VectorXd to_rows(const Eigen::VectorXd& values, double fill) const
  {
    if(row.empty()) return values;
    Eigen::VectorXd out = Eigen::VectorXd::Constant(num_rows, fill);
    for(Index i = 0; i < Index(row.size()); ++i) out[row[i]] = values[i];
    return out;
  }
  /// As above; values that are already per row are handed on, not copied.
  Eigen::VectorXd to_rows(Eigen::VectorXd&& values, double fill) const
  {
    if(row.empty()) return std::move(values);
    return to_rows(static_cast<const Eigen::VectorXd&>(values), fill);
  }
  /// Turns a matrix over the topology's vertices into the same one over the rows (zero in
  /// rows in no face), in place. `row` is increasing (a pattern extraction is never renumbered
  /// for locality), so each column keeps its entries in
  /// order: only their rows change, and the columns of rows in no face are empty. The entries
  /// are not copied (Eigen 3.4 would copy a returned SparseMatrix: fresh pages for all of it).
  void move_to_rows(Eigen::SparseMatrix<double>& A) const
  {
    if(row.empty()) return;
    A.makeCompressed();
    Eigen::SparseMatrix<double> out(num_rows, num_rows);
    out.data().swap(A.data());
    Index* const outer = out.outerIndexPtr();
    Index* const inner = out.innerIndexPtr();
    const Index* const old_outer = A.outerIndexPtr();
    Index column = 0;
    for(Index j = 0; j < Index(row.size()); ++j) {
      for(; column <= row[j]; ++column) outer[column] = old_outer[j];
      for(Index k = old_outer[j]; k < old_outer[j + 1]; ++k) inner[k] = row[inner[k]];
    }
    for(; column <= num_rows; ++column) outer[column] = old_outer[row.size()];
    A.swap(out);
  }
};

template <typename TriangleMesh, typename VertexIndexMap, typename VertexPointMap>
Extracted_arrays<TriangleMesh> read_with_index_map(const TriangleMesh& tm, VertexIndexMap vim, VertexPointMap vpm)
{
  using GT = boost::graph_traits<TriangleMesh>;
  Extracted_arrays<TriangleMesh> out;
  const Index count = static_cast<Index>(vertices(tm).size());
  out.vertex_rows.reserve(count);
  Index n = 0;
  for(typename GT::vertex_descriptor v : vertices(tm)) {
    const auto id = static_cast<long long>(get(vim, v));
    if(id < 0 || id >= count)
      throw Mesh_error("the vertex index map gives index " + std::to_string(id) + ", outside [0, " +
                       std::to_string(count) + ")");
    out.vertex_rows.emplace_back(v, Index(id));
    n = std::max(n, Index(id) + 1);
  }
  out.vertices.resize(n);
  out.positions.resize(n, 3);
  std::vector<char> seen(n, 0);
  for(const auto& [v, id] : out.vertex_rows) {
    const Eigen::RowVector3d p = point_coordinates(get(vpm, v));
    if(!p.allFinite())
      throw Mesh_error("vertex " + std::to_string(id) + " has a non-finite coordinate",
                       Mesh_error::Element::vertex, id);
    if(seen[id]) {  // a welded copy
      if(out.positions.row(id) != p)
        throw Mesh_error("two vertices with index " + std::to_string(id) +
                           " in the vertex index map have different positions",
                         Mesh_error::Element::vertex, id);
      continue;
    }
    seen[id] = 1;
    out.vertices[id] = v;
    out.positions.row(id) = p;
  }
  for(Index i = 0; i < n; ++i)
    if(!seen[i]) throw Mesh_error("the vertex index map gives no vertex the index " + std::to_string(i));
  Working_array<Index>& triangles = out.triangles;
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

/// read_with_index_map() for a Surface_mesh without removed elements in its default numbering,
/// where the position in vertices(tm) is the vertex's own index: read by index, with no
/// renumbering and no welding to check, in parallel (TBB) when asked. Same result and errors.
template <typename SurfaceMesh, typename VertexPointMap>
Extracted_arrays<SurfaceMesh> read_surface_mesh(const SurfaceMesh& tm, VertexPointMap vpm, bool parallel)
{
  using Vertex = typename SurfaceMesh::Vertex_index;
  using Face = typename SurfaceMesh::Face_index;
  const Index n = static_cast<Index>(tm.number_of_vertices()), m = static_cast<Index>(tm.number_of_faces());
  Extracted_arrays<SurfaceMesh> out;
  out.positions.resize(n, 3);
  prepare_for_writing(out.positions, parallel);
  out.vertices.resize(std::size_t(n));
  out.vertex_rows.resize(std::size_t(n));
  First_index<Index> non_finite;
  for_each_index(n, parallel, [&](Index i) {
    const Vertex v(static_cast<typename Vertex::size_type>(i));
    const Eigen::RowVector3d p = point_coordinates(get(vpm, v));
    out.positions.row(i) = p;
    if(!p.allFinite()) non_finite.record(i);
    out.vertices[std::size_t(i)] = v;
    out.vertex_rows[std::size_t(i)] = {v, i};
  });
  if(!non_finite.empty())
    throw Mesh_error("vertex " + std::to_string(non_finite.get()) + " has a non-finite coordinate",
                     Mesh_error::Element::vertex, non_finite.get());
  out.triangles.resize(3 * std::size_t(m));
  First_index<Index> not_triangle;
  for_each_index(m, parallel, [&](Index f) {
    const auto h0 = tm.halfedge(Face(static_cast<typename Face::size_type>(f)));
    const auto h1 = tm.next(h0), h2 = tm.next(h1);
    if(tm.next(h2) != h0) {
      not_triangle.record(f);
      return;
    }
    Index* corner = &out.triangles[3 * std::size_t(f)];
    corner[0] = static_cast<Index>(tm.target(h0));
    corner[1] = static_cast<Index>(tm.target(h1));
    corner[2] = static_cast<Index>(tm.target(h2));
  });
  if(!not_triangle.empty())
    throw Mesh_error("face " + std::to_string(not_triangle.get()) + " is not a triangle", Mesh_error::Element::face,
                     not_triangle.get());
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

/// Calls f(rows) with the default vertex numbering of `tm` (the position of each vertex in
/// `vertices(tm)`) as a readable property map, and returns what f returns.
template <typename TriangleMesh, typename F>
decltype(auto) with_default_vertex_rows(const TriangleMesh& tm, F&& f)
{
  if constexpr(CGAL::graph_has_property<TriangleMesh, boost::vertex_index_t>::value) {
    // The internal index (Surface_mesh: v.idx()) may have holes left by removed elements:
    // compact it. (CGAL's dynamic maps on a const Surface_mesh are sized num_vertices() and
    // indexed by idx(), which overflows when there is garbage, so they are not used here.)
    // A Surface_mesh without removed elements numbers its vertices 0, 1, ... in storage order:
    // its index is the numbering, with no map to build and no look-up through one.
    auto internal = get(boost::vertex_index, tm);
    if constexpr(is_surface_mesh<TriangleMesh>::value)
      if(!tm.has_garbage()) return f(internal);
    std::size_t bound = 0;
    for(auto v : vertices(tm)) bound = std::max<std::size_t>(bound, std::size_t(get(internal, v)) + 1);
    std::vector<Index> dense(bound, -1);
    Index i = 0;
    for(auto v : vertices(tm)) dense[get(internal, v)] = i++;
    return f(Compacted_index_map<decltype(internal)>{internal, &dense});
  } else {
    using vertex_descriptor = typename boost::graph_traits<TriangleMesh>::vertex_descriptor;
    auto dense = get(CGAL::dynamic_vertex_property_t<Index>(), tm);
    Index i = 0;
    for(vertex_descriptor v : vertices(tm)) put(dense, v, i++);
    return f(dense);
  }
}

/// Reads the positions and triangles of `tm` (named parameters: vertex_point_map,
/// vertex_index_map). Throws Mesh_error on non-triangle faces and non-finite coordinates.
/// `parallel`: read a Surface_mesh in parallel (TBB) where it can be (read_surface_mesh()).
template <typename TriangleMesh, typename NamedParameters>
Extracted_arrays<TriangleMesh> extract_arrays(const TriangleMesh& tm, const NamedParameters& np, bool parallel = false)
{
  using CGAL::parameters::choose_parameter;
  using CGAL::parameters::get_parameter;
  using CGAL::parameters::is_default_parameter;

  auto vpm = choose_parameter(get_parameter(np, CGAL::internal_np::vertex_point),
                              get_const_property_map(CGAL::vertex_point, tm));
  if constexpr(!is_default_parameter<NamedParameters, CGAL::internal_np::vertex_index_t>::value) {
    return read_with_index_map(tm, get_parameter(np, CGAL::internal_np::vertex_index), vpm);
  } else {
    if constexpr(is_surface_mesh<TriangleMesh>::value)
      if(!tm.has_garbage()) return read_surface_mesh(tm, vpm, parallel);
    (void)parallel;
    return with_default_vertex_rows(tm, [&](auto rows) { return read_with_index_map(tm, rows, vpm); });
  }
}

/// Whether the rows of the faces lie as scattered as in a shuffled mesh: then nearly every
/// corner of a pass over the faces misses the caches. Measured on a sample: the distinct blocks
/// of 64 rows among the corners of 64 consecutive faces, every 4096 faces; a shuffled mesh
/// shows nearly 192, meshes as subdivided, scanned or reordered show a half or less. Meshes of
/// fewer rows fit the caches in any order.
inline bool rows_are_scattered(const Working_array<Index>& triangles, Index num_rows)
{
  constexpr Index window = 64, stride = 4096, block_shift = 6, min_rows = Index(1) << 16;
  const Index faces = Index(triangles.size() / 3);
  if(num_rows < min_rows || faces < window) return false;
  std::array<Index, 3 * window> blocks;
  long long distinct = 0, windows = 0;
  for(Index first = 0; first + window <= faces; first += stride, ++windows) {
    for(Index c = 0; c < 3 * window; ++c) blocks[std::size_t(c)] = triangles[std::size_t(3 * first + c)] >> block_shift;
    std::sort(blocks.begin(), blocks.end());
    distinct += std::unique(blocks.begin(), blocks.end()) - blocks.begin();
  }
  return 3 * distinct >= 2 * 3 * window * windows;  // two thirds of the most possible
}

/// The rows numbered along a Morton curve of their positions (the order of the cells of an
/// octree of the bounding box): rows close in space get close numbers. Returns the number of
/// each row, a permutation.
inline std::vector<Index> locality_numbering(const Positions& positions)
{
  const Index n = Index(positions.rows());
  Box3 box;
  for(Index r = 0; r < n; ++r) box.extend(positions.row(r).transpose());
  // The code's top 32 bits (about 10 levels of the octree): cells small beside a mesh's extent,
  // inside which the rows keep their own order.
  std::vector<std::uint32_t> key(static_cast<std::size_t>(n)), key_out(static_cast<std::size_t>(n));
  std::vector<Index> rows(static_cast<std::size_t>(n)), rows_out(static_cast<std::size_t>(n));
  for(Index r = 0; r < n; ++r) {
    key[std::size_t(r)] = std::uint32_t(morton_code(positions.row(r).transpose(), box) >> 31);
    rows[std::size_t(r)] = r;
  }
  // Least significant digit first, 8 bits at a time: stable, so equal keys keep row order.
  for(int shift = 0; shift < 32; shift += 8) {
    std::array<std::size_t, 257> start{};
    for(const std::uint32_t k : key) ++start[((k >> shift) & 255) + 1];
    for(int d = 0; d < 256; ++d) start[std::size_t(d) + 1] += start[std::size_t(d)];
    for(std::size_t i = 0; i < key.size(); ++i) {
      const std::size_t at = start[(key[i] >> shift) & 255]++;
      key_out[at] = key[i];
      rows_out[at] = rows[i];
    }
    key.swap(key_out);
    rows.swap(rows_out);
  }
  std::vector<Index>& number = rows_out;  // reused: the inverse of the sorted rows
  for(Index i = 0; i < n; ++i) number[std::size_t(rows[std::size_t(i)])] = i;
  return std::move(number);
}

/// Takes into `out` the `used` rows that `topology_vertex` numbers (the others are -1): the
/// positions, first vertices and `row` of each topology vertex.
template <typename TriangleMesh>
void take_rows(const Extracted_arrays<TriangleMesh>& arrays, const std::vector<Index>& topology_vertex, Index used,
               Extracted_mesh<TriangleMesh>& out)
{
  out.row.resize(std::size_t(used));
  out.positions.resize(used, 3);
  out.vertices.resize(std::size_t(used));
  for(Index r = 0; r < Index(topology_vertex.size()); ++r)
    if(const Index v = topology_vertex[std::size_t(r)]; v >= 0) {
      out.row[std::size_t(v)] = r;
      out.positions.row(v) = arrays.positions.row(r);
      out.vertices[std::size_t(v)] = arrays.vertices[std::size_t(r)];
    }
}

/// Renumbers an extraction's rows along a Morton curve (locality_numbering()), leaving out
/// those in no face, and orders its faces by their lowest vertex: `out`'s positions, vertices,
/// `row` and `face`; returns the triangles in the new numbers and order.
template <typename TriangleMesh>
Working_array<Index> renumber_for_locality(Extracted_arrays<TriangleMesh>& arrays, Extracted_mesh<TriangleMesh>& out)
{
  const Index n = Index(arrays.positions.rows()), faces = Index(arrays.triangles.size() / 3);
  std::vector<Index> number = locality_numbering(arrays.positions);
  std::vector<Index> in_face(std::size_t(n), 0);  // then the new number of the rows in a face
  for(Index& v : arrays.triangles) {
    v = number[std::size_t(v)];
    in_face[std::size_t(v)] = 1;
  }
  Index used = 0;
  for(Index& flag : in_face) flag = flag ? used++ : -1;
  if(used < n) {
    for(Index& v : arrays.triangles) v = in_face[std::size_t(v)];
    for(Index& v : number) v = in_face[std::size_t(v)];
  }
  take_rows(arrays, number, used, out);
  // The faces by their lowest vertex, by counting (stable: the order read breaks ties).
  std::vector<Index>& start = in_face;  // reused
  start.assign(std::size_t(used) + 1, 0);
  const auto lowest = [&](Index f) {
    const Index* t = &arrays.triangles[std::size_t(3 * f)];
    return std::min({t[0], t[1], t[2]});
  };
  for(Index f = 0; f < faces; ++f) ++start[std::size_t(lowest(f)) + 1];
  for(Index v = 0; v < used; ++v) start[std::size_t(v) + 1] += start[std::size_t(v)];
  Working_array<Index> triangles(arrays.triangles.size());
  out.face.resize(std::size_t(faces));
  for(Index f = 0; f < faces; ++f) {
    const Index at = start[std::size_t(lowest(f))]++;
    out.face[std::size_t(at)] = f;
    std::copy_n(&arrays.triangles[std::size_t(3 * f)], 3, &triangles[std::size_t(3 * at)]);
  }
  return triangles;
}

/// The edges of the graph `tm`, those in no face included: a bound on the edges of its faces, and
/// so on the entries of a Laplacian's pattern (the vertices plus twice the edges).
template <typename Graph>
std::size_t graph_edge_count(const Graph& tm)
{
  return std::size_t(edges(tm).size());
}

/// How much of the topology an extraction builds: the sparsity pattern and its edge slots
/// (every operator), the corners alone (build_corner_topology(): angles, areas and their
/// gathers), or only the triangles and each vertex's corners (build_corner_incidence(): no
/// boundary flags, no edge counts, not checked for manifold edges), for a caller that finds
/// those as it builds the pattern's rows itself (assemble_cotangent_rows()).
enum class Topology_detail { pattern, corners, incidence };

/// The order of a corners-only extraction's vertices and faces.
enum class Vertex_order {
  as_read,            ///< the rows' order, and the faces as read
  local_if_scattered  ///< renumbered for locality where rows_are_scattered(): worth it for the
                      ///< mean curvature's passes, not for the Gaussian curvature's alone
                      ///< (doc/benchmarks.md, "Vertex and face order")
};

/// Extracts the connectivity and positions of `tm` (named parameters: vertex_point_map,
/// vertex_index_map), over the rows that are in a face. Throws Mesh_error on non-triangle
/// faces, non-finite coordinates, a face with a repeated vertex, and a mesh with no face.
/// `parallel` (CGAL::Parallel_tag): the reading and the topology in parallel, same result.
template <typename TriangleMesh, typename NamedParameters>
Extracted_mesh<TriangleMesh> extract_mesh(const TriangleMesh& tm, const NamedParameters& np,
                                          Topology_detail detail = Topology_detail::pattern, bool parallel = false,
                                          Vertex_order order = Vertex_order::as_read)
{
  const auto topology = [detail, parallel](Index n, Working_array<Index>&& triangles, Corner_incidence&& incidence) {
    switch(detail) {
      case Topology_detail::pattern: return build_topology(n, std::move(triangles), parallel, std::move(incidence));
      case Topology_detail::corners: return build_corner_topology(n, std::move(triangles), parallel, std::move(incidence));
      default: return build_corner_incidence(n, std::move(triangles), parallel, std::move(incidence));
    }
  };
  Extracted_arrays<TriangleMesh> arrays = extract_arrays(tm, np, parallel);
  Extracted_mesh<TriangleMesh> out;
  const Index n = Index(arrays.vertices.size());
  out.num_rows = n;
  out.vertex_rows = std::move(arrays.vertex_rows);
  if(arrays.triangles.empty()) throw Mesh_error("the mesh has no faces");
  if(detail == Topology_detail::corners && order == Vertex_order::local_if_scattered &&
     rows_are_scattered(arrays.triangles, n)) {
    // A shuffled mesh: the passes over its corners would miss the caches at nearly every
    // corner. Its vertices are numbered along a Morton curve and its faces ordered by their
    // lowest vertex; the results go back to the rows through `row` (to_rows()). A pattern's
    // matrices are results themselves, over the rows: that extraction keeps their order.
    Working_array<Index> triangles = renumber_for_locality(arrays, out);
    Working_array<Index>().swap(arrays.triangles);  // to the cache, for the topology's arrays
    const Index used = Index(out.row.size());
    Corner_incidence incidence = sort_corners_by_vertex(used, triangles, parallel);
    out.topology = topology(used, std::move(triangles), std::move(incidence));
    return out;
  }
  // The corner lists that the topology starts from also tell which rows are in no face.
  Corner_incidence incidence = sort_corners_by_vertex(n, arrays.triangles, parallel);
  if(incidence.first_vertex_in_no_face(parallel) < 0) {
    out.topology = topology(n, std::move(arrays.triangles), std::move(incidence));
    out.positions = std::move(arrays.positions);
    out.vertices = std::move(arrays.vertices);
    return out;
  }
  // Rows in no face are left out of the computation. Their corner lists are empty, so the
  // lists of the others stay as they are, their starts moved down over the empty ones.
  std::vector<Index> topology_vertex(n, -1);
  Index used = 0;
  for(Index r = 0; r < n; ++r)
    if(incidence.corner_begin[std::size_t(r) + 1] > incidence.corner_begin[std::size_t(r)]) {
      incidence.corner_begin[std::size_t(used)] = incidence.corner_begin[std::size_t(r)];
      topology_vertex[r] = used++;
    }
  incidence.corner_begin[std::size_t(used)] = Index(arrays.triangles.size());
  incidence.corner_begin.resize(std::size_t(used) + 1);
  take_rows(arrays, topology_vertex, used, out);
  for(Index& v : arrays.triangles) v = topology_vertex[v];
  out.topology = topology(used, std::move(arrays.triangles), std::move(incidence));
  return out;
}

/// Writes per-row values into a vertex property map, for every (vertex, row) pair of an
/// extraction's `vertex_rows`.
template <typename VertexRows, typename Values, typename PropertyMap>
void write_row_values(const VertexRows& vertex_rows, const Values& values, PropertyMap map)
{
  using Value = typename boost::property_traits<PropertyMap>::value_type;
  for(const auto& [v, r] : vertex_rows) put(map, v, static_cast<Value>(values[r]));
}

} // namespace internal
} // namespace lapmesh

#endif
