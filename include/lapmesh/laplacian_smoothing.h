// lapmesh — Laplacian smoothing: explicit and implicit Laplacian flow, and conformalized
// mean curvature flow.
//
//   explicit   P <- P + lambda L P                  (L = M^-1 S; stable for lambda < 2 / mu_max)
//   implicit   (M - lambda S) P' = M P              (backward Euler, SPD, unconditionally stable)
//   conformal  (M_t - lambda S_0) P' = M_t P        (Kazhdan, Solomon, Ben-Chen 2012: the
//              stiffness of the input is kept, the mass follows the surface; CGAL's smooth_shape)
//
// Uniform Laplacian: (S, M) = (W, D), so the implicit step is (I - lambda Lu) P' = P and
// lambda is dimensionless. Cotangent Laplacian: (S, M) = (C, diag(A_i)); lambda is a time
// and scales like a length squared: use scale_free_time_step() to make one number work on
// meshes of any size (lambda = tau * mean edge length^2).
//
// Boundary vertices and vertices marked by `vertex_is_constrained_map` are Dirichlet
// constraints: their positions are never written (bitwise fixed), their terms move to the
// right-hand side, and only the free block is solved.
#ifndef LAPMESH_LAPLACIAN_SMOOTHING_H
#define LAPMESH_LAPLACIAN_SMOOTHING_H

#include <lapmesh/internal/smoothing_engine.h>
#include <lapmesh/internal/stability_bound.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/parameters.h>

#include <CGAL/boost/graph/named_params_helper.h>

#include <functional>
#include <limits>
#include <memory>
#include <utility>
#include <type_traits>
#include <vector>

