// Internal: the array-based engine behind laplacian_smoothing.h.
//
// Positions live in an n x 3 row-major matrix; the operator (S, M) is assembled into the
// fixed pattern of the topology (values rewritten in place, never re-allocated), or, for the
// explicit scheme on a fixed cotangent operator, assembled once, its rows built with their
// values on a topology of corner incidence alone (assembles_operator_by_rows()). Fixed
// vertices (boundary + user constraints) are Dirichlet constraints: only the free block is
// stepped or solved, the fixed positions are never written, so they stay bitwise equal.
//
// Implicit steps solve (M - lambda S)_FF P'_F = M_FF P_F + lambda S_FB P_B with a sparse
// Cholesky factorisation of the free block (Constrained_spd_system, Spd_direct_solver in
// internal/spd_solver.h): the pattern is built once, the symbolic analysis (ordering +
// elimination tree) is computed once, and each iteration only refactorises numerically; the
// three coordinates are solved against one factorisation, in place, row by row. When the matrix
// cannot change (uniform Laplacian, or a fixed operator) it is factorised once. A rebuilt
// cotangent operator is assembled into the previous factor's memory, dead until the next
// factorisation: no stiffness matrix or cotangent array of its own stands beside the factor,
// most of a step's memory.
//
// Smoothing_worker is organised as CGAL's curvature-flow worker: init() (masks, restoration,
// first assembly), setup_system() (stability bound, or the free block and its analysis),
// solve_system() (one explicit step, preconditioned CG, or factorisation and solve) and
// update_mesh() (the operator rebuilt from the new positions), called by a short loop.
#ifndef LAPMESH_INTERNAL_SMOOTHING_ENGINE_H
#define LAPMESH_INTERNAL_SMOOTHING_ENGINE_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/laplacian_assembly.h>
#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/shape_restoration.h>
#include <lapmesh/internal/spd_solver.h>
#include <lapmesh/internal/stability_bound.h>
#include <lapmesh/internal/topology.h>
#include <lapmesh/types.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace lapmesh {

namespace internal {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0)
{
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

struct Smoothing_settings
{
  Smoothing_scheme scheme = Smoothing_scheme::implicit_euler;
  Laplacian laplacian = Laplacian::cotangent;
  Vertex_area area = Vertex_area::barycentric;
  double mollification = default_mollification_factor;  ///< intrinsic Delaunay only
  double lambda = 0;
  int iterations = 1;
  bool fixed_operator = false;
  bool restore_volume = false;
  bool restore_area = false;  ///< area and area centroid, after each step (no fixed vertices)
  bool fix_boundary = true;   ///< false: boundary vertices move (natural Neumann condition)
  bool parallel = false;
  bool compute_stability_bound = false;  ///< always run Lanczos for the explicit scheme
  /// The explicit scheme's bound where the caller has computed it already (explicit_stability_bound()
  /// of the same operator and free vertices): reported as it is, not computed again. NaN: unknown.
  double known_stability_bound = std::numeric_limits<double>::quiet_NaN();
  bool use_cholmod = true;               ///< with LAPMESH_HAS_CHOLMOD: CHOLMOD supernodal LL^T
  /// Rebuilt operator: solve with conjugate gradients preconditioned by the last Cholesky
  /// factor (relative residual 1e-12) and refactorise only when that needs > 10 iterations
  /// (after the first such failure, refactorise directly for the remaining steps).
  bool reuse_factorization = false;
  /// Called after each iteration (done, total), when the positions hold that iteration's result
  /// (the denoising study measures them there).
  std::function<void(int, int)> progress;
  /// False where `progress` cannot see the positions (the CGAL front end's callback, which gets
  /// the counts alone, while the positions it smooths are its own copy).
  bool progress_reads_positions = true;
  /// Where set, each component held is appended here as well, when it is held: a caller keeps
  /// them where a later step fails and the report is lost with the exception.
  std::vector<Collapsed_component>* held_components = nullptr;
  Spd_direct_solver::External external_solver;  ///< set: used instead of CHOLMOD / Eigen LDL^T
};

/// Whether a smoothing run with settings `s` builds its operator's rows itself, with their values
/// (assemble_cotangent_rows()), on a topology of corner incidence alone (build_corner_incidence()),
/// which a caller may then hand it instead of one with the pattern: the explicit scheme on a
/// fixed cotangent operator, assembled once, which refills no slot of a pattern, and without a
/// restoration, whose checks read the boundary before the operator is assembled.
inline bool assembles_operator_by_rows(const Smoothing_settings& s)
{
  return s.scheme == Smoothing_scheme::explicit_euler && s.laplacian == Laplacian::cotangent && s.fixed_operator &&
         !s.restore_volume && !s.restore_area;
}

/// The face with the smallest area / (longest edge)^2, and that ratio (0 for a segment).
inline std::pair<Index, double> flattest_face(const Mesh_topology& t, const Positions& P)
{
  Index best = 0;
  double best_ratio = std::numeric_limits<double>::infinity();
  for(Index f = 0; f < t.num_faces; ++f) {
    const auto [a, b, c] = face_points(t, P, f);
    const double longest = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    const double ratio = longest > 0 ? 0.5 * (b - a).cross(c - a).norm() / longest : 0.0;
    if(ratio < best_ratio) {
      best_ratio = ratio;
      best = f;
    }
  }
  return {best, best_ratio};
}

/// Rebuilds the operator from the positions after `iteration` steps. A face that the flow
/// collapsed (or a vertex whose area vanished) is reported with the iteration that did it:
/// the input itself was valid, so the bare "face F has zero area" would point at the file.
template <typename Rebuild>
void rebuild_operator_after(int iteration, Rebuild&& rebuild)
{
  try {
    rebuild();
  } catch(const Mesh_error& e) {
    const std::string prefix = "iteration " + std::to_string(iteration) + ": ";
    if(e.element() == Mesh_error::Element::face)
      throw Mesh_error(prefix + "face " + std::to_string(e.index()) +
                         " has zero area (the flow collapsed it; its cotangent weights are undefined: a smaller "
                         "lambda, fewer iterations or a fixed operator avoid this)",
                       e.element(), e.index());
    throw Mesh_error(prefix + e.what(), e.element(), e.index());
  }
}

inline void check_settings(const Smoothing_settings& s)
{
  if(!(s.lambda > 0) || !std::isfinite(s.lambda))
    throw std::invalid_argument("the time step lambda must be a positive finite number (got " +
                                message_number(s.lambda) + ")");
  if(s.iterations <= 0)
    throw std::invalid_argument("the number of iterations must be positive (got " + std::to_string(s.iterations) + ")");
}

/// One smoothing run on positions P (written in place).
class Smoothing_worker
{
public:
  /// `releasable`: the topology `t` itself, when the caller needs none of its arrays after the
  /// call (the worker then releases those that no later step reads; see release_topology()).
  Smoothing_worker(const Mesh_topology& t, Positions& P, const Smoothing_settings& s,
                   Mesh_topology* releasable = nullptr)
    : m_t(t), m_P(P), m_s(s), m_releasable_topology(releasable)
  {}

