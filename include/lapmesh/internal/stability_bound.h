// Internal: the explicit scheme's stability bound 2 / mu_max (mu_max the largest eigenvalue of
// -L = -M^-1 S on the free vertices), its cheap Gershgorin lower bound, the free-vertex mask
// they are computed on, and the conversion of a time step given in a unit into lambda.
#ifndef LAPMESH_INTERNAL_STABILITY_BOUND_H
#define LAPMESH_INTERNAL_STABILITY_BOUND_H

#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/parallel.h>
#include <lapmesh/internal/topology.h>
#include <lapmesh/types.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace lapmesh {
namespace internal {

/// The free vertices (1) of a smoothing system: a vertex is fixed (0) when `constrained[i]` != 0
/// (a shorter or empty `constrained` leaves the rest unconstrained) or when it lies on the
/// boundary (`on_boundary[i]` != 0, one flag for each of the n vertices, read only with
/// `fix_boundary`) and `fix_boundary` is set.
inline std::vector<char> free_vertex_mask(Index n, const std::vector<char>& on_boundary, bool fix_boundary,
                                          const std::vector<char>& constrained = {})
{
  std::vector<char> free_mask(static_cast<std::size_t>(n));
  for(Index i = 0; i < n; ++i) {
    const bool fixed = (std::size_t(i) < constrained.size() && constrained[i]) || (fix_boundary && on_boundary[i]);
    free_mask[i] = !fixed;
  }
  return free_mask;
}

/// free_vertex_mask() with the boundary flags of the topology t.
inline std::vector<char> free_vertex_mask(const Mesh_topology& t, bool fix_boundary,
                                          const std::vector<char>& constrained = {})
{
  return free_vertex_mask(t.num_vertices, t.on_boundary, fix_boundary, constrained);
}

/// The arrays of a pencil that the explicit scheme reads: S by compressed rows (S is symmetric,
/// so Eigen's compressed columns serve as rows) and the diagonal of M. Either a
/// Laplacian_pencil's, or stiffness values on the pattern of a topology (the smoothing engine's,
/// kept in a working array).
struct Pencil_arrays
{
  Index size = 0;
  const Index* outer = nullptr;  ///< size + 1 row starts
  const Index* inner = nullptr;
  const double* values = nullptr;
  const double* mass = nullptr;