namespace lapmesh {

/// bool; default false: keep the operator of the input mesh for all iterations instead of
/// rebuilding it from the current positions (the default, mean curvature flow).
LAPMESH_NAMED_PARAMETER(fixed_operator)
/// bool; default false: after each step, rescale about the centroid to the enclosed volume of
/// the input and move the volume centroid back (closed meshes without constrained vertices).
LAPMESH_NAMED_PARAMETER(restore_volume)
/// bool; default false: after each step, rescale about the area centroid to the surface area of
/// the input and move that centroid back (any mesh without fixed vertices: on a mesh with
/// boundary, together with fix_boundary(false)).
LAPMESH_NAMED_PARAMETER(restore_area)
/// bool; default true: boundary vertices stay fixed (Dirichlet). false: they move with the flow
/// (natural Neumann condition, as the spectral solver treats boundaries).
LAPMESH_NAMED_PARAMETER(fix_boundary)
/// std::function<void(int done, int total)>, called after each iteration.
LAPMESH_NAMED_PARAMETER(progress_callback)
/// bool; default false: for the explicit scheme, always compute the Lanczos estimate of the
/// stability bound (otherwise skipped when lambda is below the Gershgorin bound, which proves
/// stability on its own).
LAPMESH_NAMED_PARAMETER(compute_stability_bound)
/// double; default none: the explicit stability bound of the mesh with the same named parameters,
/// as explicit_stability_bound() gave it, for a caller that has computed it already (to choose
/// lambda or to warn): the explicit scheme reports it and does not run the Lanczos estimate again.
LAPMESH_NAMED_PARAMETER(known_stability_bound)
/// bool; default true: use CHOLMOD (supernodal) for the implicit schemes when lapmesh is
/// compiled with LAPMESH_HAS_CHOLMOD; false forces Eigen's SimplicialLDLT.
LAPMESH_NAMED_PARAMETER(use_cholmod)
/// bool; default false: with the rebuilt operator, solve each step by conjugate gradients
/// preconditioned by the previous Cholesky factor (to a relative residual of 1e-12) and
/// refactorise only when CG needs more than 10 iterations (after the first such step, every
/// remaining step is refactorised directly). It pays where the factorisation is expensive
/// relative to a solve (regular grids); on Loop-subdivided scans it does not.
LAPMESH_NAMED_PARAMETER(reuse_factorization)

namespace internal {

/// Whether a CGAL solver traits type can factorise once and solve many times
/// (SparseLinearAlgebraWithFactorTraits_d) or only solve with the matrix (SparseLinearAlgebraTraits_d).
template <typename Solver, typename = void>
struct has_factor : std::false_type
{};
template <typename Solver>
struct has_factor<Solver, std::void_t<decltype(std::declval<Solver&>().factor(
                            std::declval<const typename Solver::Matrix&>(), std::declval<typename Solver::NT&>()))>>
  : std::true_type
{};

/// `vertex_is_constrained_map` read into one flag per topology vertex (all 0 without the map):
/// a vertex welded from several copies is constrained when any copy is.
template <typename ExtractedMesh, typename NamedParameters>
std::vector<char> constrained_vertices(const ExtractedMesh& mesh, const NamedParameters& np)
{
  std::vector<char> fixed(mesh.vertices.size(), 0);
  if constexpr(!CGAL::parameters::is_default_parameter<NamedParameters, CGAL::internal_np::vertex_is_constrained_t>::value) {
    auto vcm = CGAL::parameters::get_parameter(np, CGAL::internal_np::vertex_is_constrained);
    mesh.for_each_vertex([&](auto v, Index i) {
      if(get(vcm, v)) fixed[std::size_t(i)] = 1;
    });
  }
  return fixed;
}

template <typename ConcurrencyTag, typename TriangleMesh, typename NamedParameters>
Smoothing_report smooth_mesh(Smoothing_scheme scheme, TriangleMesh& tm, double lambda, const NamedParameters& np)
{
  using CGAL::parameters::choose_parameter;
  using CGAL::parameters::get_parameter;
  using CGAL::parameters::is_default_parameter;

  Smoothing_settings s;
  s.scheme = scheme;
  s.laplacian = choose_laplacian(np);
  s.area = choose_vertex_area(np);
  s.mollification = choose_mollification(np);
  s.lambda = lambda;
  s.iterations = int(choose_parameter(get_parameter(np, CGAL::internal_np::number_of_iterations), 1));
  s.fixed_operator = choose_parameter(get_parameter(np, internal_np::fixed_operator), false);
  s.restore_volume = choose_parameter(get_parameter(np, internal_np::restore_volume), false);
  s.restore_area = choose_parameter(get_parameter(np, internal_np::restore_area), false);
  s.fix_boundary = choose_parameter(get_parameter(np, internal_np::fix_boundary), true);
  s.parallel = is_parallel<ConcurrencyTag>();
  s.compute_stability_bound = choose_parameter(get_parameter(np, internal_np::compute_stability_bound), false);
  s.known_stability_bound = choose_parameter(get_parameter(np, internal_np::known_stability_bound),
                                             std::numeric_limits<double>::quiet_NaN());
  s.use_cholmod = choose_parameter(get_parameter(np, internal_np::use_cholmod), true);
  s.reuse_factorization = choose_parameter(get_parameter(np, internal_np::reuse_factorization), false);
  if constexpr(!is_default_parameter<NamedParameters, internal_np::progress_callback_t>::value) {
    s.progress = get_parameter(np, internal_np::progress_callback);
    s.progress_reads_positions = false;  // the mesh is written after the last step
  }
  if constexpr(!is_default_parameter<NamedParameters, CGAL::internal_np::sparse_linear_solver_t>::value) {
    // A CGAL solver traits object (SparseLinearAlgebraWithFactorTraits_d, e.g.
    // CGAL::Eigen_solver_traits<...>): factor() once per system, linear_solver() per column.
    using Solver = std::decay_t<decltype(get_parameter(np, CGAL::internal_np::sparse_linear_solver))>;
    auto solver = std::make_shared<Solver>(get_parameter(np, CGAL::internal_np::sparse_linear_solver));
    auto matrix = std::make_shared<typename Solver::Matrix>();  // factor() may keep a pointer to it
    s.external_solver.factor = [solver, matrix](const Eigen::SparseMatrix<double>& full) {
      *matrix = typename Solver::Matrix(full);
      if constexpr(has_factor<Solver>::value) {
        typename Solver::NT D;
        return solver->factor(*matrix, D);
      } else {
        return true;  // SparseLinearAlgebraTraits_d only: every solve takes the matrix
      }
    };
    s.external_solver.solve = [solver, matrix](const Eigen::MatrixXd& B, Eigen::MatrixXd& X) {
      X.resize(B.rows(), B.cols());
      for(Index c = 0; c < B.cols(); ++c) {
        typename Solver::Vector b(std::size_t(B.rows())), x(std::size_t(B.rows()));
        for(Index i = 0; i < B.rows(); ++i) b[i] = B(i, c);
        bool ok;
        if constexpr(has_factor<Solver>::value) {
          ok = solver->linear_solver(b, x);
        } else {
          typename Solver::NT D;
          ok = solver->linear_solver(*matrix, b, x, D) && D == 1;
        }
        if(!ok) return false;
        for(Index i = 0; i < B.rows(); ++i) X(i, c) = x[i];
      }
      return true;
    };
  }

  auto mesh = extract_mesh(tm, np, assembles_operator_by_rows(s) ? Topology_detail::incidence : Topology_detail::pattern,
                           s.parallel);
  Smoothing_report report = mesh.naming_input_vertices(
    [&] { return smooth_positions_releasing_topology(mesh.topology, mesh.positions, constrained_vertices(mesh, np), s); });

  // Write back only what moved: fixed vertices keep their exact kernel coordinates. What moved
  // is told by the mesh's own points, read as the extraction read them (point_coordinates()),
  // rather than by a copy of the positions taken before (a fresh array as large as them).
  using Vpm = typename CGAL::GetVertexPointMap<TriangleMesh, NamedParameters>::type;
  Vpm vpm = choose_parameter(get_parameter(np, CGAL::internal_np::vertex_point), get_property_map(CGAL::vertex_point, tm));
  using Point = typename boost::property_traits<Vpm>::value_type;
  mesh.for_each_vertex([&](auto v, Index i) {
    const auto r = mesh.positions.row(i);
    if(r != internal::point_coordinates(get(vpm, v))) put(vpm, v, Point(r[0], r[1], r[2]));
  });
  return report;
}

} // namespace internal

/// \ingroup PkgLapmeshSmoothing
/// @brief smooths `tm` by explicit (forward Euler) Laplacian flow, P <- P + lambda L P.
///
/// Stable only for lambda below 2 / mu_max, mu_max the largest eigenvalue of -L on the free
/// vertices (explicit_stability_bound()). The report's `stability_bound` is that bound of the
/// input mesh (`stability_bound_exact` true) when lambda exceeds the cheap Gershgorin bound or
/// `compute_stability_bound(true)` is given, or the bound passed as `known_stability_bound`;
/// otherwise it is the Gershgorin bound, a lower bound that already proves lambda stable.
/// `above_stability_bound` is set when lambda exceeds the bound. To show or reuse the bound
/// itself, call explicit_stability_bound(). With the operator rebuilt every iteration (default)
/// the bound can drift as the mesh changes.
///
/// @tparam ConcurrencyTag `CGAL::Sequential_tag` or `CGAL::Parallel_tag`
/// @param tm a triangle mesh; positions are written through the vertex point map
/// @param lambda the time step (> 0)
/// @param np named parameters:
///   - `CGAL::parameters::number_of_iterations` (default 1)
///   - `CGAL::parameters::vertex_is_constrained_map` (readable bool map; default none)
///   - `CGAL::parameters::vertex_point_map`, `vertex_index_map`
///   - `lapmesh::parameters::laplacian` (default cotangent), `vertex_area` (default barycentric)
///   - `lapmesh::parameters::fixed_operator` (default false), `restore_volume` (default false),
///     `restore_area` (default false), `fix_boundary` (default true), `progress_callback`
///   - `lapmesh::parameters::compute_stability_bound` (default false), `known_stability_bound`
///     (default none)
///   - `CGAL::parameters::sparse_linear_solver` (implicit and conformal schemes: a model of CGAL's
///     `SparseLinearAlgebraWithFactorTraits_d`, e.g. `CGAL::Eigen_solver_traits<Eigen::SimplicialLDLT<...>>`,
///     factorised once per system, or of `SparseLinearAlgebraTraits_d`, e.g. the iterative
///     `CGAL::Eigen_solver_traits<>`; default: CHOLMOD when compiled in, else Eigen's SimplicialLDLT)
/// @throws std::invalid_argument for lambda <= 0 or NaN and iterations <= 0; Mesh_error for
///   invalid meshes or a non-positive vertex area; Numerical_error when the flow diverges.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Smoothing_report smooth_laplacian_explicit(TriangleMesh& tm, double lambda,
                                           const NamedParameters& np = CGAL::parameters::default_values())
{
  return internal::smooth_mesh<ConcurrencyTag>(Smoothing_scheme::explicit_euler, tm, lambda, np);
}