  /// `fixed[i]` != 0 marks a user-constrained vertex; boundary vertices are added here. A
  /// topology without the pattern (has_pattern() false) takes settings that
  /// assembles_operator_by_rows(); others throw std::logic_error.
  Smoothing_report run(const std::vector<char>& fixed)
  {
    init(fixed);
    if(m_report.free_vertices == 0) {  // nothing can move: every step leaves P as it is
      for(int it = 0; it < m_s.iterations; ++it) {
        ++m_report.iterations;
        if(m_s.progress) m_s.progress(it + 1, m_s.iterations);
      }
      return m_report;
    }
    setup_system();
    for(int it = 0; it < m_s.iterations; ++it) {
      if(it > 0 && m_rebuild) update_mesh(it);
      solve_system(it);
      restore_shape(it);
      ++m_report.iterations;
      if(m_s.progress) m_s.progress(it + 1, m_s.iterations);
    }
    take_positions_from_alternate();
    check_last_positions();
    return m_report;
  }

private:
  using Block = Eigen::Matrix<double, Eigen::Dynamic, 3>;
  /// The right-hand side and solution, row by row, as the solver takes them (row_width()).
  using Row_block = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  bool is_explicit() const { return m_s.scheme == Smoothing_scheme::explicit_euler; }

  /// Settings, free-vertex mask, shape restoration and the operator of the input.
  void init(const std::vector<char>& fixed)
  {
    check_settings(m_s);
    if(!m_t.has_pattern() && !assembles_operator_by_rows(m_s))
      throw std::logic_error("smoothing: these settings need a topology with the pattern (build_topology())");
    // Rows built with their values tell the boundary: the operator comes first.
    if(builds_operator_rows()) assemble_first_operator();
    const Index n = m_t.num_vertices;
    m_free_mask = builds_operator_rows() ? free_vertex_mask(n, m_on_boundary, m_s.fix_boundary, fixed)
                                         : free_vertex_mask(m_t, m_s.fix_boundary, fixed);
    const Index nf = Index(std::count(m_free_mask.begin(), m_free_mask.end(), char(1)));
    m_report.free_vertices = std::size_t(nf);
    if(m_s.restore_volume && m_s.restore_area)
      throw std::invalid_argument("restore the volume or the area, not both");
    if(m_s.restore_volume && (nf != n || m_t.num_boundary_edges != 0 || !m_t.manifold))
      throw Parameter_error("restore_volume", "volume restoration needs a closed mesh without constrained vertices "
                                              "(it rescales the whole mesh, which would move fixed vertices)");
    if(m_s.restore_area && nf != n) {
      if(m_t.num_boundary_edges != 0 && m_s.fix_boundary)
        throw Parameter_error("fix_boundary", "area restoration rescales the whole mesh, so no vertex may be fixed (the "
                                              "boundary is fixed: free it with fix_boundary(false))", "false");
      throw std::invalid_argument("area restoration rescales the whole mesh, so no vertex may be fixed (there are "
                                  "constrained vertices)");
    }
    m_restoration.emplace(m_s.restore_volume ? Shape_restoration::Measure::volume
                          : m_s.restore_area ? Shape_restoration::Measure::area
                                             : Shape_restoration::Measure::none,
                          m_t, m_P);
    if(!builds_operator_rows()) assemble_first_operator();

    const bool geometric = m_s.laplacian != Laplacian::uniform;
    // What must be recomputed each iteration from the current positions.
    m_rebuild_stiffness = geometric && !m_s.fixed_operator && m_s.scheme != Smoothing_scheme::conformal;
    m_rebuild = geometric && !m_s.fixed_operator;
  }

  void assemble_first_operator()
  {
    const auto t0 = Clock::now();
    assemble_operator();
    require_positive_mass(m_s.laplacian, m_pencil.mass, m_s.area);
    m_report.assembly_seconds += seconds_since(t0);
  }

