// Internal: assembly of the Laplacian pencil (S, M) of positions on a topology, the checks of
// its mass, and the choice of operator and vertex area from named parameters.
#ifndef LAPMESH_INTERNAL_LAPLACIAN_ASSEMBLY_H
#define LAPMESH_INTERNAL_LAPLACIAN_ASSEMBLY_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/intrinsic_triangulation.h>
#include <lapmesh/internal/topology.h>
#include <lapmesh/parameters.h>
#include <lapmesh/types.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace lapmesh {
namespace internal {

/// The uniform or cotangent pencil of the positions P on the pattern of the topology t: the
/// diagonal of M into `mass`, and S's values, one per slot of t.inner, into the array that
/// `stiffness_values()` returns (sized for them, every slot is written). `after_geometry()` as in
/// assemble_pencil(). `lent_cot`: memory for the corner cotangents (3 per face) that the caller
/// lends (Corner_geometry::lent_cot), or null for an array of their own.
template <typename StiffnessValues, typename AfterGeometry = void (*)()>
void assemble_on_topology_pattern(const Mesh_topology& t, const Positions& P, Laplacian laplacian, Vertex_area area,
                                  bool parallel, Eigen::VectorXd& mass, const StiffnessValues& stiffness_values,
                                  const AfterGeometry& after_geometry = [] {}, double* lent_cot = nullptr)
{
  require_manifold(t, to_string(laplacian));
  if(laplacian == Laplacian::uniform) {
    fill_uniform_stiffness(t, stiffness_values(), parallel);
    mass.resize(t.num_vertices);
    for(Index v = 0; v < t.num_vertices; ++v) mass[v] = t.degree(v);
    return;
  }
  Corner_geometry g;
  g.lent_cot = lent_cot;
  compute_corner_geometry(t, P, Corner_request{area, false, false}, parallel, g);
  mass = std::move(g.vertex_area);
  after_geometry();
  fill_cotangent_stiffness(t, g, stiffness_values(), parallel);
}

/// Where assemble_cotangent_rows() writes a matrix's compressed rows.
struct Row_arrays
{
  Index* outer;  ///< the rows' ends at outer[1 .. n]
  Index* inner;
  double* values;
};

/// Assembles the cotangent (S, M) on a topology of corner incidence alone (build_corner_incidence():
/// no pattern): the corner geometry first, M into `mass`, then the pattern's rows built with their
/// values straight into the arrays that `size_rows(capacity, in_parts)` sizes for `capacity`
/// entries and returns (Row_arrays; called again where the rows are written a second time), which
/// finds the edges, the boundary vertices (flagged in `on_boundary` when given) and any
/// non-manifold edge as it goes. At its peak the call holds the triangles, the corner lists, the
/// cotangents and the result, not the pattern's slots beside them. `max_nonzeros`: at least the
/// entries the matrix needs where no row overflows (a larger one is written again).
/// In parallel the rows are built in parts, each into its slice of the arrays, placed by
/// interior_row_start(); where a part's rows do not fill it exactly (a boundary vertex, a face
/// given twice), or serially where the capacity is too small, the rows are written again at the
/// places that the first pass counted. `after_geometry()` as in assemble_pencil(), except that the
/// triangles and the corner lists are read after it. `rows_per_part`: for tests only.
/// Returns the number of entries written (outer[n]).
template <typename SizeRows, typename AfterGeometry = void (*)()>
std::size_t assemble_cotangent_rows(const Mesh_topology& t, const Positions& P, Vertex_area area,
                                             std::size_t max_nonzeros, bool parallel, Eigen::VectorXd& mass,
                                             const SizeRows& size_rows, char* on_boundary = nullptr,
                                             const AfterGeometry& after_geometry = [] {},
                                             Index rows_per_part = vertices_per_part)
{
  const Index n = t.num_vertices;
  // The pattern's topology names a non-manifold edge; built only where there is one.
  const auto name_non_manifold_edge = [&] {
    require_manifold(build_topology(n, Working_array<Index>(t.triangles)), to_string(Laplacian::cotangent));
  };
  Corner_geometry g;
  try {
    compute_corner_geometry(t, P, Corner_request{area, false, false}, parallel, g);
  } catch(const Mesh_error&) {
    name_non_manifold_edge();  // before a degenerate face, as where the pattern is built first
    throw;
  }
  mass = std::move(g.vertex_area);
  after_geometry();
  // One thread gains nothing from parts: a single part takes all rows.
  const bool in_parts = thread_count(parallel) > 1 && n > rows_per_part;
  if(!in_parts) rows_per_part = std::max<Index>(n, 1);
  const std::size_t num_parts = std::size_t(part_count(n, rows_per_part));
  // Where each part's slice starts; the last entry is the arrays' capacity.
  std::vector<std::size_t> slice(num_parts + 1, 0);
  for(std::size_t p = 1; p <= num_parts; ++p) {
    const Index end = std::min(Index(p) * rows_per_part, n);
    slice[p] = in_parts ? interior_row_start(t, end) : max_nonzeros;
  }
  std::vector<Pattern_row_counts> counts(num_parts);
  Index* outer = nullptr;
  const auto write_rows = [&] {
    const Row_arrays arrays = size_rows(slice[num_parts], in_parts);
    outer = arrays.outer;
    for_each_part(n, rows_per_part, in_parts, [&](Index p, Index first, Index last) {
      const std::size_t at = slice[std::size_t(p)];
      Cotangent_rows rows(g.cot_values(), arrays.outer, arrays.inner + at, arrays.values + at,
                          slice[std::size_t(p) + 1] - at, on_boundary);
      build_pattern_rows(t, first, last, rows);
      counts[std::size_t(p)] = std::move(rows);  // what the part counted, without its writer
    });
  };
  write_rows();
  if(!std::all_of(counts.begin(), counts.end(), [](const Pattern_row_counts& c) { return c.manifold; }))
    name_non_manifold_edge();
  // Every part but the last must fill its slice; the last one may leave room (the bound's).
  bool in_place = true;
  for(std::size_t p = 0; p < num_parts; ++p) {
    const std::size_t room = slice[p + 1] - slice[p];
    in_place = in_place && (p + 1 < num_parts ? counts[p].size == room : counts[p].size <= room);
  }
  if(!in_place) {
    for(std::size_t p = 0; p < num_parts; ++p) slice[p + 1] = slice[p] + counts[p].size;
    write_rows();
  }
  // Each part counted its rows' ends from its slice's start.
  outer[0] = 0;
  for_each_part(n, rows_per_part, in_parts, [&](Index p, Index first, Index last) {
    const Index base = static_cast<Index>(slice[std::size_t(p)]);
    if(base > 0)
      for(Index i = first; i < last; ++i) outer[i + 1] += base;
  });
  return num_parts > 0 ? slice[num_parts - 1] + counts[num_parts - 1].size : 0;
}

/// assemble_cotangent_rows() into a pencil: S into out.stiffness, sized for `max_nonzeros` (the
/// vertices plus twice graph_edge_count()), then cut to the entries written, where the graph had
/// more edges than its faces.
template <typename AfterGeometry = void (*)()>
void assemble_cotangent_pencil_by_rows(const Mesh_topology& t, const Positions& P, Vertex_area area,
                                       std::size_t max_nonzeros, bool parallel, Laplacian_pencil& out,
                                       const AfterGeometry& after_geometry = [] {},
                                       Index rows_per_part = vertices_per_part)
{
  const auto size_rows = [&](std::size_t capacity, bool in_parts) {
    release(out.stiffness);  // a matrix written again is sized afresh, not copied
    out.stiffness.resize(t.num_vertices, t.num_vertices);
    out.stiffness.resizeNonZeros(static_cast<Index>(capacity));
    prepare_for_writing(out.stiffness, in_parts);
    return Row_arrays{out.stiffness.outerIndexPtr(), out.stiffness.innerIndexPtr(), out.stiffness.valuePtr()};
  };
  const std::size_t nonzeros = assemble_cotangent_rows(t, P, area, max_nonzeros, parallel, out.mass, size_rows,
                                                       nullptr, after_geometry, rows_per_part);
  out.stiffness.data().resize(static_cast<Index>(nonzeros));
}

/// Assembles (S, M) for the positions P on the topology t. When `out` already holds a
/// matrix with t's pattern (repeated assembly while smoothing) only the values are written;
/// the intrinsic Delaunay Laplacian has a pattern of its own (its flipped edges), rebuilt
/// each time.
/// `after_geometry()` is called once the corner geometry of the cotangent Laplacian is computed,
/// before the stiffness is sized: from then on neither the positions nor the triangles and the
/// corner lists of `t` are read, and a caller that needs them no more may release them there.
template <typename AfterGeometry = void (*)()>
void assemble_pencil(const Mesh_topology& t, const Positions& P, Laplacian laplacian, Vertex_area area,
                     bool parallel, Laplacian_pencil& out, double mollification = default_mollification_factor,
                     const AfterGeometry& after_geometry = [] {})
{
  if(laplacian == Laplacian::intrinsic_delaunay) {
    Intrinsic_delaunay_stats stats;
    const Intrinsic_triangulation it = intrinsic_delaunay_triangulation(t, P, mollification, &stats);
    if(stats.flips > 0 || !t.manifold) {
      assemble_intrinsic_pencil(it, area, out.stiffness, out.mass);
      return;
    }
    // No flip on a manifold mesh: the triangles are the mesh's (the front sheet of a tufted
    // cover, whose back sheet mirrors it), so are the pattern and the assembly; only the
    // cotangents and areas come from the (mollified) lengths.
    if(out.stiffness.rows() != t.num_vertices || out.stiffness.nonZeros() != t.num_nonzeros() ||
       !out.stiffness.isCompressed() ||
       !std::equal(t.inner.begin(), t.inner.end(), out.stiffness.innerIndexPtr()))
      make_pattern_matrix(t, out.stiffness, parallel);
    Corner_geometry g;
    intrinsic_corner_geometry(t, it, area, parallel, g);
    fill_cotangent_stiffness(t, g, out.stiffness.valuePtr(), parallel);
    out.mass = std::move(g.vertex_area);
    return;
  }
  assemble_on_topology_pattern(
    t, P, laplacian, area, parallel, out.mass,
    [&] {
      if(out.stiffness.rows() != t.num_vertices || out.stiffness.nonZeros() != t.num_nonzeros() ||
         !out.stiffness.isCompressed())
        make_pattern_matrix(t, out.stiffness, parallel);
      return out.stiffness.valuePtr();
    },
    after_geometry);
}

inline Eigen::VectorXd vertex_areas(const Mesh_topology& t, const Positions& P, Vertex_area area, bool parallel)
{
  Corner_geometry g;
  compute_corner_geometry(t, P, Corner_request{area, false, false, false}, parallel, g);
  return std::move(g.vertex_area);
}

/// What makes a vertex area non-positive, for the messages that name such a vertex: valid
/// obtuse faces make a Voronoi area negative, but the other areas sum non-negative parts of
/// the faces around the vertex, so only faces without area (e.g. collapsed by a flow) do.
inline const char* non_positive_area_remedy(Vertex_area area)
{
  return area == Vertex_area::voronoi ? "use the mixed or barycentric area" : "the faces around it have no area";
}

/// Throws Mesh_error naming the first vertex with a non-positive mass. The spectral and
/// smoothing solvers need M positive definite; the Voronoi area can fail this on obtuse meshes.
inline void require_positive_mass(const Eigen::VectorXd& mass, Vertex_area area)
{
  for(Eigen::Index i = 0; i < mass.size(); ++i)
    if(!(mass[i] > 0))
      throw Mesh_error("vertex " + std::to_string(i) + " has a non-positive " + to_string(area) +
                         " area (" + message_number(mass[i]) + "); the mass matrix must be positive: " +
                         non_positive_area_remedy(area),
                       Mesh_error::Element::vertex, i);
}

/// require_positive_mass() for the vertex areas of the geometric Laplacians; the uniform mass
/// (the degrees) is positive by construction.
inline void require_positive_mass(Laplacian laplacian, const Eigen::VectorXd& mass, Vertex_area area)
{
  if(laplacian != Laplacian::uniform) require_positive_mass(mass, area);
}

template <typename NamedParameters>
Laplacian choose_laplacian(const NamedParameters& np)
{
  return CGAL::parameters::choose_parameter(CGAL::parameters::get_parameter(np, internal_np::laplacian),
                                            Laplacian::cotangent);
}
/// `factor` if it is a valid mollification factor (finite and >= 0); else Parameter_error
/// naming `parameter`, the setting as its caller calls it.
inline double checked_mollification(double factor, const char* parameter)
{
  if(!(factor >= 0) || !std::isfinite(factor))
    throw Parameter_error(parameter, "must be a finite number >= 0 (got " + message_number(factor) + ")", "1e-5");
  return factor;
}
/// The mollification factor of the named parameters, checked.
template <typename NamedParameters>
double choose_mollification(const NamedParameters& np)
{
  return checked_mollification(CGAL::parameters::choose_parameter(
                                 CGAL::parameters::get_parameter(np, internal_np::mollification_factor),
                                 default_mollification_factor),
                               "mollification_factor");
}
template <typename NamedParameters>
Vertex_area choose_vertex_area(const NamedParameters& np)
{
  return CGAL::parameters::choose_parameter(CGAL::parameters::get_parameter(np, internal_np::vertex_area),
                                            Vertex_area::barycentric);
}

} // namespace internal
} // namespace lapmesh

#endif