/// @brief smooths `tm` by implicit (backward Euler) Laplacian flow, (M - lambda S) P' = M P.
///
/// The SPD free block is factorised by a sparse Cholesky (CHOLMOD's supernodal LL^T when compiled
/// in, else Eigen::SimplicialLDLT); the symbolic analysis is done once, and the matrix is
/// refactorised only when it changes (each iteration for the rebuilt cotangent operator; once
/// for `uniform` or `fixed_operator`). Where the operator follows the positions, a connected
/// component that the flow shrinks to nearly a point (area below 1e-12 x lambda) is held there
/// for the remaining steps while the others go on (the report's `collapsed_components`; not
/// the largest component, nor with `restore_volume` or `restore_area`); as in smooth_conformal_flow().
/// Named parameters as for smooth_laplacian_explicit().
/// @throws Numerical_error when a factorisation or solve fails.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Smoothing_report smooth_laplacian_implicit(TriangleMesh& tm, double lambda,
                                           const NamedParameters& np = CGAL::parameters::default_values())
{
  return internal::smooth_mesh<ConcurrencyTag>(Smoothing_scheme::implicit_euler, tm, lambda, np);
}

/// @brief smooths `tm` by conformalized mean curvature flow (Kazhdan et al. 2012):
/// (M_t - lambda S_0) P' = M_t P with the stiffness S_0 of the input mesh and the mass M_t of
/// the current one. Unlike CGAL's smooth_shape it does not rescale unless `restore_volume`.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Smoothing_report smooth_conformal_flow(TriangleMesh& tm, double lambda,
                                       const NamedParameters& np = CGAL::parameters::default_values())
{
  return internal::smooth_mesh<ConcurrencyTag>(Smoothing_scheme::conformal, tm, lambda, np);
}