  /// Explicit: the stability bound. Implicit: the free block, its scaling and its analysis.
  void setup_system()
  {
    if(is_explicit()) {
      // Below the Gershgorin bound the scheme is provably stable: the Lanczos estimate is not needed.
      const double gershgorin = gershgorin_stability_bound(operator_arrays(), m_free_mask);
      if(!std::isnan(m_s.known_stability_bound)) {
        m_report.stability_bound = m_s.known_stability_bound;
        m_report.stability_bound_exact = true;
      } else if(m_s.compute_stability_bound || m_s.lambda > gershgorin) {
        m_report.stability_bound = explicit_stability_bound(operator_arrays(), m_free_mask, m_s.parallel);
        m_report.stability_bound_exact = true;
      } else {
        m_report.stability_bound = gershgorin;
      }
      m_report.above_stability_bound = m_s.lambda > m_report.stability_bound;
      if(alternates_positions())
        m_alternate.resize(3 * std::size_t(m_P.rows()));
      else
        m_next.resize(m_P.rows(), 3);
      return;
    }
    const auto t0 = Clock::now();
    // The system (M - lambda S) X = M P is divided by a power of four near the mean mass: on
    // meshes of extreme scale M P would overflow (or underflow) although the solution is
    // representable. Dividing by an even power of two is exact, down to the square roots of the
    // Cholesky factor, so the solution is bitwise that of the unscaled system.
    int mass_exponent = 0;
    std::frexp(m_pencil.mass.mean(), &mass_exponent);
    m_system_scale = std::ldexp(1.0, -2 * (mass_exponent / 2));
    m_scaled_lambda = m_s.lambda * m_system_scale;

    if(holds_collapsed_components()) prepare_holds();
    const int planned_factorizations = m_rebuild ? m_s.iterations : 1;
    m_solver = std::make_unique<Spd_direct_solver>(m_s.use_cholmod, m_s.external_solver);
    analyze_system(planned_factorizations);
    m_report.solver = m_solver->name();
    m_report.analysis_seconds += seconds_since(t0);
    // Preconditioned CG is tried until it fails once: then the operator changes too fast for an
    // old factor, and refactorising directly is cheaper than failed CG runs followed by a
    // factorisation anyway.
    m_try_preconditioned_cg = m_s.reuse_factorization;
  }

  /// The explicit scheme keeps the stiffness of the uniform and cotangent Laplacians, whose
  /// pattern is the topology's, as values alone in a working array: its mapping is then kept
  /// for the next call (mapping_cache.h), where a sparse matrix's blocks come from glibc's heap,
  /// which a caller's frees between calls may have trimmed, so that they are faulted in afresh.
  bool keeps_values_on_topology_pattern() const
  {
    return is_explicit() && m_s.laplacian != Laplacian::intrinsic_delaunay;
  }

  /// (S, M) of the current positions: into m_pencil, or S's values into m_stiffness_values or
  /// into the factor's memory (factor_memory_for_stiffness()).
  void assemble_operator()
  {
    if(builds_operator_rows()) {
      assemble_operator_rows();
      return;
    }
    m_stiffness_in_factor = factor_memory_for_stiffness();
    if(m_stiffness_in_factor) {  // the corner cotangents after S's values
      double* values = m_stiffness_in_factor;
      assemble_on_topology_pattern(m_t, m_P, m_s.laplacian, m_s.area, m_s.parallel, m_pencil.mass, [values] { return values; },
                                   [] {}, values + m_t.num_nonzeros());
      return;
    }
    if(!keeps_values_on_topology_pattern()) {
      assemble_pencil(m_t, m_P, m_s.laplacian, m_s.area, m_s.parallel, m_pencil, m_s.mollification);
      return;
    }
    assemble_on_topology_pattern(m_t, m_P, m_s.laplacian, m_s.area, m_s.parallel, m_pencil.mass, [&] {
      m_stiffness_values.resize(std::size_t(m_t.num_nonzeros()));
      return m_stiffness_values.data();
    });
  }

  /// Whether the operator's rows are built here (assembles_operator_by_rows()): the topology came
  /// without the pattern.
  bool builds_operator_rows() const { return !m_t.has_pattern(); }

  /// S by rows into m_operator_outer, m_operator_inner and m_stiffness_values, M into m_pencil, the
  /// boundary flags into m_on_boundary. Once the rows are built, the corner lists of a releasable
  /// topology are read no more.
  void assemble_operator_rows()
  {
    const Index n = m_t.num_vertices;
    m_on_boundary.assign(std::size_t(n), 0);
    // A row holds its vertex and each neighbour: as many neighbours as corners around an interior
    // vertex of manifold edges, one more around a boundary vertex. Rows that need more (a vertex
    // where several fans meet) are written again at their counted places.
    const std::size_t max_nonzeros = 2 * std::size_t(n) + 3 * std::size_t(m_t.num_faces);
    const auto size_rows = [&](std::size_t capacity, bool) {
      m_operator_outer.resize(std::size_t(n) + 1);
      m_operator_inner.resize(capacity);
      m_stiffness_values.resize(capacity);
      return Row_arrays{m_operator_outer.data(), m_operator_inner.data(), m_stiffness_values.data()};
    };
    assemble_cotangent_rows(m_t, m_P, m_s.area, max_nonzeros, m_s.parallel, m_pencil.mass, size_rows,
                            m_on_boundary.data());
    if(m_releasable_topology) m_releasable_topology->release_corner_lists();
  }

  /// Where a rebuilt cotangent stiffness goes once a step has been solved: into the factor's
  /// values, which nothing reads until the next factorisation rewrites them, so that the
  /// assembly adds neither a matrix nor its corner cotangents (which follow S's values there)
  /// beside the factor. Not while preconditioned CG may solve with the old factor, nor for the
  /// intrinsic Delaunay operator, whose pattern is not the topology's (fill_rhs() reads the
  /// slots from the topology). nullptr where the solver holds no such memory (before the first
  /// factorisation; Eigen's LDL^T, a user's solver) or too little of it.
  double* factor_memory_for_stiffness() const
  {
    if(is_explicit() || !m_solver || m_try_preconditioned_cg || m_s.laplacian != Laplacian::cotangent) return nullptr;
    return m_solver->values_to_overwrite(std::size_t(m_t.num_nonzeros()) + 3 * std::size_t(m_t.num_faces));
  }

