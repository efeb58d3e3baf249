// Internal: the array-based engine behind laplacian_smoothing.h.
//
// Positions live in an n x 3 row-major matrix; the operator (S, M) is assembled into the
// fixed pattern of the topology (values rewritten in place, never re-allocated). Fixed
// vertices (boundary + user constraints) are Dirichlet constraints: only the free block is
// stepped or solved, the fixed positions are never written, so they stay bitwise equal.
//
// Implicit steps solve (M - lambda S)_FF P'_F = M_FF P_F + lambda S_FB P_B with a sparse
// Cholesky factorisation of the free block (lower triangle only; Spd_direct_solver). Its pattern
// is built once from the topology pattern (an index map slot-of-S -> slot-of-A), the symbolic
// analysis (ordering + elimination tree) is computed once, and each iteration only refactorises
// numerically; the three coordinates are solved against one factorisation. When the matrix
// cannot change (uniform Laplacian, or a fixed operator) it is factorised once.
#ifndef LAPMESH_INTERNAL_SMOOTHING_ENGINE_H
#define LAPMESH_INTERNAL_SMOOTHING_ENGINE_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/cholmod.h>
#include <lapmesh/laplacian.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <optional>
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

/// Largest eigenvalue of -M_FF^-1 S_FF (the free block of -L), by Lanczos on the symmetric
/// form M^-1/2 (-S) M^-1/2, which has the same spectrum. Extreme Ritz values converge first;
/// no reorthogonalisation is needed for the largest one (ghost copies do not move it). The
/// returned value is the Ritz value plus its residual bound |beta_k s_k|, so that 2 / result
/// errs on the safe side. `free_mask[i]` = 0 for fixed vertices.
inline double largest_eigenvalue_of_minus_laplacian(const Laplacian_pencil& pencil,
                                                     const std::vector<char>& free_mask, bool parallel,
                                                     int max_steps = 400, double rel_tol = 1e-9)
{
  const Index n = Index(pencil.mass.size());
  const auto& S = pencil.stiffness;
  Eigen::VectorXd inv_sqrt_m(n);
  for(Index i = 0; i < n; ++i) inv_sqrt_m[i] = free_mask[i] ? 1.0 / std::sqrt(pencil.mass[i]) : 0.0;
  auto apply = [&](const Eigen::VectorXd& x, Eigen::VectorXd& y) {
    for_each_index(n, parallel, [&](Index i) {
      if(!free_mask[i]) { y[i] = 0; return; }
      double s = 0;
      for(Index k = S.outerIndexPtr()[i]; k < S.outerIndexPtr()[i + 1]; ++k) {
        const Index j = S.innerIndexPtr()[k];
        s += S.valuePtr()[k] * inv_sqrt_m[j] * x[j];
      }
      y[i] = -inv_sqrt_m[i] * s;
    });
  };
  // Deterministic start with components on every free vertex.
  Eigen::VectorXd v(n), w(n), v_prev = Eigen::VectorXd::Zero(n);
  std::uint64_t state = 0x9E3779B97F4A7C15ull;
  for(Index i = 0; i < n; ++i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    v[i] = free_mask[i] ? double(state >> 11) / double(1ull << 53) - 0.5 : 0.0;
  }
  const double norm0 = v.norm();
  if(!(norm0 > 0)) return 0.0;
  v /= norm0;
  std::vector<double> alpha, beta;
  double estimate = 0;
  for(int k = 0; k < max_steps; ++k) {
    apply(v, w);
    const double a = w.dot(v);
    w -= a * v;
    if(k > 0) w -= beta.back() * v_prev;
    alpha.push_back(a);
    const double b = w.norm();
    // Ritz values of the tridiagonal matrix, every 8 steps (O(m^2) each).
    const int m = int(alpha.size());
    if(m % 8 != 0 && m != max_steps && !(b <= 1e-14 * std::abs(a))) {
      beta.push_back(b);
      v_prev.swap(v);
      v = w / b;
      continue;
    }
    Eigen::VectorXd diag = Eigen::Map<const Eigen::VectorXd>(alpha.data(), m);
    Eigen::VectorXd sub(std::max(m - 1, 1));
    for(int r = 0; r + 1 < m; ++r) sub[r] = beta[r];
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
    es.computeFromTridiagonal(diag, sub.head(std::max(m - 1, 0)), Eigen::ComputeEigenvectors);
    const double theta = es.eigenvalues()[m - 1];
    const double residual = std::abs(b * es.eigenvectors()(m - 1, m - 1));
    estimate = theta + residual;
    if(residual <= rel_tol * theta || b <= 1e-14 * std::abs(theta)) break;
    beta.push_back(b);
    v_prev.swap(v);
    v = w / b;
  }
  return estimate;
}