  /// A compressed pencil's arrays (assembled pencils are compressed).
  /// Implicit, so that a Laplacian_pencil is passed where its arrays are read.
  Pencil_arrays(const Laplacian_pencil& pencil)
    : size(Index(pencil.mass.size())), outer(pencil.stiffness.outerIndexPtr()),
      inner(pencil.stiffness.innerIndexPtr()), values(pencil.stiffness.valuePtr()), mass(pencil.mass.data())
  {
    assert(pencil.stiffness.isCompressed() && pencil.stiffness.rows() == size);
  }
  Pencil_arrays(const Mesh_topology& t, const double* stiffness_values, const Eigen::VectorXd& mass_diagonal)
    : Pencil_arrays(t.num_vertices, t.outer.data(), t.inner.data(), stiffness_values, mass_diagonal)
  {}
  Pencil_arrays(Index rows, const Index* row_ends, const Index* columns, const double* stiffness_values,
                const Eigen::VectorXd& mass_diagonal)
    : size(rows), outer(row_ends), inner(columns), values(stiffness_values), mass(mass_diagonal.data())
  {}
  Index nonzeros() const { return outer ? outer[size] : 0; }
};

/// The largest eigenvalue of a symmetric tridiagonal matrix and the last component of its unit
/// eigenvector (up to sign).
struct Tridiagonal_top
{
  double value = 0, last_component = 1;
};

/// Tridiagonal_top of the matrix of diagonal `a` (m = a.size() entries) and off-diagonal the first
/// m - 1 entries of `b`. The eigenvalue comes from Eigen's QL iteration without vectors; the vector
/// from inverse iteration with a shift just above it, where the shifted matrix is negative definite
/// and its LDL^T needs no pivoting: O(m) a solve, where accumulating every eigenvector costs O(m^3).
inline Tridiagonal_top top_eigenpair_of_tridiagonal(const std::vector<double>& a, const std::vector<double>& b)
{
  const int m = int(a.size());
  assert(m >= 1 && int(b.size()) >= m - 1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
  const Eigen::VectorXd diagonal = Eigen::Map<const Eigen::VectorXd>(a.data(), m);
  const Eigen::VectorXd off_diagonal = Eigen::Map<const Eigen::VectorXd>(b.data(), m - 1);
  es.computeFromTridiagonal(diagonal, off_diagonal, Eigen::EigenvaluesOnly);
  Tridiagonal_top top;
  top.value = es.eigenvalues()[m - 1];
  if(m == 1) return top;
  // The eigenvalue is within a few roundings of the matrix's scale of the true one: a shift of
  // many roundings lies above every eigenvalue and is still far nearer the top one than the next.
  double scale = 0;
  for(int i = 0; i < m; ++i)
    scale = std::max(scale, std::abs(a[std::size_t(i)]) + (i > 0 ? std::abs(b[std::size_t(i) - 1]) : 0.0) +
                              (i + 1 < m ? std::abs(b[std::size_t(i)]) : 0.0));
  const double tiny = std::max(scale, std::numeric_limits<double>::min()) * std::numeric_limits<double>::epsilon();
  const double shift = top.value + 64 * tiny;
  // LDL^T of the shifted matrix (every pivot negative), then two solves from a vector of ones.
  const std::size_t size = std::size_t(m);
  std::vector<double> pivot(size), factor(size), x(size, 1.0);
  for(int i = 0; i < m; ++i) {
    double d = a[std::size_t(i)] - shift;
    if(i > 0) {
      factor[std::size_t(i)] = b[std::size_t(i) - 1] / pivot[std::size_t(i) - 1];
      d -= factor[std::size_t(i)] * b[std::size_t(i) - 1];
    }
    pivot[std::size_t(i)] = d < 0 ? d : -tiny;  // negative in exact arithmetic
  }
  for(int iteration = 0; iteration < 2; ++iteration) {
    for(int i = 1; i < m; ++i) x[std::size_t(i)] -= factor[std::size_t(i)] * x[std::size_t(i) - 1];
    for(int i = 0; i < m; ++i) x[std::size_t(i)] /= pivot[std::size_t(i)];
    for(int i = m - 1; i-- > 0;) x[std::size_t(i)] -= factor[std::size_t(i) + 1] * x[std::size_t(i) + 1];
    double norm = 0;
    for(double v : x) norm = std::max(norm, std::abs(v));
    for(double& v : x) v /= norm;
  }
  double norm_sq = 0;
  for(double v : x) norm_sq += v * v;
  top.last_component = x[std::size_t(m) - 1] / std::sqrt(norm_sq);
  return top;
}

/// What the Lanczos run of top_eigenvalue_of_minus_laplacian() gave, and how it stopped.
struct Top_eigenvalue_estimate
{
  double value = 0;        ///< the top Ritz value plus its residual bound
  int products = 0;        ///< applications of the operator
  bool converged = false;  ///< the residual bound met the tolerance (not stalled, not capped)
};

/// When the Lanczos run for the top eigenvalue stops: its residual bound at `rel_tol` of the Ritz
/// value, or after `max_steps` products, or once the estimate (Ritz value + residual bound) has
/// stayed within a band of `stall_tol` of itself at every check of the last `stall_window`
/// products (`stall_tol` 0: never). The estimate approaches the top eigenvalue from above, so
/// one that has stalled still lies on the safe side. It can pause on its way down and then fall
/// again: a window of several checks, rather than two checks a window apart, lets such a pause
/// pass.
struct Top_eigenvalue_stopping
{
  int max_steps = 400;
  double rel_tol = 1e-9;
  double stall_tol = 2e-4;
  int stall_window = 64;
};

/// Largest eigenvalue of -M_FF^-1 S_FF (the free block of -L), by Lanczos on the symmetric
/// form M^-1/2 (-S) M^-1/2, which has the same spectrum. Extreme Ritz values converge first;
/// no reorthogonalisation is needed for the largest one (ghost copies do not move it). The
/// value is the Ritz value plus its residual bound |beta_k s_k|, so that 2 / value errs on the
/// safe side. `free_mask[i]` = 0 for fixed vertices. The top eigenvalues of the uniform
/// Laplacian (and of any Laplacian on a regular grid) lie close together: there the residual
/// bound shrinks slowly and the stall rule ends the run.
inline Top_eigenvalue_estimate top_eigenvalue_of_minus_laplacian(const Pencil_arrays& pencil,
                                                                 const std::vector<char>& free_mask, bool parallel,
                                                                 const Top_eigenvalue_stopping& stop = {})
{
  const Index n = pencil.size;
  Eigen::VectorXd inv_sqrt_m(n), scaled(n);
  for(Index i = 0; i < n; ++i) inv_sqrt_m[i] = free_mask[i] ? 1.0 / std::sqrt(pencil.mass[i]) : 0.0;
  const Index* outer = pencil.outer;
  const Index* inner = pencil.inner;
  const double* values = pencil.values;
  const Index nonzeros = pencil.nonzeros();
  // The neighbours' values are gathered from one array, scaled beforehand, and prefetched well
  // ahead, as in the explicit step: the gathers miss the caches on a large mesh.
  auto apply = [&](const Eigen::VectorXd& x, Eigen::VectorXd& y) {
    for_each_index(n, parallel, [&](Index i) { scaled[i] = inv_sqrt_m[i] * x[i]; });
    for_each_index(n, parallel, [&](Index i) {
      if(!free_mask[i]) { y[i] = 0; return; }
      double s = 0;
      for(Index k = outer[i]; k < outer[i + 1]; ++k) {
        if(k + sparse_gather_prefetch_distance < nonzeros) prefetch(&scaled[inner[k + sparse_gather_prefetch_distance]]);
        s += values[k] * scaled[inner[k]];
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
  Top_eigenvalue_estimate result;
  const double norm0 = v.norm();
  if(!(norm0 > 0)) return result;
  v /= norm0;
  // The checks come every 8 products; the stall rule reads the checks of the last window.
  constexpr int check_every = 8;
  const int checks_per_window = std::max(1, stop.stall_window / check_every);
  std::vector<double> alpha, beta, checked_estimates;
  for(int k = 0; k < stop.max_steps; ++k) {
    apply(v, w);
    const double a = w.dot(v);
    w -= a * v;
    if(k > 0) w -= beta.back() * v_prev;
    alpha.push_back(a);
    const double b = w.norm();
    // The top Ritz value of the tridiagonal matrix, at each check (O(m^2) each).
    const int m = int(alpha.size());
    result.products = m;
    if(m % check_every != 0 && m != stop.max_steps && !(b <= 1e-14 * std::abs(a))) {
      beta.push_back(b);
      v_prev.swap(v);
      v = w / b;
      continue;
    }
    const Tridiagonal_top top = top_eigenpair_of_tridiagonal(alpha, beta);
    const double theta = top.value;
    const double residual = std::abs(b * top.last_component);
    result.value = theta + residual;
    if(residual <= stop.rel_tol * theta || b <= 1e-14 * std::abs(theta)) {
      result.converged = true;
      break;
    }
    if(m % check_every == 0) {
      checked_estimates.push_back(result.value);
      const std::size_t count = checked_estimates.size(), span = std::size_t(checks_per_window) + 1;
      if(stop.stall_tol > 0 && count >= span) {
        const auto window = std::minmax_element(checked_estimates.end() - std::ptrdiff_t(span), checked_estimates.end());
        if(*window.second - *window.first <= stop.stall_tol * std::abs(result.value)) break;
      }
    }
    beta.push_back(b);
    v_prev.swap(v);
    v = w / b;
  }
  return result;
}

/// 2 / mu for a largest eigenvalue mu of -L; infinity when mu <= 0 (nothing is unstable).
inline double stability_bound_of(double mu) { return mu > 0 ? 2.0 / mu : std::numeric_limits<double>::infinity(); }

/// The explicit scheme's stability bound 2 / mu_max of the pencil on the free vertices
/// (Lanczos estimate, on the safe side).
inline double explicit_stability_bound(const Pencil_arrays& pencil, const std::vector<char>& free_mask,
                                       bool parallel)
{
  return stability_bound_of(top_eigenvalue_of_minus_laplacian(pencil, free_mask, parallel).value);
}

/// Gershgorin on M^-1 S: mu_max <= G = max_i (|S_ii| + sum_j |S_ij|) / M_i over the free
/// vertices, so 2 / G is a lower bound of the stability bound (infinity when G = 0). Below it
/// the explicit scheme is provably stable without the Lanczos estimate.
inline double gershgorin_stability_bound(const Pencil_arrays& pencil, const std::vector<char>& free_mask)
{
  double G = 0;
  for(Index i = 0; i < pencil.size; ++i) {
    if(!free_mask[i]) continue;
    double r = 0;
    for(Index k = pencil.outer[i]; k < pencil.outer[i + 1]; ++k) r += std::abs(pencil.values[k]);
    G = std::max(G, r / pencil.mass[i]);
  }
  return G > 0 ? 2.0 / G : std::numeric_limits<double>::infinity();
}

/// lambda for a time step `value` given in `unit`: value x stability bound, value x (mean edge
/// length)^2 for the cotangent Laplacian (the uniform one's lambda is already dimensionless),
/// or value itself. `mean_edge_length()` and `stability_bound()` are called only when the unit
/// needs them.
template <typename MeanEdgeLength, typename StabilityBound>
double lambda_of_time_step(double value, Time_step_unit unit, Laplacian laplacian, MeanEdgeLength&& mean_edge_length,
                           StabilityBound&& stability_bound)
{
  switch(unit) {
    case Time_step_unit::stability_bound: return value * stability_bound();
    case Time_step_unit::mean_edge_length_squared: {
      if(laplacian == Laplacian::uniform) return value;
      const double h = mean_edge_length();
      return value * h * h;
    }
    case Time_step_unit::absolute: break;
  }
  return value;
}

} // namespace internal
} // namespace lapmesh

#endif