  /// The current stiffness: m_pencil's, or the topology's pattern with the values in the factor's
  /// memory.
  Eigen::Map<const Eigen::SparseMatrix<double>> stiffness() const
  {
    if(m_stiffness_in_factor)
      return {m_t.num_vertices, m_t.num_vertices, m_t.num_nonzeros(), m_t.outer.data(), m_t.inner.data(),
              m_stiffness_in_factor};
    const auto& S = m_pencil.stiffness;
    return {S.rows(), S.cols(), S.nonZeros(), S.outerIndexPtr(), S.innerIndexPtr(), S.valuePtr()};
  }

  /// Whether the explicit steps alternate between m_P and m_alternate, a working array whose
  /// mapping the next call reuses (as the operator's values): only where nothing reads m_P
  /// between steps. Where the operator follows the positions, a restoration rescales them or a
  /// progress callback may read them, each step's result is swapped into m_P instead, which
  /// spares a copy per step.
  bool alternates_positions() const
  {
    return is_explicit() && !m_rebuild && !m_restoration->rescales() &&
           !(m_s.progress && m_s.progress_reads_positions);
  }

  /// Copies the latest positions into m_P when the last step left them in m_alternate.
  void take_positions_from_alternate()
  {
    if(!m_positions_in_alternate) return;
    std::copy(m_alternate.begin(), m_alternate.end(), m_P.data());
    m_positions_in_alternate = false;
  }

  /// The arrays of the operator that the explicit scheme reads.
  Pencil_arrays operator_arrays() const
  {
    if(builds_operator_rows())
      return Pencil_arrays(m_t.num_vertices, m_operator_outer.data(), m_operator_inner.data(),
                           m_stiffness_values.data(), m_pencil.mass);
    if(keeps_values_on_topology_pattern()) return Pencil_arrays(m_t, m_stiffness_values.data(), m_pencil.mass);
    return Pencil_arrays(m_pencil);
  }

  /// Step `it` (0-based): P after it + 1 steps, fixed vertices untouched.
  void solve_system(int it)
  {
    if(is_explicit()) {
      explicit_step();
      return;
    }
    bool solved = false;
    if(!m_factorized && m_try_preconditioned_cg && m_report.factorizations > 0) solved = preconditioned_solve();
    if(!solved) {
      // The right-hand side reads the stiffness for the fixed vertices' terms alone, and
      // factorize() may release it (or write over it): with fixed vertices it is filled first,
      // otherwise after the factorisation, so that its block does not stand beside the first
      // factorisation's work space.
      const bool rhs_first = !m_system->all_free();
      const auto t0 = Clock::now();
      if(rhs_first) fill_rhs();
      m_report.solve_seconds += seconds_since(t0);
      if(is_last_operator(it)) release_topology();
      if(!m_factorized) factorize(it);
      const auto t1 = Clock::now();
      if(!rhs_first) fill_rhs();
      if(!m_solver->solve_rows_in_place(m_B.data(), m_B.rows(), std::size_t(m_B.cols()), 3) || !m_B.allFinite())
        throw Numerical_error("the linear solve of the smoothing system failed at iteration " + std::to_string(it + 1));
      m_report.solve_seconds += seconds_since(t1);
    }
    m_system->scatter(m_B.leftCols<3>(), m_P);
  }

  /// Rebuilds the operator (or only the mass, conformal flow) from the positions after `it` steps.
  void update_mesh(int it)
  {
    const auto t0 = Clock::now();
    hold_collapsed_components(it);
    {
      const Held_input_shown shown(*this);
      rebuild_operator_after(it, [&] {
        try {
          if(m_rebuild_stiffness) {
            assemble_operator();
          } else if(m_s.laplacian == Laplacian::intrinsic_delaunay) {  // its mass is that of the intrinsic triangles
            Laplacian_pencil current;
            assemble_pencil(m_t, m_P, m_s.laplacian, m_s.area, m_s.parallel, current, m_s.mollification);
            m_pencil.mass = std::move(current.mass);
          } else {
            m_pencil.mass = vertex_areas(m_t, m_P, m_s.area, m_s.parallel);
          }
          require_positive_mass(m_pencil.mass, m_s.area);
        } catch(const Mesh_error& e) {
          // A component shrunk to nearly a point loses its faces' and vertices' areas to
          // underflow, which may come before a factorisation fails: the shrinking is named in
          // both cases. Otherwise the error goes on to rebuild_operator_after(), which dates it.
          if(m_rebuild)
            throw_if_shrunk_to_a_point(it, e.element() == Mesh_error::Element::face
                                             ? "face " + std::to_string(e.index()) + " has zero area"
                                             : std::string(e.what()));
          throw;
        }
      });
    }
    m_report.assembly_seconds += seconds_since(t0);
    m_factorized = false;
    // The intrinsic Delaunay operator's pattern follows its flips: a new pattern needs a new
    // free block and a new symbolic analysis.
    if(!is_explicit() && pattern_may_change() && pattern_changed()) {
      const auto t1 = Clock::now();
      analyze_system(m_s.iterations - it);
      m_report.analysis_seconds += seconds_since(t1);
    }
  }