/// The three corner positions of face f.
inline std::array<Eigen::Vector3d, 3> face_points(const Mesh_topology& t, const Positions& P, Index f)
{
  return {P.row(t.triangles[3 * f]).transpose(), P.row(t.triangles[3 * f + 1]).transpose(),
          P.row(t.triangles[3 * f + 2]).transpose()};
}

/// Signed enclosed volume (divergence theorem) and volume centroid of a closed mesh.
inline void volume_and_centroid(const Mesh_topology& t, const Positions& P, double& volume, Eigen::Vector3d& centroid)
{
  double V = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for(Index f = 0; f < t.num_faces; ++f) {
    const auto [a, b, d] = face_points(t, P, f);
    const double v6 = a.dot(b.cross(d));  // 6 x volume of the tetrahedron (0, a, b, d)
    V += v6;
    c += v6 * (a + b + d);
  }
  volume = V / 6.0;
  centroid = V != 0 ? Eigen::Vector3d(c / (4.0 * V)) : Eigen::Vector3d::Zero();
}

/// Surface area and area centroid (area-weighted mean of the face centroids).
inline void area_and_centroid(const Mesh_topology& t, const Positions& P, double& area, Eigen::Vector3d& centroid)
{
  double A = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for(Index f = 0; f < t.num_faces; ++f) {
    const auto [a, b, d] = face_points(t, P, f);
    const double af = 0.5 * (b - a).cross(d - a).norm();
    A += af;
    c += af * (a + b + d) / 3.0;
  }
  area = A;
  centroid = A > 0 ? Eigen::Vector3d(c / A) : Eigen::Vector3d::Zero();
}

/// Undoes the shrinkage of a flow after each step: a uniform scaling about the current centroid
/// back to the initial enclosed volume (closed meshes) or surface area, and a translation back
/// to the initial centroid. It moves every vertex, so it needs a mesh without fixed vertices.
class Shape_restoration
{
public:
  enum class Measure { none, volume, area };

  Shape_restoration(Measure measure, const Mesh_topology& t, const Positions& P) : m_measure(measure)
  {
    if(m_measure == Measure::none) return;
    measure_of(t, P, m_measure0, m_centroid0);
    if(!(std::abs(m_measure0) > 0))
      throw Mesh_error(m_measure == Measure::volume ? "volume restoration: the mesh encloses no volume"
                                                    : "area restoration: the mesh has no area");
  }
  void apply(const Mesh_topology& t, Positions& P) const
  {
    if(m_measure == Measure::none) return;
    double value;
    Eigen::Vector3d c;
    measure_of(t, P, value, c);
    const double f = m_measure == Measure::volume ? std::cbrt(m_measure0 / value) : std::sqrt(m_measure0 / value);
    for(Index i = 0; i < P.rows(); ++i) P.row(i) = (P.row(i) - c.transpose()) * f + m_centroid0.transpose();
  }

private:
  void measure_of(const Mesh_topology& t, const Positions& P, double& value, Eigen::Vector3d& c) const
  {
    if(m_measure == Measure::volume)
      volume_and_centroid(t, P, value, c);
    else
      area_and_centroid(t, P, value, c);
  }
  Measure m_measure;
  double m_measure0 = 0;
  Eigen::Vector3d m_centroid0 = Eigen::Vector3d::Zero();
};