/// @brief returns the explicit scheme's stability bound 2 / mu_max for the operator of `tm`
/// (free vertices only: boundary and `vertex_is_constrained_map`). Named parameters:
/// `laplacian`, `vertex_area`, `vertex_point_map`, `vertex_index_map`, `vertex_is_constrained_map`,
/// `fix_boundary`.
template <typename TriangleMesh, typename NamedParameters = CGAL::parameters::Default_named_parameters>
double explicit_stability_bound(const TriangleMesh& tm, const NamedParameters& np = CGAL::parameters::default_values())
{
  const auto mesh = internal::extract_mesh(tm, np);
  Laplacian_pencil pencil;
  const Laplacian lap = internal::choose_laplacian(np);
  const Vertex_area area = internal::choose_vertex_area(np);
  internal::assemble_pencil(mesh.topology, mesh.positions, lap, area, false, pencil,
                            internal::choose_mollification(np));
  mesh.naming_input_vertices([&] { internal::require_positive_mass(lap, pencil.mass, area); });
  const bool fix_boundary =
    CGAL::parameters::choose_parameter(CGAL::parameters::get_parameter(np, internal_np::fix_boundary), true);
  const std::vector<char> free_mask =
    internal::free_vertex_mask(mesh.topology, fix_boundary, internal::constrained_vertices(mesh, np));
  return internal::explicit_stability_bound(pencil, free_mask, false);
}

/// @brief returns the mean edge length of `tm` (each edge once). Named parameters:
/// `vertex_point_map`, `vertex_index_map`.
template <typename TriangleMesh, typename NamedParameters = CGAL::parameters::Default_named_parameters>
double mean_edge_length(const TriangleMesh& tm, const NamedParameters& np = CGAL::parameters::default_values())
{
  const auto mesh = internal::extract_mesh(tm, np);
  return internal::mean_edge_length(mesh.topology, mesh.positions);
}

/// @brief returns lambda = tau * (mean edge length)^2 for the cotangent Laplacian, and tau
/// itself for the uniform one (whose lambda is already dimensionless). tau ~ 1 is one mean
/// edge length squared of diffusion per step on any mesh, whatever its size.
template <typename TriangleMesh, typename NamedParameters = CGAL::parameters::Default_named_parameters>
double scale_free_time_step(const TriangleMesh& tm, double tau,
                            const NamedParameters& np = CGAL::parameters::default_values())
{
  return internal::lambda_of_time_step(
    tau, Time_step_unit::mean_edge_length_squared, internal::choose_laplacian(np),
    [&] { return mean_edge_length(tm, np); }, [] { return std::numeric_limits<double>::quiet_NaN(); });
}

/// @brief returns the time step lambda given as `value` in `unit` for the operator of `tm`
/// (named parameters as explicit_stability_bound()).
template <typename TriangleMesh, typename NamedParameters = CGAL::parameters::Default_named_parameters>
double time_step(const TriangleMesh& tm, double value, Time_step_unit unit,
                 const NamedParameters& np = CGAL::parameters::default_values())
{
  return internal::lambda_of_time_step(
    value, unit, internal::choose_laplacian(np), [&] { return mean_edge_length(tm, np); },
    [&] { return explicit_stability_bound(tm, np); });
}

/// @brief returns the explicit scheme's automatic time step for a stability bound computed
/// by explicit_stability_bound(): 0.9 of it (for a caller that also needs the bound).
inline double automatic_explicit_time_step(double stability_bound) { return 0.9 * stability_bound; }

/// @brief returns the automatic time step of `lapmesh smooth --lambda auto` and the viewer:
/// 0.9 of the stability bound for the explicit scheme (the largest step that stays stable, with
/// a margin for the operator changing between iterations), one mean edge length squared
/// (scale_free_time_step() with tau = 1) for the implicit and conformal schemes, which are
/// stable at any step and remove noise of about one edge length per step.
template <typename TriangleMesh, typename NamedParameters = CGAL::parameters::Default_named_parameters>
double automatic_time_step(const TriangleMesh& tm, Smoothing_scheme scheme,
                           const NamedParameters& np = CGAL::parameters::default_values())
{
  return scheme == Smoothing_scheme::explicit_euler
           ? automatic_explicit_time_step(explicit_stability_bound(tm, np))
           : time_step(tm, 1.0, Time_step_unit::mean_edge_length_squared, np);
}

} // namespace lapmesh

#endif