  /// Whether a component that the flow shrinks to nearly a point is held, so that the others go
  /// on: implicit flows whose operator follows the positions, where M - lambda S is refactorised
  /// each step, unless a restoration rescales the whole mesh (and would move a held component).
  bool holds_collapsed_components() const { return !is_explicit() && m_rebuild && !m_restoration->rescales(); }

  /// The component labels, and the input positions of every vertex outside the largest
  /// component, where the mesh has several components.
  void prepare_holds()
  {
    m_component = connected_component_labels(m_t, &m_components);
    if(m_components < 2) {
      std::vector<Index>().swap(m_component);
      return;
    }
    std::vector<Index> size(std::size_t(m_components), 0);
    for(Index c : m_component) ++size[std::size_t(c)];
    m_largest_component = Index(std::max_element(size.begin(), size.end()) - size.begin());
    m_held.assign(std::size_t(m_t.num_vertices), 0);
    for(Index v = 0; v < m_t.num_vertices; ++v)
      if(m_component[v] != m_largest_component) m_spare_vertices.push_back(v);
    m_spare_input.resize(Index(m_spare_vertices.size()), 3);
    for(Index k = 0; k < Index(m_spare_vertices.size()); ++k) m_spare_input.row(k) = m_P.row(m_spare_vertices[k]);
    hold_collapsed_components(0);
  }

  /// Holds each component whose area after `it` steps is below 1e-12 x lambda where the flow
  /// left it: its part of M is lost beside lambda S, whose null space holds the component's
  /// constant vectors, so the factorisation fails or solves for rounding. Its rows of the system
  /// become the identity's and their right-hand side its positions (the components do not
  /// couple, so the pattern and its analysis stay, and the others' steps are those they would
  /// take alone). Its faces may have collapsed too: its rows of the operator, unread, are
  /// assembled from its input positions (Held_input_shown). Not the largest component (whose
  /// input positions are not kept), nor when nothing would be left to move: the flow then ends
  /// as it would without the hold (the errors of the assembly or of the factorisation).
  void hold_collapsed_components(int it)
  {
    if(m_component.empty()) return;
    const auto count = std::size_t(m_components);
    const Component_tally tally = tally_components(m_component, m_components);
    std::vector<char> collapsed(count, 0);
    Index held = 0, total_moving = 0;
    for(std::size_t c = 0; c < count; ++c) {
      total_moving += tally.moving[c];
      if(tally.moving[c] > 0 && Index(c) != m_largest_component && tally.area[c] < 1e-12 * m_s.lambda) {
        collapsed[c] = 1;
        held += tally.moving[c];
      }
    }
    if(held == 0 || held == total_moving) return;
    const Index before = Index(m_held_vertices.size());
    for(Index v = 0; v < m_t.num_vertices; ++v) {
      if(!collapsed[std::size_t(m_component[v])]) continue;
      m_held[v] = 1;
      m_held_vertices.push_back(v);
    }
    const Index total = Index(m_held_vertices.size());
    m_held_positions.conservativeResize(total, 3);
    m_held_input.conservativeResize(total, 3);
    for(Index k = before; k < total; ++k) {
      const Index v = m_held_vertices[std::size_t(k)];
      m_held_positions.row(k) = m_P.row(v);
      const auto spare = std::lower_bound(m_spare_vertices.begin(), m_spare_vertices.end(), v);
      m_held_input.row(k) = m_spare_input.row(Index(spare - m_spare_vertices.begin()));
    }
    for(std::size_t c = 0; c < count; ++c)
      if(collapsed[c]) {
        m_report.collapsed_components.push_back(
          {it, std::size_t(tally.first[c]), std::size_t(tally.size[c]), tally.area[c] / m_s.lambda});
        if(m_s.held_components) m_s.held_components->push_back(m_report.collapsed_components.back());
      }
  }

  /// Per connected component (`component` labels `count` of them): its area at the current
  /// positions (the sum of its faces'), its vertex count, its first vertex, and its vertices that
  /// move (free, not held).
  struct Component_tally
  {
    std::vector<double> area;
    std::vector<Index> size, first, moving;
  };
  Component_tally tally_components(const std::vector<Index>& component, Index count) const
  {
    Component_tally tally;
    tally.area.assign(std::size_t(count), 0.0);
    tally.size.assign(std::size_t(count), 0);
    tally.first.assign(std::size_t(count), -1);
    tally.moving.assign(std::size_t(count), 0);
    for(Index f = 0; f < m_t.num_faces; ++f) {
      const auto [a, b, c] = face_points(m_t, m_P, f);
      tally.area[std::size_t(component[m_t.triangles[3 * f]])] += 0.5 * (b - a).cross(c - a).norm();
    }
    for(Index v = 0; v < m_t.num_vertices; ++v) {
      const auto c = std::size_t(component[v]);
      if(tally.size[c]++ == 0) tally.first[c] = v;
      tally.moving[c] += m_free_mask[v] && (m_held.empty() || !m_held[v]);
    }
    return tally;
  }

  /// While it lives, the held vertices show their input positions (for an assembly or its
  /// checks, which their collapsed faces may fail); then where the flow left them again.
  class Held_input_shown
  {
  public:
    explicit Held_input_shown(Smoothing_worker& w) : m_w(w)
    {
      for(std::size_t k = 0; k < m_w.m_held_vertices.size(); ++k)
        m_w.m_P.row(m_w.m_held_vertices[k]) = m_w.m_held_input.row(Index(k));
    }
    ~Held_input_shown()
    {
      for(std::size_t k = 0; k < m_w.m_held_vertices.size(); ++k)
        m_w.m_P.row(m_w.m_held_vertices[k]) = m_w.m_held_positions.row(Index(k));
    }
    Held_input_shown(const Held_input_shown&) = delete;
    Held_input_shown& operator=(const Held_input_shown&) = delete;