#ifdef LAPMESH_HAS_CHOLMOD
/// CHOLMOD's last warning or error on this thread. CHOLMOD reports through a C callback
/// without user data, so the message is kept per thread until the caller turns it into a
/// lapmesh exception.
inline std::string& last_cholmod_message()
{
  static thread_local std::string message;
  return message;
}
inline void record_cholmod_message(int status, const char* /*file*/, int /*line*/, const char* message)
{
  last_cholmod_message() = std::string(status > 0 ? "warning " : "error ") + std::to_string(status) + ": " +
                           (message ? message : "(no message)");
}
/// CHOLMOD prints its warnings itself (on stdout, by default) unless told not to: lapmesh
/// reports them in its own exceptions instead.
inline void route_cholmod_messages(cholmod_common& common)
{
  common.print = 0;
  common.error_handler = &record_cholmod_message;
}
#endif

/// Sparse Cholesky of an SPD matrix given by its lower triangle: Eigen's SimplicialLDLT (AMD),
/// or, when compiled with LAPMESH_HAS_CHOLMOD (and linked with libcholmod), CHOLMOD's
/// supernodal LL^T (internal/cholmod.h). Ordering: AMD, or CHOLMOD's choice between AMD and
/// METIS when the analysis serves at least `automatic_ordering_min_factorizations`
/// factorisations. Measured (serial CHOLMOD, OpenBLAS): on a 250k-vertex torus METIS orders in
/// 1.07 s against AMD's 0.10 s and factorises in 0.41 s against 0.56 s (2.5x fewer flops), so
/// it pays from about 6 factorisations; on a Loop-subdivided 280k-vertex scan it saves no time
/// (0.30 s both), and CHOLMOD's rule keeps AMD there.
class Spd_direct_solver
{
public:
  using SpMat = Eigen::SparseMatrix<double>;
  /// A user's solver (CGAL's `sparse_linear_solver`): factorises the full symmetric matrix,
  /// then solves one right-hand side block.
  struct External
  {
    std::function<bool(const SpMat& full)> factor;
    std::function<bool(const Eigen::MatrixXd& B, Eigen::MatrixXd& X)> solve;
  };

  explicit Spd_direct_solver(bool use_cholmod, External external = {}) : m_external(std::move(external))
  {
#ifdef LAPMESH_HAS_CHOLMOD
    m_cholmod = use_cholmod;
    route_cholmod_messages(m_chol.cholmod());
#else
    (void)use_cholmod;
#endif
  }
  const char* name() const
  {
    return m_external.factor ? "sparse_linear_solver" : m_cholmod ? "cholmod-supernodal" : "eigen-ldlt";
  }

  static constexpr int automatic_ordering_min_factorizations = 6;

  void analyze(const SpMat& A, int planned_factorizations)
  {
    if(m_external.factor) return;  // the user's solver analyses in its factor()
#ifdef LAPMESH_HAS_CHOLMOD
    if(m_cholmod) {
      using Ordering = Cholmod_supernodal_llt::Ordering;
      const bool automatic = planned_factorizations >= automatic_ordering_min_factorizations;
      m_chol.set_ordering(automatic ? Ordering::automatic : Ordering::amd);
      m_chol.analyzePattern(A);
      if(m_chol.info() != Eigen::Success && automatic) {  // METIS failed (or is missing): AMD alone
        m_chol.set_ordering(Ordering::amd);
        m_chol.analyzePattern(A);
      }
      if(m_chol.info() != Eigen::Success) throw Numerical_error("the symbolic analysis (CHOLMOD) of the smoothing system failed");
      return;
    }
#endif
    (void)planned_factorizations;
    m_ldlt.analyzePattern(A);
    if(m_ldlt.info() != Eigen::Success) throw Numerical_error("the symbolic analysis of the smoothing system failed");
  }
  /// False if the matrix is not (numerically) positive definite; failure() then says why.
  bool factorize(const SpMat& A)
  {
    m_failure.clear();
    if(m_external.factor) {
      const bool ok = m_external.factor(SpMat(A.selfadjointView<Eigen::Lower>()));
      if(!ok) m_failure = "the user's sparse_linear_solver failed";
      return ok;
    }
#ifdef LAPMESH_HAS_CHOLMOD
    if(m_cholmod) {
      last_cholmod_message().clear();
      m_chol.factorize(A);
      if(m_chol.info() == Eigen::Success) return true;
      m_failure = "CHOLMOD " + (last_cholmod_message().empty() ? std::string("reported a numerical issue")
                                                                 : last_cholmod_message());
      return false;
    }
#endif
    m_ldlt.factorize(A);
    if(m_ldlt.info() == Eigen::Success && m_ldlt.vectorD().minCoeff() > 0) return true;
    m_failure = "Eigen's LDL^T found a pivot <= 0";
    return false;
  }
  /// Why the last factorize() failed (empty after a success).
  const std::string& failure() const { return m_failure; }
  template <typename Rhs, typename Solution>
  bool solve(const Rhs& B, Solution& X)
  {
    if(m_external.solve) {
      Eigen::MatrixXd x;
      if(!m_external.solve(Eigen::MatrixXd(B), x) || x.rows() != B.rows() || x.cols() != B.cols()) return false;
      X = x;
      return true;
    }
#ifdef LAPMESH_HAS_CHOLMOD
    if(m_cholmod) {
      X = m_chol.solve(B);
      return m_chol.info() == Eigen::Success;
    }
#endif
    X = m_ldlt.solve(B);
    return m_ldlt.info() == Eigen::Success;
  }

private:
  External m_external;
  std::string m_failure;
  bool m_cholmod = false;
  Eigen::SimplicialLDLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int>> m_ldlt;
#ifdef LAPMESH_HAS_CHOLMOD
  Cholmod_supernodal_llt m_chol;
#endif
};