  private:
    Smoothing_worker& m_w;
  };

  /// The free block of the operator's pattern and its symbolic analysis, in the solver's order.
  void analyze_system(int planned_factorizations)
  {
    m_system.emplace(m_pencil.stiffness, m_free_mask);  // an earlier block is destroyed first
    const std::vector<Index> order = m_solver->analyze(m_system->matrix(), planned_factorizations);
    if(!order.empty()) {
      m_system.emplace(m_pencil.stiffness, m_free_mask, order);
      m_solver->analyze_in_order(m_system->matrix());
    }
    if(pattern_may_change()) remember_pattern();
  }

  /// Only the intrinsic Delaunay operator, rebuilt, changes its pattern (its flips follow the
  /// positions); the others keep the topology's, and no copy of it is kept.
  bool pattern_may_change() const { return m_rebuild_stiffness && m_s.laplacian == Laplacian::intrinsic_delaunay; }
  void remember_pattern()
  {
    const auto& S = m_pencil.stiffness;
    m_pattern_outer.assign(S.outerIndexPtr(), S.outerIndexPtr() + S.outerSize() + 1);
    m_pattern_inner.assign(S.innerIndexPtr(), S.innerIndexPtr() + S.nonZeros());
  }
  bool pattern_changed() const
  {
    const auto& S = m_pencil.stiffness;
    return Index(m_pattern_inner.size()) != S.nonZeros() ||
           !std::equal(m_pattern_outer.begin(), m_pattern_outer.end(), S.outerIndexPtr()) ||
           !std::equal(m_pattern_inner.begin(), m_pattern_inner.end(), S.innerIndexPtr());
  }

  /// A flow whose operator follows the positions stops at the first step that collapses a face
  /// or, with Voronoi areas, makes a vertex area non-positive, whether or not another step
  /// follows: the last step's positions get the checks of the next operator's assembly. Not the
  /// intrinsic Delaunay operator: it takes such faces, and its areas are those of its own
  /// triangulation, which is not rebuilt only for a check.
  void check_last_positions()
  {
    if(!m_rebuild || m_s.laplacian == Laplacian::intrinsic_delaunay) return;
    const Held_input_shown shown(*this);  // a held component is not assembled again
    rebuild_operator_after(m_s.iterations, [&] {
      if(m_s.area == Vertex_area::voronoi) {
        // The only kind of area that valid faces can make non-positive. Summed serially: the
        // parallel sums read the corner lists, which release_topology() may have freed.
        require_positive_mass(vertex_areas(m_t, m_P, m_s.area, false), m_s.area);
      } else {
        require_faces_in_range(m_t, m_P, m_s.parallel);
      }
    });
  }

  /// Volume or area restoration; the explicit scheme's divergence check.
  void restore_shape(int it)
  {
    m_restoration->apply(m_t, m_P);
    // The explicit step checks the values it writes; a restoration rescales them, so they are
    // checked again after it.
    if(is_explicit() && !(m_step_finite && (!m_restoration->rescales() || m_P.allFinite()))) {
      take_positions_from_alternate();  // the caller sees the positions that diverged
      throw Numerical_error("explicit smoothing diverged at iteration " + std::to_string(it + 1) + " (lambda " +
                            std::to_string(m_s.lambda) + " is above the stability bound " +
                            std::to_string(m_report.stability_bound) + ")");
    }
  }

  /// P <- P + lambda M^-1 S P on the free vertices.
  void explicit_step()
  {
    const auto t0 = Clock::now();
    const Pencil_arrays S = operator_arrays();
    const Index* outer = S.outer;
    const Index* inner = S.inner;
    const double* values = S.values;
    const Index nonzeros = S.nonzeros();
    const bool alternating = alternates_positions();
    const double* P = m_positions_in_alternate ? m_alternate.data() : m_P.data();
    double* next = !alternating ? m_next.data() : m_positions_in_alternate ? m_P.data() : m_alternate.data();
    // Divergence shows as coordinates that are no longer finite: checked on the values as they
    // are written, which spares a pass over all positions after each step. x - x is zero for a
    // finite x and NaN otherwise, so a part's sum of them stays zero while all are finite.
    std::atomic<bool> finite{true};
    for_each_part(m_t.num_vertices, Index(4096), m_s.parallel, [&](Index, Index first, Index last) {
      double non_finite = 0;
      for(Index i = first; i < last; ++i) {
        const double* p_i = P + 3 * std::size_t(i);
        double* next_i = next + 3 * std::size_t(i);
        if(!m_free_mask[i]) {
          next_i[0] = p_i[0]; next_i[1] = p_i[1]; next_i[2] = p_i[2];
          continue;
        }
        double x = 0, y = 0, z = 0;
        for(Index k = outer[i]; k < outer[i + 1]; ++k) {
          if(k + sparse_gather_prefetch_distance < nonzeros)
            prefetch(P + 3 * std::size_t(inner[k + sparse_gather_prefetch_distance]));
          const double w = values[k];
          const double* p = P + 3 * std::size_t(inner[k]);
          x += w * p[0]; y += w * p[1]; z += w * p[2];
        }
        const double c = m_s.lambda / S.mass[i];
        const double nx = p_i[0] + c * x, ny = p_i[1] + c * y, nz = p_i[2] + c * z;
        next_i[0] = nx;
        next_i[1] = ny;
        next_i[2] = nz;
        non_finite += (nx - nx) + (ny - ny) + (nz - nz);
      }
      if(!(non_finite == 0)) finite.store(false, std::memory_order_relaxed);
    });
    m_step_finite = finite.load();
    if(alternating)
      m_positions_in_alternate = !m_positions_in_alternate;
    else
      m_P.swap(m_next);
    m_report.solve_seconds += seconds_since(t0);
  }

  /// (M - lambda S)_FF, scaled.
  /// The rows of held components are the identity's (hold_collapsed_components()).
  void fill_matrix()
  {
    m_system->fill_matrix(stiffness().valuePtr(), -m_scaled_lambda, m_pencil.mass, m_system_scale);
    if(!m_held_vertices.empty()) m_system->set_identity_rows(m_held);
  }
  /// M_FF P_F + lambda S_FB P_B, scaled as the matrix, into m_B (its padding zero).
  /// The block is kept from step to step: made afresh at every step, a large one faults in its
  /// pages again each time, which costs more than holding it beside the next factorisation.
  void fill_rhs()
  {
    const Index rows = m_system->size(), width = Index(m_solver->row_width(3));
    if(m_B.rows() != rows || m_B.cols() != width) m_B.setZero(rows, width);  // the solves keep the padding zero
    auto rhs = m_B.leftCols<3>();
    m_system->fill_rhs(stiffness(), -m_scaled_lambda, m_pencil.mass, m_system_scale, m_P, rhs, m_s.parallel);
    for(Index v : m_held_vertices)
      if(m_system->is_free(v)) rhs.row(m_system->free_index(v)) = m_P.row(v);
  }

  /// Preconditioned CG (three coordinates as one block with per-column step sizes), warm
  /// started from the current positions, preconditioned by the previous factorisation. False
  /// (and no more tries) when it does not reach the tolerance in 10 iterations.
  bool preconditioned_solve()
  {
    const auto t0 = Clock::now();
    fill_matrix();
    fill_rhs();
    const Index nf = m_system->size();
    Block X(nf, 3);
    m_system->gather(m_P, X);
    const auto Asym = m_system->matrix().selfadjointView<Eigen::Lower>();
    const Block B = m_B.leftCols<3>();
    Block R = B - Asym * X, Z(nf, 3), D(nf, 3), Q(nf, 3);
    const Eigen::RowVector3d bnorm = B.colwise().norm();
    bool ok = m_solver->solve(R, Z);
    D = Z;
    Eigen::RowVector3d rz = (R.cwiseProduct(Z)).colwise().sum();
    int k = 0;
    for(; ok && k < 10; ++k) {
      if(((R.colwise().norm().array()) <= 1e-12 * bnorm.array()).all()) break;
      Q = Asym * D;
      const Eigen::RowVector3d dq = (D.cwiseProduct(Q)).colwise().sum();
      const Eigen::RowVector3d alpha = (dq.array() > 0).select(rz.array() / dq.array(), 0.0);
      X += D * alpha.asDiagonal();
      R -= Q * alpha.asDiagonal();
      ok = m_solver->solve(R, Z);
      const Eigen::RowVector3d rz_new = (R.cwiseProduct(Z)).colwise().sum();
      const Eigen::RowVector3d beta = (rz.array() > 0).select(rz_new.array() / rz.array(), 0.0);
      D = Z + D * beta.asDiagonal();
      rz = rz_new;
    }
    m_report.cg_iterations += 3 * k;
    bool solved = false;
    if(ok && X.allFinite() && ((R.colwise().norm().array()) <= 1e-12 * bnorm.array()).all()) {
      solved = true;
      m_B.leftCols<3>() = X;  // where solve_system() takes the solution from
      ++m_report.preconditioned_solves;
    } else {
      m_try_preconditioned_cg = false;
    }
    m_report.solve_seconds += seconds_since(t0);
    return solved;
  }

  /// Whether step `it` solves with the last operator of the run: none is assembled after it.
  bool is_last_operator(int it) const { return !m_rebuild || it + 1 == m_s.iterations; }

  /// Once no operator is assembled any more, the corner lists and the pattern of a releasable
  /// topology are not read again (the triangles are: shape restoration and the error that names
  /// a collapsed face), so they are not held beside the factorisation.
  void release_topology()
  {
    if(!m_releasable_topology) return;
    m_releasable_topology->release_corner_lists();
    m_releasable_topology->release_pattern();
    m_releasable_topology = nullptr;
  }

  /// Numeric factorisation of the free block for step `it`.
  void factorize(int it)
  {
    const auto t0 = Clock::now();
    fill_matrix();
    // A stiffness that the next step assembles again is not needed until then. Released, it is
    // held neither beside the factorisation's work space nor beside the corner areas of the
    // next assembly (assemble_pencil() frees them before it sizes the stiffness).
    if(m_rebuild_stiffness) release(m_pencil.stiffness);
    m_stiffness_in_factor = nullptr;  // the factorisation writes over it
    if(is_last_operator(it)) m_system->release_fill_map();  // no later step fills the matrix
    const bool ok = m_solver->factorize(m_system->matrix());
    ++m_report.factorizations;
    // M - lambda S is positive definite in exact arithmetic (M > 0, and -S is a sum of
    // positive semidefinite element matrices, negative cotangent weights included), so a
    // failure is numerical: nearly degenerate faces with huge cotangent weights. Name the
    // flattest face, in the words of the zero-area error (positions after `it` steps), unless
    // a connected component shrank so far that its part of M is lost beside lambda S, whose
    // null space holds the component's constant vectors: then no face is to blame.
    if(!ok) {
      if(m_rebuild)
        throw_if_shrunk_to_a_point(it, "the Cholesky factorisation of M - lambda S for the next step failed (" +
                                         m_solver->failure() + "): M is then negligible beside lambda S");
      const auto [face, flatness] = flattest_face(m_t, m_P);
      if(!(flatness < 1e-6))  // no face to blame (a user's solver that failed, say)
        throw Numerical_error("iteration " + std::to_string(it + 1) + ": the factorisation of M - lambda S failed (" +
                              m_solver->failure() + ")");
      char ratio[32];
      std::snprintf(ratio, sizeof ratio, "%.2g", flatness);
      throw Numerical_error(
        "iteration " + std::to_string(it) + ": face " + std::to_string(face) + " is nearly collapsed (area " + ratio +
        " x its longest edge squared; the flow collapsed it), and the Cholesky factorisation of M - "
        "lambda S for the next step failed (" + m_solver->failure() + "): the matrix is positive definite in exact "
        "arithmetic, such faces make it numerically indefinite; a smaller lambda, fewer iterations or a fixed "
        "operator avoid this");
    }
    m_factorized = true;
    m_report.factorization_seconds += seconds_since(t0);
  }