struct Smoothing_settings
{
  Smoothing_scheme scheme = Smoothing_scheme::implicit_euler;
  Laplacian laplacian = Laplacian::cotangent;
  Vertex_area area = Vertex_area::barycentric;
  double lambda = 0;
  int iterations = 1;
  bool fixed_operator = false;
  bool restore_volume = false;
  bool restore_area = false;  ///< area and area centroid, after each step (no fixed vertices)
  bool fix_boundary = true;   ///< false: boundary vertices move (natural Neumann condition)
  bool parallel = false;
  bool compute_stability_bound = false;  ///< always run Lanczos for the explicit scheme
  bool use_cholmod = true;               ///< with LAPMESH_HAS_CHOLMOD: CHOLMOD supernodal LL^T
  /// Rebuilt operator: solve with conjugate gradients preconditioned by the last Cholesky
  /// factor (relative residual 1e-12) and refactorise only when that needs > 10 iterations
  /// (after the first such failure, refactorise directly for the remaining steps).
  bool reuse_factorization = false;
  std::function<void(int, int)> progress;  ///< called after each iteration (done, total)
  Spd_direct_solver::External external_solver;  ///< set: used instead of CHOLMOD / Eigen LDL^T
};

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
                                std::to_string(s.lambda) + ")");
  if(s.iterations <= 0)
    throw std::invalid_argument("the number of iterations must be positive (got " + std::to_string(s.iterations) + ")");
}

/// Smooths P in place. `fixed[i]` != 0 marks a user-constrained vertex; boundary vertices are
/// added here. Throws Mesh_error (non-positive mass, degenerate face), Numerical_error
/// (failed factorisation or solve, non-finite result), std::invalid_argument (settings).
inline Smoothing_report smooth_positions(const Mesh_topology& t, Positions& P, std::vector<char> fixed,
                                         const Smoothing_settings& s)
{
  check_settings(s);
  const Index n = t.num_vertices;
  fixed.resize(n, 0);
  for(Index i = 0; i < n; ++i) fixed[i] = fixed[i] || (s.fix_boundary && t.on_boundary[i]);
  std::vector<char> free_mask(n);
  std::vector<Index> fid(n, -1);
  Index nf = 0;
  for(Index i = 0; i < n; ++i) {
    free_mask[i] = !fixed[i];
    if(!fixed[i]) fid[i] = nf++;
  }

  Smoothing_report report;
  report.free_vertices = std::size_t(nf);
  if(s.restore_volume && s.restore_area)
    throw std::invalid_argument("restore the volume or the area, not both");
  if(s.restore_volume && (nf != n || t.num_boundary_edges != 0))
    throw std::invalid_argument("volume restoration needs a closed mesh without constrained vertices "
                                "(it rescales the whole mesh, which would move fixed vertices)");
  if(s.restore_area && nf != n) {
    if(t.num_boundary_edges != 0 && s.fix_boundary)
      throw Parameter_error("fix_boundary", "area restoration rescales the whole mesh, so no vertex may be fixed (the "
                                            "boundary is fixed: free it with fix_boundary(false))", "false");
    throw std::invalid_argument("area restoration rescales the whole mesh, so no vertex may be fixed (there are "
                                "constrained vertices)");
  }
  const Shape_restoration restoration(s.restore_volume ? Shape_restoration::Measure::volume
                                      : s.restore_area ? Shape_restoration::Measure::area
                                                       : Shape_restoration::Measure::none,
                                      t, P);

  Laplacian_pencil pencil;
  auto t0 = Clock::now();
  assemble_pencil(t, P, s.laplacian, s.area, s.parallel, pencil);
  if(s.laplacian == Laplacian::cotangent) require_positive_mass(pencil.mass, s.area);
  report.assembly_seconds += seconds_since(t0);

  const bool geometric = s.laplacian == Laplacian::cotangent;
  // What must be recomputed each iteration from the current positions.
  const bool rebuild_stiffness = geometric && !s.fixed_operator && s.scheme != Smoothing_scheme::conformal;
  const bool rebuild_mass = geometric && !s.fixed_operator;

  if(s.scheme == Smoothing_scheme::explicit_euler) {
    // Gershgorin on M^-1 S: mu_max <= max_i (|S_ii| + sum_j |S_ij|) / M_i. Below 2/G the
    // scheme is provably stable and the Lanczos estimate is not needed.
    double G = 0;
    for(Index i = 0; i < n; ++i) {
      if(!free_mask[i]) continue;
      double r = 0;
      for(Index k = pencil.stiffness.outerIndexPtr()[i]; k < pencil.stiffness.outerIndexPtr()[i + 1]; ++k)
        r += std::abs(pencil.stiffness.valuePtr()[k]);
      G = std::max(G, r / pencil.mass[i]);
    }
    const double gershgorin = G > 0 ? 2.0 / G : std::numeric_limits<double>::infinity();
    if(s.compute_stability_bound || s.lambda > gershgorin) {
      const double mu = largest_eigenvalue_of_minus_laplacian(pencil, free_mask, s.parallel);
      report.stability_bound = mu > 0 ? 2.0 / mu : std::numeric_limits<double>::infinity();
      report.stability_bound_exact = true;
    } else {
      report.stability_bound = gershgorin;
    }
    report.above_stability_bound = s.lambda > report.stability_bound;
  }

  const auto& S = pencil.stiffness;
  const Index* outer = S.outerIndexPtr();
  const Index* inner = S.innerIndexPtr();

  // ---- explicit ----
  if(s.scheme == Smoothing_scheme::explicit_euler) {
    Positions next(P.rows(), 3);
    for(int it = 0; it < s.iterations; ++it) {
      if(it > 0 && rebuild_stiffness) {
        t0 = Clock::now();
        rebuild_operator_after(it, [&] {
          assemble_pencil(t, P, s.laplacian, s.area, s.parallel, pencil);
          require_positive_mass(pencil.mass, s.area);
        });
        report.assembly_seconds += seconds_since(t0);
      }
      t0 = Clock::now();
      const double* values = S.valuePtr();
      for_each_index(n, s.parallel, [&](Index i) {
        if(!free_mask[i]) { next.row(i) = P.row(i); return; }
        double x = 0, y = 0, z = 0;
        for(Index k = outer[i]; k < outer[i + 1]; ++k) {
          const double w = values[k];
          const double* p = P.data() + 3 * std::size_t(inner[k]);
          x += w * p[0]; y += w * p[1]; z += w * p[2];
        }
        const double c = s.lambda / pencil.mass[i];
        next(i, 0) = P(i, 0) + c * x;
        next(i, 1) = P(i, 1) + c * y;
        next(i, 2) = P(i, 2) + c * z;
      });
      P.swap(next);
      report.solve_seconds += seconds_since(t0);
      restoration.apply(t, P);
      if(!P.allFinite())
        throw Numerical_error("explicit smoothing diverged at iteration " + std::to_string(it + 1) +
                              " (lambda " + std::to_string(s.lambda) + " is above the stability bound " +
                              std::to_string(report.stability_bound) + ")");
      ++report.iterations;
      if(s.progress) s.progress(it + 1, s.iterations);
    }
    return report;
  }

  // ---- implicit / conformal: pattern of the lower triangle of the free block ----
  t0 = Clock::now();
  using SpMat = Eigen::SparseMatrix<double>;
  SpMat A(nf, nf);
  std::vector<Index> a_source;   // slot of S feeding each slot of A
  std::vector<Index> a_diagonal(nf);
  {
    std::vector<Index> a_outer(nf + 1, 0), a_inner;
    a_inner.reserve(std::size_t(S.nonZeros()) / 2 + nf);
    a_source.reserve(a_inner.capacity());
    for(Index j = 0; j < n; ++j) {
      if(!free_mask[j]) continue;
      for(Index k = outer[j]; k < outer[j + 1]; ++k) {  // column j = row j (symmetric pattern)
        const Index i = inner[k];
        if(i < j || !free_mask[i]) continue;
        if(i == j) a_diagonal[fid[j]] = Index(a_inner.size());
        a_inner.push_back(fid[i]);
        a_source.push_back(k);
      }
      a_outer[fid[j] + 1] = Index(a_inner.size());
    }
    A.resizeNonZeros(Index(a_inner.size()));
    std::copy(a_outer.begin(), a_outer.end(), A.outerIndexPtr());
    std::copy(a_inner.begin(), a_inner.end(), A.innerIndexPtr());
  }
  // The system (M - lambda S) X = M P is divided by a power of four near the mean mass: on
  // meshes of extreme scale M P would overflow (or underflow) although the solution is
  // representable. Dividing by an even power of two is exact, down to the square roots of the
  // Cholesky factor, so the solution is bitwise that of the unscaled system.
  int mass_exponent = 0;
  std::frexp(pencil.mass.mean(), &mass_exponent);
  const double system_scale = std::ldexp(1.0, -2 * (mass_exponent / 2));
  const double scaled_lambda = s.lambda * system_scale;

  const int planned_factorizations = (rebuild_stiffness || rebuild_mass) ? s.iterations : 1;
  Spd_direct_solver solver(s.use_cholmod, s.external_solver);
  solver.analyze(A, planned_factorizations);
  report.solver = solver.name();
  report.analysis_seconds += seconds_since(t0);

  Eigen::Matrix<double, Eigen::Dynamic, 3> B(nf, 3), X(nf, 3);
  bool factorized = false;
  // Preconditioned CG is tried until it fails once: then the operator changes too fast for an old
  // factor (measured on Loop-subdivided scans at one mean edge length squared: every step failed
  // after 10 CG iterations and was refactorised anyway, 3x slower than refactorising directly).
  bool try_preconditioned_cg = s.reuse_factorization;
  for(int it = 0; it < s.iterations; ++it) {
    if(it > 0 && (rebuild_stiffness || rebuild_mass)) {
      t0 = Clock::now();
      rebuild_operator_after(it, [&] {
        if(rebuild_stiffness) {
          assemble_pencil(t, P, s.laplacian, s.area, s.parallel, pencil);
        } else {
          pencil.mass = vertex_areas(t, P, s.area, s.parallel);
        }
        require_positive_mass(pencil.mass, s.area);
      });
      report.assembly_seconds += seconds_since(t0);
      factorized = false;
    }
    const double* values = S.valuePtr();
    auto fill_matrix = [&] {
      double* a = A.valuePtr();
      const Index na = A.nonZeros();
      for(Index k = 0; k < na; ++k) a[k] = -scaled_lambda * values[a_source[k]];
      for(Index i = 0; i < n; ++i)
        if(free_mask[i]) a[a_diagonal[fid[i]]] += pencil.mass[i] * system_scale;
    };
    auto fill_rhs = [&] {  // M_FF P_F + lambda S_FB P_B, scaled as the matrix
      for_each_index(n, s.parallel, [&](Index i) {
        if(!free_mask[i]) return;
        Eigen::Vector3d b = (pencil.mass[i] * system_scale) * P.row(i).transpose();
        for(Index k = outer[i]; k < outer[i + 1]; ++k)
          if(!free_mask[inner[k]]) b += scaled_lambda * values[k] * P.row(inner[k]).transpose();
        B.row(fid[i]) = b.transpose();
      });
    };
    bool solved = false;
    if(!factorized && try_preconditioned_cg && report.factorizations > 0) {
      // Preconditioned CG (three coordinates as one block with per-column step sizes), warm
      // started from the current positions, preconditioned by the previous factorisation.
      t0 = Clock::now();
      fill_matrix();
      fill_rhs();
      for(Index i = 0; i < n; ++i)
        if(free_mask[i]) X.row(fid[i]) = P.row(i);
      const auto Asym = A.selfadjointView<Eigen::Lower>();
      Eigen::Matrix<double, Eigen::Dynamic, 3> R = B - Asym * X, Z(nf, 3), D(nf, 3), Q(nf, 3);
      const Eigen::RowVector3d bnorm = B.colwise().norm();
      bool ok = solver.solve(R, Z);
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
        ok = solver.solve(R, Z);
        const Eigen::RowVector3d rz_new = (R.cwiseProduct(Z)).colwise().sum();
        const Eigen::RowVector3d beta = (rz.array() > 0).select(rz_new.array() / rz.array(), 0.0);
        D = Z + D * beta.asDiagonal();
        rz = rz_new;
      }
      report.cg_iterations += 3 * k;
      if(ok && X.allFinite() && ((R.colwise().norm().array()) <= 1e-12 * bnorm.array()).all()) {
        solved = true;
        ++report.preconditioned_solves;
      } else {
        try_preconditioned_cg = false;
      }
      report.solve_seconds += seconds_since(t0);
    }
    if(!factorized && !solved) {
      t0 = Clock::now();
      fill_matrix();
      const bool ok = solver.factorize(A);
      ++report.factorizations;
      // M - lambda S is positive definite in exact arithmetic (M > 0, and -S is a sum of
      // positive semidefinite element matrices, negative cotangent weights included), so a
      // failure is numerical: nearly degenerate faces with huge cotangent weights. Name the
      // flattest face, in the words of the zero-area error (positions after `it` steps).
      if(!ok) {
        const auto [face, flatness] = flattest_face(t, P);
        if(!(flatness < 1e-6))  // no face to blame (a user's solver that failed, say)
          throw Numerical_error("iteration " + std::to_string(it + 1) + ": the factorisation of M - lambda S failed (" +
                                solver.failure() + ")");
        char ratio[32];
        std::snprintf(ratio, sizeof ratio, "%.2g", flatness);
        throw Numerical_error(
          "iteration " + std::to_string(it) + ": face " + std::to_string(face) + " is nearly collapsed (area " +
          ratio + " x its longest edge squared; the flow collapsed it), and the Cholesky factorisation of M - "
          "lambda S for the next step failed (" + solver.failure() + "): the matrix is positive definite in exact "
          "arithmetic, such faces make it numerically indefinite; a smaller lambda, fewer iterations or a fixed "
          "operator avoid this");
      }
      factorized = true;
      report.factorization_seconds += seconds_since(t0);
    }
    t0 = Clock::now();
    if(!solved) {
      fill_rhs();
      if(!solver.solve(B, X) || !X.allFinite())
        throw Numerical_error("the linear solve of the smoothing system failed at iteration " + std::to_string(it + 1));
    }
    for(Index i = 0; i < n; ++i)
      if(free_mask[i]) P.row(i) = X.row(fid[i]);
    report.solve_seconds += seconds_since(t0);
    restoration.apply(t, P);
    ++report.iterations;
    if(s.progress) s.progress(it + 1, s.iterations);
  }
  return report;
}

/// Mean length of the edges (each edge counted once).
inline double mean_edge_length(const Mesh_topology& t, const Positions& P)
{
  double sum = 0;
  std::size_t count = 0;
  for(Index i = 0; i < t.num_vertices; ++i)
    for(Index k = t.outer[i]; k < t.outer[i + 1]; ++k) {
      const Index j = t.inner[k];
      if(j <= i) continue;
      sum += (P.row(i) - P.row(j)).norm();
      ++count;
    }
  return count ? sum / double(count) : 0.0;
}

} // namespace internal
} // namespace lapmesh

#endif