  /// The error of a step that failed after `it` steps (`consequence`: what failed) when a
  /// connected component that moves has an area (its faces') below 1e-12 x lambda: the shrinking
  /// is the cause. Nothing otherwise.
  void throw_if_shrunk_to_a_point(int it, const std::string& consequence) const
  {
    Index components = 0;
    const std::vector<Index> component = connected_component_labels(m_t, &components);
    const Component_tally tally = tally_components(component, components);
    // Among the components that move: a held one does not.
    const std::vector<double>& area = tally.area;
    std::size_t smallest = area.size();
    for(std::size_t c = 0; c < area.size(); ++c)
      if(tally.moving[c] > 0 && (smallest == area.size() || area[c] < area[smallest])) smallest = c;
    if(smallest == area.size() || !(area[smallest] < 1e-12 * m_s.lambda)) return;
    char ratio[32];
    std::snprintf(ratio, sizeof ratio, "%.2g", area[smallest] / m_s.lambda);
    const std::string what = components == 1 ? std::string("the mesh")
                                             : "the connected component of vertex " +
                                                 std::to_string(tally.first[smallest]) + " (" +
                                                 std::to_string(tally.size[smallest]) + " vertices)";
    throw Numerical_error("iteration " + std::to_string(it) + ": the flow shrank " + what +
                          " to nearly a point (its area is " + ratio + " x lambda), and " + consequence +
                          "; a smaller lambda, fewer iterations or a fixed operator avoid this");
  }

  const Mesh_topology& m_t;
  Positions& m_P;
  const Smoothing_settings& m_s;
  Mesh_topology* m_releasable_topology;
  Smoothing_report m_report;
  std::vector<char> m_free_mask;
  // Where holds_collapsed_components() and the mesh has several components: the component
  // labels, the vertices outside the largest component with their input positions, and the held
  // vertices with the positions where the flow left them and their input positions.
  std::vector<Index> m_component;
  Index m_components = 0, m_largest_component = -1;
  std::vector<Index> m_spare_vertices, m_held_vertices;
  std::vector<char> m_held;  ///< per vertex
  Positions m_spare_input, m_held_positions, m_held_input;
  std::optional<Shape_restoration> m_restoration;
  Laplacian_pencil m_pencil;                 ///< (S, M); only M where m_stiffness_values holds S
  Working_array<double> m_stiffness_values;  ///< S on the topology's pattern or on m_operator_* (explicit scheme)
  Working_array<Index> m_operator_outer, m_operator_inner;  ///< S's rows where builds_operator_rows()
  std::vector<char> m_on_boundary;                         ///< their boundary flags
  double* m_stiffness_in_factor = nullptr;   ///< S on the topology's pattern, in the factor's memory
  bool m_rebuild_stiffness = false;
  bool m_rebuild = false;  ///< the operator (or its mass) follows the positions
  // explicit
  Positions m_next;                      ///< the next positions, swapped into m_P after each step
  Working_array<double> m_alternate;     ///< or the other array of the two the steps alternate between
  bool m_positions_in_alternate = false; ///< the latest positions are in m_alternate, not in m_P
  bool m_step_finite = true;  ///< the last explicit step wrote finite positions only
  // implicit / conformal
  std::optional<Constrained_spd_system> m_system;
  std::unique_ptr<Spd_direct_solver> m_solver;
  double m_system_scale = 1, m_scaled_lambda = 0;
  Row_block m_B;  // the right-hand side, then the solution (its columns past the third zero)
  bool m_factorized = false;
  std::vector<Index> m_pattern_outer, m_pattern_inner;  // of the analysed system
  bool m_try_preconditioned_cg = false;
};

/// Smooths P in place. `fixed[i]` != 0 marks a user-constrained vertex; boundary vertices are
/// added here. Throws Mesh_error (non-positive mass, degenerate face), Numerical_error
/// (failed factorisation or solve, non-finite result), std::invalid_argument (settings).
inline Smoothing_report smooth_positions(const Mesh_topology& t, Positions& P, std::vector<char> fixed,
                                         const Smoothing_settings& s)
{
  return Smoothing_worker(t, P, s).run(fixed);
}

/// smooth_positions() for a caller that reads nothing of `t` afterwards: of the implicit
/// schemes' topology only the counts, the triangles and the boundary flags are left once the last
/// operator is assembled.
inline Smoothing_report smooth_positions_releasing_topology(Mesh_topology& t, Positions& P, std::vector<char> fixed,
                                                            const Smoothing_settings& s)
{
  return Smoothing_worker(t, P, s, &t).run(fixed);
}

} // namespace internal
} // namespace lapmesh

#endif
