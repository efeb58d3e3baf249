// lapmesh — the eigen-solver behind Spectral_basis: the k smallest eigenpairs of the
// symmetric pencil -S phi = lambda M phi with M diagonal and positive.
//
// Method. With M diagonal the pencil is the standard symmetric problem
//   A y = lambda y,  A = M^-1/2 (-S) M^-1/2,  phi = M^-1/2 y,
// so Euclidean-orthonormal y give M-orthonormal phi. A Krylov method runs on the shift-invert
// operator (A - sigma I)^-1 = M^1/2 K^-1 M^1/2 with K = -S - sigma M, factorised once by a
// sparse Cholesky (CHOLMOD's supernodal LL^T when LAPMESH_HAS_CHOLMOD is defined, else Eigen's
// SimplicialLLT). The Krylov method is, by default, lapmesh's thick-restart block Lanczos
// (internal/block_lanczos.h: blocks of 8 triangular solves read the factor once), or Spectra's
// SymEigsShiftSolver (implicitly restarted single-vector Lanczos), selectable; both are tested
// against each other. The B-inner products of a generalized mode disappear.
//
// Shift. sigma = -shift_factor / sum(M) (default shift_factor = 1e-2), i.e. slightly below
// zero on the scale of the smallest non-zero eigenvalue (lambda_1 ~ 25 / area on a sphere-like
// surface): K is then symmetric positive definite even on closed meshes, where -S is
// singular, and the eigenvalues nearest to sigma are the smallest ones. When the wanted ones
// crowd together far above it (a dense band of distinct values), a first block Lanczos run is
// given up after a few restarts, and a second runs from a shift just below the band, located by
// inertia counts (Crowding_watch, reshifted_eigenpairs()).
//
// Completeness. Krylov solvers can drop a member of a repeated eigenvalue. The solver asks
// for k + extra pairs, picks tau in the first spectral gap at or above lambda_{k-1}, and
// counts the eigenvalues below tau exactly by Sylvester's law of inertia: the number of
// negative pivots of the LDL^T factorisation of -S - tau M. A mismatch triggers a retry with
// more extra pairs, then a Numerical_error: never a silent partial basis.
//
// Null space. On a mesh of c > 1 connected components lambda = 0 has multiplicity c, and the
// indicator of each component is an exact null vector of -S (rows sum to zero). Computed by
// Krylov, these c values are round-off around 0: with c >= k the cluster of lambda_{k-1} was
// split at a spurious gap, and the inertia check put tau inside it, where -S - tau M is
// singular to working precision (CAD meshes have dozens to hundreds of components). The solver
// therefore takes the null space exactly (the M-normalised indicators, lambda = 0), runs the
// Krylov method on its M-orthogonal complement (the right-hand sides lose their component sums,
// the solutions their M-weighted component means), and checks by inertia that exactly c
// eigenvalues lie below the first gap above 0. A connected mesh (c = 1) is solved as before.
#ifndef LAPMESH_INTERNAL_SPECTRAL_SOLVER_H
#define LAPMESH_INTERNAL_SPECTRAL_SOLVER_H

#include <lapmesh/errors.h>
#include <lapmesh/types.h>
#include <lapmesh/internal/block_lanczos.h>
#include <lapmesh/internal/memory.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <lapmesh/internal/cholmod.h>
#include <lapmesh/internal/component_copies.h>
#include <lapmesh/internal/supernodal_ldlt.h>
#include <lapmesh/internal/union_find.h>

#include <Spectra/SymEigsShiftSolver.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace lapmesh {

namespace internal {

/// y = M^1/2 K^-1 M^1/2 x, the shift-invert operator of the standardised problem.
template <typename Factor>
class Spectral_shift_invert_op
{
public:
  using Scalar = double;
  Spectral_shift_invert_op(const Factor& f, const Eigen::VectorXd& sqrt_mass,
                           const std::function<void(long long)>& on_op)
    : m_factor(f), m_sqrt_mass(sqrt_mass), m_b(sqrt_mass.size()), m_on_op(on_op)
  {}
  Eigen::Index rows() const { return m_sqrt_mass.size(); }
  Eigen::Index cols() const { return m_sqrt_mass.size(); }
  void set_shift(double) {}
  void perform_op(const double* x_in, double* y_out) const
  {
    const Eigen::Index n = m_sqrt_mass.size();
    Eigen::Map<const Eigen::VectorXd> x(x_in, n);
    Eigen::Map<Eigen::VectorXd> y(y_out, n);
    m_b = m_sqrt_mass.cwiseProduct(x);
    y = m_factor.solve(m_b);
    y.array() *= m_sqrt_mass.array();
    ++m_ops;
    if(m_on_op) m_on_op(m_ops);
  }
  long long operations() const { return m_ops; }

private:
  const Factor& m_factor;
  const Eigen::VectorXd& m_sqrt_mass;
  mutable Eigen::VectorXd m_b;
  mutable long long m_ops = 0;
  const std::function<void(long long)>& m_on_op;
};

/// The null space of -S on a mesh of several connected components (see "Null space" above):
/// the components of the graph of S's non-zero off-diagonal entries, when there are at least
/// `min_components` and every row of S sums to zero to round-off. Inactive (count() == 0)
/// otherwise: by default a connected mesh, or a pencil whose stiffness is not a Laplacian
/// (from_pencil accepts any).
class Null_space_deflation
{
public:
  Null_space_deflation() = default;
  /// `stiffness` is S (or -S: the components and the row sums do not depend on the sign).
  Null_space_deflation(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass,
                       Eigen::Index min_components = 2)
  {
    const Eigen::Index n = stiffness.rows();
    if(!rows_sum_to_zero(stiffness)) return;  // not a Laplacian: no known null space
    Smallest_root_sets<int> components(static_cast<int>(n));  // S's indices are int
    for(Eigen::Index j = 0; j < stiffness.outerSize(); ++j)
      for(Eigen::SparseMatrix<double>::InnerIterator it(stiffness, j); it; ++it)
        if(it.value() != 0 && it.index() != j) components.join(int(it.index()), int(j));
    int c = 0;
    const std::vector<int> label = components.labels(c);
    m_component = Eigen::Map<const Eigen::VectorXi>(label.data(), n);
    if(c < std::max<Eigen::Index>(min_components, 1)) {
      m_component.resize(0);
      return;
    }
    m_mass = Eigen::VectorXd::Zero(c);
    for(Eigen::Index v = 0; v < n; ++v) m_mass[m_component[v]] += mass[v];
  }
  /// The dimension of the deflated null space (0: inactive).
  Eigen::Index count() const { return m_mass.size(); }
  /// B <- B - M 1_C (1_C^T B) / m_C for every component C: the right-hand sides of K u = B lose
  /// their null-space loads (K = -S - sigma M maps null vectors onto M 1_C).
  void remove_loads(Eigen::Ref<Eigen::MatrixXd> B, const Eigen::VectorXd& mass) const
  {
    subtract_component_sums(B, [](Eigen::Index) { return 1.0; }, [&](Eigen::Index v) { return mass[v]; });
  }
  /// U <- U - 1_C (1_C^T M U) / m_C for every component C: M-orthogonal to the null space.
  void remove_means(Eigen::Ref<Eigen::MatrixXd> U, const Eigen::VectorXd& mass) const
  {
    subtract_component_sums(U, [&](Eigen::Index v) { return mass[v]; }, [](Eigen::Index) { return 1.0; });
  }
  /// x <- x - q_C (q_C^T x) for every component C, q_C = M^(1/2) 1_C / sqrt(m_C): the null
  /// space removed from a vector of the Krylov runs' symmetric form, x = M^(1/2) u.
  void remove_from_symmetric_form(Eigen::Ref<Eigen::VectorXd> x, const Eigen::VectorXd& sqrt_mass) const
  {
    remove_from_symmetric_block(Eigen::Map<Eigen::MatrixXd>(x.data(), x.size(), 1), sqrt_mass);
  }
  /// remove_from_symmetric_form() for every column of X.
  void remove_from_symmetric_block(Eigen::Ref<Eigen::MatrixXd> X, const Eigen::VectorXd& sqrt_mass) const
  {
    const auto weight = [&](Eigen::Index v) { return sqrt_mass[v]; };
    subtract_component_sums(X, weight, weight);
  }
  /// The same null space for vectors whose row i is row order[i] of the matrix's (a Krylov run in
  /// a factor's row order); its vertex weights are then given in that order too.
  Null_space_deflation in_order(const int* order) const
  {
    Null_space_deflation d;
    d.m_mass = m_mass;
    d.m_component.resize(m_component.size());
    for(Eigen::Index i = 0; i < m_component.size(); ++i) d.m_component[i] = m_component[order[i]];
    return d;
  }
  /// The null space's M-orthonormal basis: column C is 1_C / sqrt(m_C).
  Eigen::MatrixXd null_vectors() const
  {
    Eigen::MatrixXd Z = Eigen::MatrixXd::Zero(m_component.size(), count());
    for(Eigen::Index v = 0; v < Z.rows(); ++v) Z(v, m_component[v]) = 1.0 / std::sqrt(m_mass[m_component[v]]);
    return Z;
  }
  /// The pairs on the complement, (re)projected and M-normalised against round-off, after the
  /// null space's c pairs (lambda = 0).
  void prepend_null_space(Spectral_pairs& pairs, const Eigen::VectorXd& mass) const
  {
    const Eigen::Index c = count(), m = pairs.values.size();
    remove_means(pairs.vectors, mass);
    for(Eigen::Index j = 0; j < m; ++j)
      pairs.vectors.col(j) /= std::sqrt(pairs.vectors.col(j).cwiseAbs2().dot(mass));
    Eigen::VectorXd values(c + m);
    values << Eigen::VectorXd::Zero(c), pairs.values;
    Eigen::MatrixXd vectors(mass.size(), c + m);
    vectors << null_vectors(), pairs.vectors;
    pairs.values = std::move(values);
    pairs.vectors = std::move(vectors);
  }

private:
  /// X <- X - diag(out) 1_C (1_C^T diag(in) X) / m_C for every component C, with the vertex
  /// weights in(v) and out(v): the three projections above differ only in these.
  template <typename In, typename Out>
  void subtract_component_sums(Eigen::Ref<Eigen::MatrixXd> X, const In& in, const Out& out) const
  {
    // Column by column: X is column-major.
    Eigen::MatrixXd sums = Eigen::MatrixXd::Zero(count(), X.cols());
    for(Eigen::Index j = 0; j < X.cols(); ++j)
      for(Eigen::Index v = 0; v < X.rows(); ++v) sums(m_component[v], j) += in(v) * X(v, j);
    sums.array().colwise() /= m_mass.array();
    for(Eigen::Index j = 0; j < X.cols(); ++j)
      for(Eigen::Index v = 0; v < X.rows(); ++v) X(v, j) -= out(v) * sums(m_component[v], j);
  }

  Eigen::VectorXi m_component;  // per vertex
  Eigen::VectorXd m_mass;       // per component: m_C = 1_C^T M 1_C
};

/// K^-1 on the M-orthogonal complement of the null space: u = K^-1 b with b's null-space loads
/// removed, then u's component means (round-off, since 1_C^T K u = -sigma m_C mean_C(u)).
/// Stands in for the factor in the Krylov runs.
template <typename Factor>
class Deflated_solve
{
public:
  Deflated_solve(const Factor& f, const Null_space_deflation& d, const Eigen::VectorXd& mass)
    : m_factor(f), m_deflation(d), m_mass(mass)
  {}
  template <typename Rhs>
  Eigen::Matrix<double, Eigen::Dynamic, Rhs::ColsAtCompileTime> solve(const Rhs& b) const
  {
    Eigen::Matrix<double, Eigen::Dynamic, Rhs::ColsAtCompileTime> r = b;
    m_deflation.remove_loads(r, m_mass);
    Eigen::Matrix<double, Eigen::Dynamic, Rhs::ColsAtCompileTime> u = m_factor.solve(r);
    m_deflation.remove_means(u, m_mass);
    return u;
  }
  const Null_space_deflation& deflation() const { return m_deflation; }
  const Factor& factor() const { return m_factor; }

private:
  const Factor& m_factor;
  const Null_space_deflation& m_deflation;
  const Eigen::VectorXd& m_mass;
};

/// The null space a Krylov run's operator removes: none for a plain factor.
template <typename Factor>
const Null_space_deflation* deflation_of(const Factor&)
{
  return nullptr;
}
template <typename Factor>
const Null_space_deflation* deflation_of(const Deflated_solve<Factor>& solve)
{
  return &solve.deflation();
}

/// The factor behind a Krylov run's operator.
template <typename Factor>
const Factor& factor_of(const Factor& factor)
{
  return factor;
}
template <typename Factor>
const Factor& factor_of(const Deflated_solve<Factor>& solve)
{
  return solve.factor();
}

/// The fill-reducing permutation P of a Cholesky factor (L L^T = P K P^T), as an Eigen
/// permutation: the completeness check factorises a matrix of the same pattern with it, which
/// spares a second ordering, whose cost grows with the mesh.
using Fill_permutation = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;
inline Fill_permutation fill_permutation(const Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower>& f)
{
  return f.permutationP();
}

inline void throw_inertia_failure(double tau)
{
  throw Numerical_error("spectral completeness check: the LDL^T factorisation of -S - tau M failed (tau = " +
                        message_number(tau) + ")");
}

/// K = -S - sigma M, a matrix of its own. The solver's stages take S itself: a negated copy held
/// for the whole run would add to its peak memory.
inline Eigen::SparseMatrix<double> shifted_pencil(const Eigen::SparseMatrix<double>& stiffness,
                                                  const Eigen::VectorXd& mass, double sigma)
{
  Eigen::SparseMatrix<double> K = -stiffness;
  K.diagonal() -= sigma * mass;
  return K;
}

/// Number of eigenvalues of -S phi = lambda M phi strictly below tau (Sylvester's inertia): the
/// negative pivots of the simplicial LDL^T factorisation of P (-S - tau M) P^T, P a
/// fill-reducing ordering.
inline Eigen::Index count_eigenvalues_below(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass,
                                            double tau, const Fill_permutation& P)
{
  const Eigen::SparseMatrix<double> K = shifted_pencil(stiffness, mass, tau);
  Eigen::SparseMatrix<double> Kp(K.rows(), K.cols());
  Kp.selfadjointView<Eigen::Lower>() = K.selfadjointView<Eigen::Lower>().twistedBy(P);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt(Kp);
  if(ldlt.info() != Eigen::Success) throw_inertia_failure(tau);
  return (ldlt.vectorD().array() < 0).count();
}

/// Counts the eigenvalues below tau for the completeness check. Made after the factorisation of
/// -S - sigma M, it reuses that factor's ordering (an analysis whose cost grows with the mesh);
/// with CHOLMOD it reuses the supernodal structure too, for a supernodal LDL^T
/// (internal/supernodal_ldlt.h), several times faster than the simplicial one on large meshes.
template <typename Factor>
class Eigenvalue_counter
{
public:
  Eigenvalue_counter(const Factor& factor, const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass)
      : m_stiffness(stiffness), m_mass(mass), m_P(fill_permutation(factor))
  {}
  Eigen::Index below(double tau) const { return count_eigenvalues_below(m_stiffness, m_mass, tau, m_P); }
  static constexpr bool overwrites_factor() { return false; }

private:
  const Eigen::SparseMatrix<double>& m_stiffness;
  const Eigen::VectorXd& m_mass;
  Fill_permutation m_P;
};

#ifdef LAPMESH_HAS_CHOLMOD
/// -S - sigma M as L D L^T on the supernodal structure of a CHOLMOD factor, at any shift sigma:
/// the count of negative pivots (the eigenvalues below sigma) and solves. Shared by the
/// completeness check and spectrum slicing.
class Shifted_supernodal_ldlt
{
public:
  Shifted_supernodal_ldlt(const cholmod_factor& structure, const Eigen::SparseMatrix<double>& stiffness,
                          const Eigen::VectorXd& mass)
      : m_ldlt(structure), m_lower(m_ldlt.permuted_lower(stiffness)), m_mass(mass)
  {
    m_lower *= -1.0;  // -S from S without a second matrix
  }
  /// Factorises at sigma, into `storage` (values_size() doubles, see Supernodal_ldlt::factorize_in)
  /// or, without it, into its own memory. False on a zero pivot.
  bool factorize_at(double sigma, double* storage = nullptr)
  {
    return storage ? m_ldlt.factorize_in(storage, m_lower, m_mass, sigma) : m_ldlt.factorize(m_lower, m_mass, sigma);
  }
  Eigen::Index negative_pivots() const { return m_ldlt.negative_pivots(); }
  template <typename Rhs>
  Eigen::Matrix<double, Eigen::Dynamic, Rhs::ColsAtCompileTime> solve(const Rhs& b) const
  {
    return m_ldlt.solve(b);
  }
  /// The fill-reducing ordering: row i of the factor is row order()[i] of the matrix.
  const int* order() const { return m_ldlt.matrix_rows(); }
  /// Y = D K^-1 D X, D = diag(scale), for X, Y and scale in order().
  void scaled_solve_in_factor_order(const Eigen::VectorXd& scale, const Eigen::Ref<const Eigen::MatrixXd>& X,
                                    Eigen::MatrixXd& Y) const
  {
    m_ldlt.scaled_solve_by_rows([](Eigen::Index i) { return i; }, scale.data(), X, Y);
  }

private:
  Supernodal_ldlt m_ldlt;
  Eigen::SparseMatrix<double> m_lower;  // P (-S) P^T, lower triangle
  const Eigen::VectorXd& m_mass;
};

/// With CHOLMOD the LDL^T is written over the factor of -S - sigma M, whose memory is then free:
/// the completeness check comes after the Krylov run, and a retry factorises again
/// (overwrites_factor()). On a large mesh this spares a second factor's fresh pages.
template <>
class Eigenvalue_counter<Cholmod_supernodal_llt>
{
public:
  Eigenvalue_counter(Cholmod_supernodal_llt& factor, const Eigen::SparseMatrix<double>& stiffness,
                     const Eigen::VectorXd& mass)
      : m_factor(factor), m_shifted(*factor.factor(), stiffness, mass)
  {}
  Eigen::Index below(double tau) const
  {
    if(!m_shifted.factorize_at(tau, m_factor.values_to_overwrite())) throw_inertia_failure(tau);
    return m_shifted.negative_pivots();
  }
  static constexpr bool overwrites_factor() { return true; }

private:
  Cholmod_supernodal_llt& m_factor;
  mutable Shifted_supernodal_ldlt m_shifted;
};
#endif

/// The shift-invert factor is read by every Krylov step: a CHOLMOD factor is made with compact
/// supernodes (doc/benchmarks-history.md: smaller, and faster over a run, than CHOLMOD's default),
/// which are small on a surface mesh: lapmesh's numeric factorisation where it is the faster.
template <typename Factor>
void prepare_for_many_solves(Factor&)
{}
#ifdef LAPMESH_HAS_CHOLMOD
inline void prepare_for_many_solves(Cholmod_supernodal_llt& f)
{
  f.set_supernodes(Cholmod_supernodal_llt::Supernodes::compact);
  f.set_numeric(Cholmod_supernodal_llt::Numeric::fastest);
}
#endif

template <typename Factor>
void factorise_or_throw(Factor& f, const Eigen::SparseMatrix<double>& K)
{
  release_cached_large_arrays();  // the factor is the run's largest block: no large cached mapping beside it
  f.compute(K);
  if(f.info() != Eigen::Success)
    throw Numerical_error("spectral solver: the Cholesky factorisation of -S - sigma M failed "
                          "(the pencil is not positive semidefinite, or M is not positive)");
}

inline Spectral_pairs dense_smallest_eigenpairs(const Eigen::SparseMatrix<double>& stiffness,
                                                const Eigen::VectorXd& mass, Eigen::Index m)
{
  const Eigen::VectorXd isq = mass.cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd A = -(isq.asDiagonal() * Eigen::MatrixXd(stiffness) * isq.asDiagonal());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A);
  if(es.info() != Eigen::Success) throw Numerical_error("spectral solver: the dense eigen-solver did not converge");
  Spectral_pairs out;
  out.values = es.eigenvalues().head(m);
  out.vectors = isq.asDiagonal() * es.eigenvectors().leftCols(m);
  out.dense = true;
  out.attempts = 1;
  return out;
}

/// The pairs (lambda_j, M^-1/2 y_j) in ascending lambda, from the eigenpairs (lambda_j, y_j) of
/// the standardised problem. The vectors are reordered and scaled in place: on a large mesh a
/// copy would be the run's peak memory.
inline Spectral_pairs ascending_pairs(const Eigen::VectorXd& lambda, Eigen::MatrixXd&& Y,
                                      const Eigen::VectorXd& sqrt_mass)
{
  // Column j of the result is column order[j] of Y: Y P with P's indices `order`, which Eigen
  // applies in place (column swaps along the permutation's cycles).
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, Eigen::Index> order(lambda.size());
  order.setIdentity();
  std::sort(order.indices().data(), order.indices().data() + lambda.size(),
            [&](Eigen::Index a, Eigen::Index b) { return lambda[a] < lambda[b]; });
  Spectral_pairs out;
  out.values.resize(lambda.size());
  for(Eigen::Index j = 0; j < lambda.size(); ++j) out.values[j] = lambda[order.indices()[j]];
  out.vectors = std::move(Y);
  out.vectors = out.vectors * order;
  out.vectors.array().colwise() /= sqrt_mass.array();
  return out;
}

/// One run of Spectra's Lanczos for m pairs with the factor of K = -S - sigma M.
template <typename Factor>
Spectral_pairs spectra_run(const Factor& factor, const Eigen::VectorXd& sqrt_mass, double sigma, Eigen::Index m,
                           const Spectral_options& opt, const std::function<void(long long)>& on_op)
{
  const Eigen::Index n = sqrt_mass.size();
  Spectral_shift_invert_op<Factor> op(factor, sqrt_mass, on_op);
  const double ncv_factor = opt.ncv_factor > 0 ? opt.ncv_factor : 2.0;
  const Eigen::Index ncv = std::min<Eigen::Index>(n, std::max<Eigen::Index>(Eigen::Index(ncv_factor * double(m)) + 1, m + 20));
  Spectra::SymEigsShiftSolver<Spectral_shift_invert_op<Factor>> eigs(op, m, ncv, sigma);
  if(const Null_space_deflation* null_space = deflation_of(factor)) {
    // Spectra's own random start would carry the null space (see block_lanczos_run()); its
    // refills still may.
    Eigen::VectorXd start = Eigen::VectorXd::LinSpaced(n, -1.0, 1.0).array().sin();
    null_space->remove_from_symmetric_form(start, sqrt_mass);
    eigs.init(start.data());
  } else {
    eigs.init();
  }
  eigs.compute(Spectra::SortRule::LargestMagn, opt.max_restarts, opt.tolerance, Spectra::SortRule::SmallestAlge);
  if(eigs.info() != Spectra::CompInfo::Successful)
    throw Numerical_error("spectral solver: Lanczos did not converge to " + std::to_string(m) + " eigenpairs in " +
                          std::to_string(opt.max_restarts) + " restarts (tolerance " +
                          message_number(opt.tolerance) + "); raise number_of_iterations or the tolerance");
  const Eigen::VectorXd vals = eigs.eigenvalues();
  if(vals.size() < m) throw Numerical_error("spectral solver: fewer converged eigenpairs than requested");
  Spectral_pairs out = ascending_pairs(vals, eigs.eigenvectors(), sqrt_mass);
  out.operations = op.operations();
  out.shift = sigma;
  return out;
}

/// Y = D K^-1 D X, D = diag(scale), with the factor of K.
template <typename Factor>
void scaled_solve(const Factor& factor, const Eigen::VectorXd& scale, const Eigen::Ref<const Eigen::MatrixXd>& X,
                  Eigen::MatrixXd& Y, Eigen::MatrixXd& buffer)
{
  buffer = scale.asDiagonal() * X;
  Y = factor.solve(buffer);
  Y = scale.asDiagonal() * Y;
}
#ifdef LAPMESH_HAS_CHOLMOD
inline void scaled_solve(const Cholmod_supernodal_llt& factor, const Eigen::VectorXd& scale,
                         const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::MatrixXd& Y, Eigen::MatrixXd&)
{
  factor.scaled_solve(scale, X, Y);
}
#endif

/// The order of the rows a factor solves in: CHOLMOD's fill-reducing permutation (row i of its
/// system is row order[i] of the matrix), nullptr for a factor that solves in the matrix's order.
/// A Krylov run in that order hands the solves their blocks without gathering rows.
template <typename Factor>
const int* solve_order(const Factor&)
{
  return nullptr;
}
/// scaled_solve() for blocks in solve_order(factor), with `scale` in that order.
template <typename Factor>
void scaled_solve_in_solve_order(const Factor& factor, const Eigen::VectorXd& scale,
                                 const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::MatrixXd& Y,
                                 Eigen::MatrixXd& buffer)
{
  scaled_solve(factor, scale, X, Y, buffer);
}
#ifdef LAPMESH_HAS_CHOLMOD
inline const int* solve_order(const Cholmod_supernodal_llt& factor)
{
  return factor.permutation();
}
inline void scaled_solve_in_solve_order(const Cholmod_supernodal_llt& factor, const Eigen::VectorXd& scale,
                                        const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::MatrixXd& Y,
                                        Eigen::MatrixXd&)
{
  factor.scaled_solve_in_factor_order(scale, X, Y);
}
#endif

/// The block size of a block Lanczos run for m pairs, unless the options set one. Blocks of 4
/// need fewer solves than blocks of 8 (a block of 8 costs two of 4 without AVX-512, and more
/// than one with it); from a few hundred pairs on, the larger block's fewer passes over the
/// basis make up for its extra solves (doc/spectral.md).
inline Eigen::Index default_block_size(Eigen::Index m) { return m < 250 ? 4 : 8; }

/// The basis of a block Lanczos run for m pairs, per pair, unless the options set it. For a few
/// dozen pairs a larger basis than Spectra's: its fewer restarts save more solves than the longer
/// re-orthogonalisation costs; for more pairs a smaller one, for the opposite reason
/// (doc/spectral.md).
inline double default_basis_factor(Eigen::Index m) { return m <= 48 ? 2.5 : 1.75; }

/// The most copies of one value (equal to 1e-8 relative) among v[from..].
inline Eigen::Index largest_multiplicity(const Eigen::VectorXd& v, Eigen::Index from)
{
  Eigen::Index largest = 0;
  for(Eigen::Index j = from, run = 0; j < v.size(); ++j) {
    run = j > from && v[j] - v[j - 1] <= 1e-8 * std::abs(v[j]) ? run + 1 : 1;
    largest = std::max(largest, run);
  }
  return largest;
}

/// Watches a shift-invert run from below zero for wanted eigenvalues that crowd together far
/// above the shift (a dense band of distinct values: many near-identical parts joined at one
/// vertex). Seen from the shift they are then nearly equal, and Krylov convergence, which goes
/// with their separation relative to their distance from the shift, nearly stops. A run that has
/// not converged after `patience` restarts with such Ritz values is given up, and its Ritz values
/// are kept as estimates for a run from a shift next to them (reshifted_eigenpairs()).
struct Crowding_watch
{
  int patience = 10;          // restarts
  double crowding = 1e-2;     // the wanted values' width over their distance from the shift
  Eigen::VectorXd estimates;  // ascending; set when the run was given up
};

/// The first of the eigenvalue estimates `lambda` (ascending) beyond round-off from zero, relative
/// to the last: the crowding measures leave out the null space of a connected mesh.
inline Eigen::Index first_beyond_zero(const Eigen::VectorXd& lambda)
{
  const Eigen::Index last = lambda.size() - 1;
  Eigen::Index first = 0;
  while(first < last && std::abs(lambda[first]) <= 1e-6 * std::abs(lambda[last])) ++first;
  return first;
}

/// Whether the eigenvalue estimates `lambda` (ascending) crowd as Crowding_watch describes.
inline bool crowded_far_from_shift(const Eigen::VectorXd& lambda, double sigma, double crowding)
{
  const Eigen::Index last = lambda.size() - 1, first = first_beyond_zero(lambda);
  const double distance = lambda[first] - sigma;
  return first < last && distance > 0 && lambda[last] - lambda[first] < crowding * distance;
}

/// A block Lanczos run that converged no further wanted pair in stall_restarts restarts in a row
/// (Block_lanczos_options): the caller may retry with a larger block.
class Stalled_run : public Numerical_error
{
public:
  Stalled_run(const std::string& what, long long operations) : Numerical_error(what), operations(operations) {}
  long long operations;  ///< the run's
};

/// The block to run again with after a run for m pairs stalled in blocks of `block` (0: the
/// default): copies of a repeated value beyond what the block finds, as on identical parts. Twice
/// the block, up to eight times the default for m pairs; a stall with a block the options fix,
/// or at that limit, is a Numerical_error.
inline Eigen::Index block_after_stall(Eigen::Index block, Eigen::Index m, const Spectral_options& opt,
                                      const Stalled_run& stalled)
{
  const Eigen::Index standard = default_block_size(m), current = std::max(block, standard);
  if(opt.block_size > 0 || current >= 8 * standard) throw Numerical_error(stalled.what());
  return 2 * current;
}

/// The restarts without progress after which a run of verified_runs() is retried with a larger
/// block: a value repeated more often than a block's Krylov space holds it had runs of 20
/// identical parts reach the 1000 restarts allowed (doc/spectral.md).
constexpr int stalled_run_restarts = 100;

/// One block Lanczos run for m pairs with the factor of K = -S - sigma M. With a `watch`, a run
/// that it gives up returns no pairs (and the watch's estimates). With `stall_restarts` > 0, a run
/// that stalls that long throws Stalled_run.
template <typename Factor>
Spectral_pairs block_lanczos_run(const Factor& factor, const Eigen::VectorXd& sqrt_mass, double sigma, Eigen::Index m,
                                 const Spectral_options& opt, const std::function<void(long long)>& on_op,
                                 Crowding_watch* watch = nullptr, int stall_restarts = 0)
{
  const Eigen::Index n = sqrt_mass.size();
  Block_lanczos_options bo;
  bo.block_size = opt.block_size > 0 ? opt.block_size : default_block_size(m);
  bo.tolerance = opt.tolerance;
  bo.max_restarts = opt.max_restarts;
  const double basis_factor = opt.ncv_factor > 0 ? opt.ncv_factor : default_basis_factor(m);
  bo.max_basis = std::max<Eigen::Index>(Eigen::Index(basis_factor * double(m)), m + 6 * bo.block_size);
  bo.by_magnitude = true;  // sigma inside the spectrum (bands): theta of both signs
  bo.stall_restarts = stall_restarts;
  // theta = 1 / (lambda - sigma): the eigenvalues nearest to sigma.
  const auto ascending_lambda = [sigma](const Eigen::VectorXd& theta) {
    Eigen::VectorXd lambda = (1.0 / theta.array() + sigma).matrix();
    std::sort(lambda.data(), lambda.data() + lambda.size());
    return lambda;
  };
  if(watch)
    bo.give_up = [&](const Eigen::VectorXd& theta, int restart) {
      return restart >= watch->patience && crowded_far_from_shift(ascending_lambda(theta), sigma, watch->crowding);
    };
  // The run works in the order the factor solves in; its vectors are put back in the matrix's
  // order once, at the end. On a mesh of several components, the null space is removed from the
  // factor's solutions in that order too. The operator maps the null space onto itself, so
  // removing it from the solution removes what the block carried of it as well.
  const auto& solver = factor_of(factor);
  const int* order = solve_order(solver);
  const Null_space_deflation* null_space = deflation_of(factor);
  Eigen::VectorXd ordered_sqrt_mass;
  if(order) {
    ordered_sqrt_mass.resize(n);
    for(Eigen::Index i = 0; i < n; ++i) ordered_sqrt_mass[i] = sqrt_mass[order[i]];
  }
  const Eigen::VectorXd& run_sqrt_mass = order ? ordered_sqrt_mass : sqrt_mass;
  const Null_space_deflation ordered_null_space =
    order && null_space ? null_space->in_order(order) : Null_space_deflation();
  const Null_space_deflation* run_null_space = order && null_space ? &ordered_null_space : null_space;
  if(run_null_space)
    bo.remove_null_space = [run_null_space, &run_sqrt_mass](Eigen::Ref<Eigen::VectorXd> x) {
      run_null_space->remove_from_symmetric_form(x, run_sqrt_mass);
    };
  bo.row_order = order;
  Eigen::MatrixXd rhs;
  auto apply = [&](const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::MatrixXd& Y) {
    if(order && null_space) {
      scaled_solve_in_solve_order(solver, run_sqrt_mass, X, Y, rhs);
      ordered_null_space.remove_from_symmetric_block(Y, run_sqrt_mass);
    } else {
      scaled_solve_in_solve_order(factor, run_sqrt_mass, X, Y, rhs);
    }
  };
  Block_lanczos_result r = block_lanczos_largest(n, m, apply, bo, on_op);
  if(r.stalled)
    throw Stalled_run("block Lanczos: " + std::to_string(r.converged_pairs) + " of " + std::to_string(m) +
                        " eigenpairs converged, none more in the last " + std::to_string(stall_restarts) +
                        " restarts (blocks of " + std::to_string(bo.block_size) + ")",
                      r.operations);
  if(!r.converged) {
    watch->estimates = ascending_lambda(r.values);
    Spectral_pairs none;
    none.operations = r.operations;
    none.shift = sigma;
    return none;
  }
  const Eigen::VectorXd lambda = (1.0 / r.values.array() + sigma).matrix();
  Spectral_pairs out = ascending_pairs(lambda, std::move(r.vectors), run_sqrt_mass);
  if(order) {  // row i to row order[i], a column at a time: a row of a column-major block is scattered
    Eigen::VectorXd column(n);
    for(Eigen::Index j = 0; j < out.vectors.cols(); ++j) {
      column = out.vectors.col(j);
      for(Eigen::Index i = 0; i < n; ++i) out.vectors(order[i], j) = column[i];
    }
  }
  out.operations = r.operations;
  out.shift = sigma;
  return out;
}

/// One Krylov run for m pairs, by the method the options name (a `watch` and `stall_restarts` are
/// for block Lanczos).
template <typename Factor>
Spectral_pairs lanczos_run(const Factor& factor, const Eigen::VectorXd& sqrt_mass, double sigma, Eigen::Index m,
                           const Spectral_options& opt, const std::function<void(long long)>& on_op,
                           Crowding_watch* watch = nullptr, int stall_restarts = 0)
{
  if(opt.method == Krylov_method::spectra) return spectra_run(factor, sqrt_mass, sigma, m, opt, on_op);
  return block_lanczos_run(factor, sqrt_mass, sigma, m, opt, on_op, watch, stall_restarts);
}

/// Whether the ascending values v[i - 1] and v[i] belong to different eigenspaces: a relative
/// gap, against v[i] or, near zero, against `scale`, the magnitude of the largest value.
inline bool gap_before(const Eigen::VectorXd& v, Eigen::Index i, double scale)
{
  return v[i] - v[i - 1] > 1e-6 * std::max(std::abs(v[i]), 1e-6 * scale);
}

/// The magnitude of the largest of ascending values, for gap_before().
inline double gap_scale(const Eigen::VectorXd& v) { return std::max(std::abs(v[v.size() - 1]), 1e-300); }

/// The end of the cluster of lambda_{k-1}: the first j >= k-1 with a relative gap to
/// lambda_{j+1}; -1 when the cluster reaches the last computed value.
inline Eigen::Index cluster_end(const Eigen::VectorXd& v, Eigen::Index k)
{
  const double scale = gap_scale(v);
  for(Eigen::Index j = k - 1; j + 1 < v.size(); ++j)
    if(gap_before(v, j + 1, scale)) return j;
  return -1;
}

/// The first member of the eigenspace of v[i] among ascending values (gap_before()).
inline Eigen::Index eigenspace_start(const Eigen::VectorXd& v, Eigen::Index i)
{
  const double scale = gap_scale(v);
  while(i > 0 && !gap_before(v, i, scale)) --i;
  return i;
}

/// How close to lambda_{count-1}, relative, its eigenspace must lie for a partial one to be
/// accepted (leading_values_are_complete()).
constexpr double partial_eigenspace_margin = 1e-9;

/// Whether `count` values found, the largest `top`, are the `count` smallest eigenvalues when
/// the eigenspace of `top` reaches past the values found: a value repeated more often than a
/// run holds (a mesh of many identical parts). `found_below(tau)` counts the values found below
/// tau, `below(tau)` the eigenvalues (exactly, by inertia). None below top's eigenspace may have
/// been missed, and at least `count` must lie up to it; each of the values is then within the
/// margin of its eigenvalue.
template <typename FoundBelow, typename Below>
bool leading_values_are_complete(double top, Eigen::Index count, const FoundBelow& found_below, const Below& below)
{
  const double d = partial_eigenspace_margin * std::abs(top);
  return d > 0 && below(top - d) == found_below(top - d) && below(top + d) >= count;
}

/// How many of a run's pairs (`values` ascending, from the smallest eigenvalue on) are verified
/// by the inertia counts `below(tau)` to be the smallest eigenvalues, k of them at least: whole
/// eigenspaces up to lambda_{k-1}'s, or k + 1 when that eigenspace reaches past the values
/// found (then splits_eigenspace(k) sees the split). 0: a value was missed, ask for more.
template <typename Below>
Eigen::Index verified_count(const Eigen::VectorXd& values, Eigen::Index k, const Below& below)
{
  const Eigen::Index j = cluster_end(values, k);
  if(j >= 0) {
    const Eigen::Index count = below(0.5 * (values[j] + values[j + 1]));
    if(count == j + 1) return j + 1;
    if(count < j + 1)
      throw Numerical_error("spectral solver: inconsistent eigenvalue count (" + std::to_string(count) +
                            " below tau, " + std::to_string(j + 1) + " computed)");
  }
  if(values.size() > k) {
    // The eigenspace of lambda_{k-1} has more members than the run found, or reaches past the
    // computed pairs: its computed members stand for the rest once the counts show that none
    // below it was missed.
    const double* v = values.data();
    const auto found_below = [&](double tau) { return Eigen::Index(std::lower_bound(v, v + k + 1, tau) - v); };
    if(leading_values_are_complete(v[k], k + 1, found_below, below)) return k + 1;
  }
  return 0;
}


/// The LDL^T factorisation of -S - sigma M at the shifts of spectrum slicing (one analysis for
/// all): the count of its negative pivots, and solves. Supernodal with CHOLMOD, else Eigen's
/// simplicial LDL^T.
class Shifted_ldlt
{
public:
  Shifted_ldlt(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass)
#ifdef LAPMESH_HAS_CHOLMOD
  {
    Cholmod_supernodal_llt analysis;
    analysis.analyzePattern(stiffness);  // the pattern only
    if(analysis.info() != Eigen::Success || !analysis.factor())
      throw Numerical_error("spectral solver: the analysis of -S - sigma M failed");
    m_ldlt.emplace(*analysis.factor(), stiffness, mass);
  }
#else
      : m_stiffness(stiffness), m_mass(mass)
  {}
#endif
  /// Factorises at sigma; returns the number of eigenvalues below sigma.
  Eigen::Index factorize_at(double sigma)
  {
#ifdef LAPMESH_HAS_CHOLMOD
    const bool ok = m_ldlt->factorize_at(sigma);
#else
    const Eigen::SparseMatrix<double> K = shifted_pencil(m_stiffness, m_mass, sigma);
    if(!m_analysed) m_simplicial.analyzePattern(K);
    m_analysed = true;
    m_simplicial.factorize(K);
    const bool ok = m_simplicial.info() == Eigen::Success;
#endif
    if(!ok)
      throw Numerical_error("spectral solver: the LDL^T factorisation of -S - sigma M failed (sigma = " +
                            message_number(sigma) + ")");
#ifdef LAPMESH_HAS_CHOLMOD
    return m_ldlt->negative_pivots();
#else
    return (m_simplicial.vectorD().array() < 0).count();
#endif
  }
  template <typename Rhs>
  Eigen::Matrix<double, Eigen::Dynamic, Rhs::ColsAtCompileTime> solve(const Rhs& b) const
  {
#ifdef LAPMESH_HAS_CHOLMOD
    return m_ldlt->solve(b);
#else
    return m_simplicial.solve(b);
#endif
  }

#ifdef LAPMESH_HAS_CHOLMOD
  /// The supernodal factor's ordering and its solves in that order (the block Krylov runs'),
  /// with the last factorisation.
  const Shifted_supernodal_ldlt& supernodal() const { return *m_ldlt; }
#endif

private:
#ifdef LAPMESH_HAS_CHOLMOD
  std::optional<Shifted_supernodal_ldlt> m_ldlt;
#else
  const Eigen::SparseMatrix<double>& m_stiffness;
  const Eigen::VectorXd& m_mass;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> m_simplicial;
  bool m_analysed = false;
#endif
};

#ifdef LAPMESH_HAS_CHOLMOD
inline const int* solve_order(const Shifted_ldlt& factor) { return factor.supernodal().order(); }
inline void scaled_solve_in_solve_order(const Shifted_ldlt& factor, const Eigen::VectorXd& scale,
                                        const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::MatrixXd& Y, Eigen::MatrixXd&)
{
  factor.supernodal().scaled_solve_in_factor_order(scale, X, Y);
}
#endif

/// The vectors of a new band, held[cut, end), and of the bands held before it are M-orthogonal
/// only to about the Krylov tolerance times the distance of a value from its band's shift over its
/// gap to the other's: far from round-off where distinct values crowd, and not only next to the
/// cut. The earlier bands (`band_begins`, the last entry the cut) that couple with the new one by
/// more than 1e-10, up to eight back, take part with it in a Rayleigh-Ritz step that makes them
/// M-orthonormal again. It keeps their span, and with it their orthogonality to the other bands.
inline void rayleigh_ritz_across_cut(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass,
                                     std::vector<double>& values, std::vector<Eigen::VectorXd>& vectors,
                                     const std::vector<Eigen::Index>& band_begins, Eigen::Index end)
{
  const auto at = [](Eigen::Index j) { return std::size_t(j); };
  const Eigen::Index cut = band_begins.back();
  // The coupling P^T M N of an earlier band P with the new band N, measured by its action on two
  // fixed unit vectors (two products with each band).
  std::vector<Eigen::VectorXd> probed;
  for(const double phase : {0.3, 1.9}) {
    const Eigen::VectorXd probe =
      Eigen::VectorXd::LinSpaced(end - cut, phase, phase + 0.7 * double(end - cut)).array().sin().matrix().normalized();
    Eigen::VectorXd y = Eigen::VectorXd::Zero(mass.size());
    for(Eigen::Index j = cut; j < end; ++j) y += probe[j - cut] * vectors[at(j)];
    probed.push_back(mass.cwiseProduct(y));
  }
  Eigen::Index begin = cut;
  for(std::size_t b = band_begins.size() - 1; b-- > 0 && band_begins.size() - b <= 9;) {
    double coupling = 0;
    for(Eigen::Index i = band_begins[b]; i < band_begins[b + 1]; ++i)
      for(const Eigen::VectorXd& y : probed) coupling = std::max(coupling, std::abs(vectors[at(i)].dot(y)));
    if(coupling > 1e-10) begin = band_begins[b];
  }
  if(begin == cut) return;
  Eigen::MatrixXd V(mass.size(), end - begin);
  for(Eigen::Index j = begin; j < end; ++j) V.col(j - begin) = vectors[at(j)];
  const Eigen::MatrixXd G = V.transpose() * (mass.asDiagonal() * V);
  const Eigen::MatrixXd H = -(V.transpose() * (stiffness * V));
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> ritz(0.5 * (H + H.transpose()), 0.5 * (G + G.transpose()));
  if(ritz.info() != Eigen::Success) throw Numerical_error("spectral solver: the Rayleigh-Ritz step across a band's cut failed");
  V = V * ritz.eigenvectors();  // M-orthonormal: the solver normalises Z^T G Z = I
  for(Eigen::Index j = begin; j < end; ++j) {
    values[at(j)] = ritz.eigenvalues()[j - begin];
    vectors[at(j)] = V.col(j - begin);
  }
}

/// The largest relative residual ||S x + lambda M x|| / (lambda ||M x||) of a pair that a band
/// holds: far above the Krylov runs' own (about 1e-11 on the test meshes), far below what the
/// tests accept for a verified spectrum.
constexpr double held_residual = 1e-8;

/// Spectrum slicing ("bands", as in Vallet & Levy's manifold harmonics): shift-invert Lanczos
/// around successive shifts sigma_0 < sigma_1 < ..., each for about band_size pairs, so that the
/// Krylov space stays small (a run's dense work grows with the square of its size). Each
/// shift's LDL^T factorisation (one symbolic analysis for all) also gives, by Sylvester's law,
/// the exact number of eigenvalues below it: every band is checked against it, so a dropped
/// or duplicated pair is detected, never returned.
///
/// Symmetric meshes have clustered spectra (a sphere: groups of 2l+1 nearly or exactly equal
/// values, separated by wide gaps), so neither a fixed window nor a shift placed by the mean
/// density can be trusted: a group may be wider than the window, or the window may be filled
/// by the group just accepted. Each band therefore adapts until it holds a complete, verified
/// slice above the accepted range: the inertia at the shift bounds how far the shift may lie
/// above it, a window that does not reach back to the accepted range pulls the shift down, and
/// a window whose new values hold no gap before its edge (a cluster wider than the window), or
/// that fails the inertia count (a missed copy of a repeated value), is widened. Values that
/// crowd far above the last cut, across a gap that the counts show empty, raise the accepted
/// range to just below them, so that the next shift lies next to them and not in the gap.
/// From the second band on, windows are exact: the values in [u, edge), edge in a gap found by
/// inertia, so that no window's edge cuts a cluster and no margin of values is found again.
inline Spectral_pairs banded_eigenpairs(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass,
                                        Eigen::Index k, const Spectral_options& opt)
{
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const Eigen::Index n = mass.size();
  if(k > n - 2)
    throw Numerical_error("spectral solver: k = " + std::to_string(k) + " needs the dense solver, which is limited to " +
                          std::to_string(opt.dense_limit) + " vertices");
  const Eigen::VectorXd sqrt_mass = mass.cwiseSqrt();
  const Null_space_deflation null_space(stiffness, mass);
  const Eigen::Index c = null_space.count();                  // 0 on a connected mesh
  const Eigen::Index max_window = std::max<Eigen::Index>(1, n - c - 2);  // Spectra needs nev < n
  const Eigen::Index B = std::min<Eigen::Index>(std::max<Eigen::Index>(opt.band_size, 8), max_window);
  constexpr int max_attempts = 12;        // per band; a widening multiplies the window by 1.5
  Shifted_ldlt ldlt(stiffness, mass);
  const Deflated_solve<Shifted_ldlt> deflated(ldlt, null_space, mass);
  auto factor_at = [&](double sigma) { return ldlt.factorize_at(sigma); };
  int band = 0;
  long long ops_total = 0;
  const std::function<void(long long)> on_op = [&](long long ops) {
    if(opt.progress && ops % 10 == 0)
      opt.progress(Spectral_progress{"lanczos band", ops_total + ops, band + 1,
                                     std::chrono::duration<double>(clock::now() - t0).count()});
  };
  auto relative_gap = [](double a, double b) { return (b - a) / std::max(std::abs(b), 1e-300); };

  // The null space's c pairs are held from the start; the first band verifies their count.
  std::vector<double> values(static_cast<std::size_t>(c), 0.0);
  std::vector<Eigen::VectorXd> vectors;
  if(c > 0) {
    const Eigen::MatrixXd Z = null_space.null_vectors();
    for(Eigen::Index j = 0; j < c; ++j) vectors.push_back(Z.col(j));
  }
  double u = 0;          // every eigenvalue below u is in `values` (verified by inertia)
  std::vector<Eigen::Index> band_begins{c};  // the first pair of every band held, and the end
  double density = 0;    // eigenvalues per unit of lambda in the last band
  double sigma = -opt.shift_factor / mass.sum();
  Eigen::Index window = B;
  int attempt = 0;
  // u was raised to just below values that crowd far above the last cut, nothing lying between:
  // a window above u then reaches the accepted range.
  bool u_raised = false;
  // Values this far apart (relative) are distinct, far beyond round-off.
  constexpr double distinct = 1e3 * partial_eigenspace_margin;
  // Where u is raised to: below `lowest` by half the `spread` of the values from it, but by no
  // less than `distinct` (the count there must not depend on an eigenvalue's last digits), and
  // no more than half the way down to `floor`.
  const auto just_below = [](double lowest, double floor, double spread) {
    return lowest - std::min(0.5 * (lowest - floor), std::max(0.5 * spread, distinct * std::abs(lowest)));
  };
  auto retry = [&](bool widen, const std::string& why) {
    if(++attempt >= max_attempts || (widen && window >= max_window))
      throw Numerical_error("spectral solver: band " + std::to_string(band) + " could not be completed in " +
                            std::to_string(attempt) + " attempts (window of " + std::to_string(window) +
                            " pairs; last: " + why + ")");
    if(widen) window = std::min<Eigen::Index>(max_window, window + window / 2);
  };
  Eigen::Index band_block = 0;  // > 0: the block that runs which stalled grew to
  while(Eigen::Index(values.size()) < k || band == 0) {
    const Eigen::Index accepted = Eigen::Index(values.size());
    // From the second band on, a window of exactly the eigenvalues in [u, edge), edge inside a gap
    // (the counts a tenth of the mean spacing below and above it agree), with the shift midway:
    // all of them lie nearer the shift than any other, so the run wants no margin, no value of
    // a cluster is split from the rest by the window's edge, and the band ends at the edge.
    bool exact_window = false;
    double edge = 0;
    Eigen::Index wanted_pairs = window;
    for(const double reach : {1.5, 1.0, 2.0, 0.75, 0.5}) {
      if(band == 0 || attempt > 0) break;  // a band retried falls back to the placement below
      const double at = u + reach * double(B) / density, margin = 0.1 / density;
      const Eigen::Index count = factor_at(at) - accepted;
      if(count < 1 || count > std::min(3 * B, max_window) || factor_at(at - margin) - accepted != count ||
         factor_at(at + margin) - accepted != count)
        continue;
      exact_window = true;
      edge = at;
      wanted_pairs = count;
      sigma = 0.5 * (u + edge);
      break;
    }
    // The window of the pairs nearest sigma reaches back below u only if [u, 2 sigma - u]
    // holds fewer than it does: count them exactly by inertia (a factorisation costs far less
    // than a Lanczos run) and move the shift halfway down to u until they fit, with a margin.
    if(band > 0 && attempt == 0 && !exact_window) sigma = u + 0.4 * double(window) / density;
    for(int i = 0; band > 0 && !exact_window && i < 64 && factor_at(2 * sigma - u) - accepted > window - window / 8; ++i)
      sigma = u + 0.5 * (sigma - u);
    factor_at(sigma);
    // An exact window holds its values up to both ends, the farthest from the shift, where a
    // run's residual relative to the value is largest: a tenth of the tolerance keeps them as
    // accurate as a margin does.
    Spectral_options run_opt = opt;
    if(exact_window) run_opt.tolerance = std::max(0.1 * opt.tolerance, std::min(opt.tolerance, 1e-12));
    if(band_block > 0) run_opt.block_size = int(band_block);
    Spectral_pairs F;
    try {
      // A run that converges no further pair in half the restarts allowed has stalled. The single
      // run's shorter watch would cut short band runs on values crowded far closer than the
      // tolerance, which converge slowly but surely, and not at all with larger blocks
      // (doc/spectral.md).
      const int stall = opt.block_size <= 0 ? std::max(1, opt.max_restarts / 2) : 0;
      F = c > 0 ? lanczos_run(deflated, sqrt_mass, sigma, wanted_pairs, run_opt, on_op, nullptr, stall)
                : lanczos_run(ldlt, sqrt_mass, sigma, wanted_pairs, run_opt, on_op, nullptr, stall);
    } catch(const Stalled_run& stalled) {
      // The larger block is kept for the bands that follow: identical parts repeat their values
      // alike all along the spectrum.
      band_block = block_after_stall(band_block, wanted_pairs, opt, stalled);
      ops_total += stalled.operations;
      retry(false, stalled.what());
      continue;
    }
    if(c > 0) {  // the complement's pairs only: re-project them against round-off
      null_space.remove_means(F.vectors, mass);
      for(Eigen::Index j = 0; j < F.values.size(); ++j)
        F.vectors.col(j) /= std::sqrt(F.vectors.col(j).cwiseAbs2().dot(mass));
    }
    ops_total += F.operations;
    const Eigen::Index m = F.values.size();
    const auto hold = [&](Eigen::Index begin, Eigen::Index end) {
      for(Eigen::Index j = begin; j < end; ++j) {
        values.push_back(F.values[j]);
        vectors.push_back(F.vectors.col(j));
      }
    };
#ifdef LAPMESH_DEBUG_BANDS
    std::fprintf(stderr, "band %d attempt %d window %ld sigma %.9g u %.9g found [%.9g, %.9g] in %lld solves\n", band,
                 attempt, long(wanted_pairs), sigma, u, F.values[0], F.values[m - 1], F.operations);
#endif
    exact_window = exact_window && m == wanted_pairs && F.values[0] >= u && F.values[m - 1] < edge;
    // No overlap with the accepted range: move the shift down, unless u was raised to just below
    // values crowded above the last cut and the inertia shows nothing between u and the window
    // (one missed closer to it fails the cut's count), or the window is an exact one.
    if(band > 0 && !exact_window && F.values[0] > u &&
       !(u_raised && factor_at(just_below(F.values[0], u, F.values[m - 1] - F.values[0])) == accepted)) {
      retry(false, "the window does not reach the accepted range");
      sigma = u + 0.5 * (sigma - u);
      continue;
    }
    // k inside the null space: the first band only verifies that no other eigenvalue lies below
    // the complement's smallest.
    if(band == 0 && accepted >= k && factor_at(0.5 * F.values[0]) == accepted) {
      ++band;
      break;
    }
    // Krylov misses happen at the edge of the window: drop the top eighth. Cut at the widest
    // relative gap in the upper quarter of the new values that remain (a wide gap keeps vectors
    // of neighbouring bands orthogonal; a high one leaves fewer values to find again), else at
    // any gap above u; where distinct values crowd so that no gap is wide, at a narrow one (the
    // Rayleigh-Ritz step across the cut restores orthogonality), still far wider than the margin
    // that joins values into one eigenspace.
    Eigen::Index top = exact_window ? m : m - std::max<Eigen::Index>(1, m / 8);
    Eigen::Index first_new = 0;
    while(first_new < m && band > 0 && F.values[first_new] < u) ++first_new;
    // And a value is held only with a small residual: from a shift far below values that crowd,
    // the Ritz vectors toward the window's top mix their neighbours though their values have
    // converged. The cut stays below the first such one.
    for(Eigen::Index j = first_new; j < top; ++j) {
      const Eigen::VectorXd Mx = mass.cwiseProduct(F.vectors.col(j));
      const double scale = std::max(std::abs(F.values[j]), std::abs(F.values[m - 1])) * Mx.norm();
      if((stiffness * F.vectors.col(j) + F.values[j] * Mx).norm() > held_residual * scale) {
        top = j;
        break;
      }
    }
    // The cut lies between F.values[cut_at - 1] and F.values[cut_at]; -1: no gap of that width.
    const auto widest_gap = [&](Eigen::Index from, double narrowest) {
      Eigen::Index at = -1;
      for(Eigen::Index j = std::max<Eigen::Index>(from, 1); j <= top; ++j)
        if(relative_gap(F.values[j - 1], F.values[j]) > narrowest) {
          narrowest = relative_gap(F.values[j - 1], F.values[j]);
          at = j;
        }
      return at;
    };
    Eigen::Index cut_at = exact_window && top == m ? m : -1;
    for(const double narrowest : {1e-6, 100 * partial_eigenspace_margin})
      for(const Eigen::Index from : {first_new + 1 + 3 * (top - first_new) / 4, first_new + 1})
        if(cut_at < 0) cut_at = widest_gap(from, narrowest);
    if(cut_at < 0) {  // the new values up to the edge are one cluster: widen past it
      // Unless they reach k + 1 (one past the k asked for: see the single run) and the counts show
      // that none below them was missed.
      const Eigen::Index wanted = k + 1 - accepted;
      if(wanted > 0 && top - first_new >= wanted) {
        const auto found_below = [&](double tau) {
          const Eigen::Index held = Eigen::Index(std::lower_bound(values.begin(), values.end(), tau) - values.begin());
          const double* v = F.values.data() + first_new;
          return held + Eigen::Index(std::lower_bound(v, v + wanted, tau) - v);
        };
        if(leading_values_are_complete(F.values[first_new + wanted - 1], k + 1, found_below, factor_at)) {
          hold(first_new, first_new + wanted);
          if(band > 0) rayleigh_ritz_across_cut(stiffness, mass, values, vectors, band_begins, accepted + wanted);
          break;
        }
      }
      retry(true, "no spectral gap above " + message_number(u) + " inside the window");
      continue;
    }
    const double cut = cut_at == m ? edge : 0.5 * (F.values[cut_at - 1] + F.values[cut_at]);
    const Eigen::Index added = cut_at - first_new;
    // Sylvester: exactly accepted + added eigenvalues below the cut, or the band missed one (an
    // exact window's edge was counted before its run).
    const Eigen::Index below = cut_at == m ? accepted + wanted_pairs : factor_at(cut);
#ifdef LAPMESH_DEBUG_BANDS
    std::fprintf(stderr, "band %d cut %.9g below %ld expected %ld\n", band, cut, long(below), long(accepted + added));
#endif
    if(below != accepted + added) {
      retry(true, std::to_string(below) + " eigenvalues below " + message_number(cut) + ", " +
                    std::to_string(accepted + added) + " found");
      continue;
    }
    hold(first_new, cut_at);
    if(band > 0) rayleigh_ritz_across_cut(stiffness, mass, values, vectors, band_begins, accepted + added);
    band_begins.push_back(accepted + added);
    density = double(added) / (cut - (band == 0 ? 0.0 : u));
    u = cut;
    u_raised = false;
    // The window's values above the cut estimate the next ones. Where distinct values crowd far
    // above it (a gap far wider than their spread), a shift placed by the density would lie in
    // the gap, and see them as nearly one value (a slow run, poorly resolved vectors). When the
    // counts show no eigenvalue in the gap, the accepted range reaches up to just below them.
    // (Copies of one repeated value are left alone: raising u puts them at the next window's
    // lower edge, where a run misses copies.)
    const double next = cut_at < m ? F.values[cut_at] : 0, spread = F.values[m - 1] - next;
    if(cut_at < m && spread > distinct * std::abs(next) && next - cut > 100 * spread) {
      const double raised = just_below(next, cut, spread);
      u_raised = factor_at(raised) == accepted + added;
      if(u_raised) u = raised;
    }
    ++band;
    attempt = 0;  // a window widened for a cluster is kept: a sphere's clusters grow with lambda
  }
  Spectral_pairs out;
  // Every band ends at a gap, and the held set holds whole clusters, but the last band when it
  // ends one value past lambda_{k-1}'s eigenspace, found to reach past the window.
  const Eigen::Index keep = Eigen::Index(values.size());
  out.values = Eigen::Map<Eigen::VectorXd>(values.data(), keep);
  out.vectors.resize(n, keep);
  for(Eigen::Index j = 0; j < keep; ++j) out.vectors.col(j) = vectors[std::size_t(j)];
  out.operations = ops_total;
  out.attempts = band;
  out.shift = sigma;
  return out;
}

/// The pairs a first run asks for beyond the k wanted: they locate the spectral gap above them.
inline Eigen::Index extra_pairs(Eigen::Index k, const Spectral_options& opt)
{
  return opt.extra >= 0 ? opt.extra : std::max<Eigen::Index>(6, k / 10);
}

/// Up to this many rows, a pencil is small: the dense solver takes milliseconds there, on
/// average over k as long as a Krylov run, and a Krylov basis spans much of so small a space,
/// where a run can return a pair whose residual is far above the dense solve's round-off
/// (doc/spectral.md, "Small problems").
constexpr Eigen::Index small_pencil_size = 200;

/// Whether a pencil of n rows is solved by the dense solver for `wanted` pairs: a small pencil,
/// or nearly the whole spectrum.
inline bool solved_densely(Eigen::Index n, Eigen::Index wanted, const Spectral_options& opt)
{
  return n <= opt.dense_limit && (n <= small_pencil_size || 2 * wanted >= n);
}

/// The retries of a shift-invert solve for the k smallest pairs, c of them the null space's:
/// Krylov runs, each asking for more pairs than the last (and, with the default block size, a
/// larger block), until the inertia counts `below(tau)` verify them. `run(m, run_opt, spent)` is
/// one run for m pairs above the null space, returned with the null space's pairs first; one
/// that holds no values was given up (Crowding_watch) and is returned at once. `spent` are the
/// operations before it, `attempt` the caller's (its progress reports), `missed` what a failure
/// names.
template <typename Report, typename Run, typename Below>
Spectral_pairs verified_runs(Eigen::Index n, Eigen::Index k, Eigen::Index c, Eigen::Index extra,
                             const Spectral_options& opt, long long spent, int& attempt, const Report& report,
                             const Run& run, const Below& below, const std::string& missed)
{
  Spectral_options run_opt = opt;
  Eigen::Index block = 0;
  for(attempt = 1;; ++attempt) {
    // With a deflated null space, the Krylov run looks for the pairs above its c zeros only.
    const Eigen::Index m = std::min<Eigen::Index>(std::max<Eigen::Index>(k - c, 0) + extra, n - c - 2);
    if(opt.block_size <= 0) {
      block = std::max(block, default_block_size(m));
      run_opt.block_size = int(block);
    }
    Spectral_pairs pairs;
    try {
      pairs = run(m, run_opt, spent);
    } catch(const Stalled_run& stalled) {
      if(attempt >= 4) throw Numerical_error(stalled.what());
      spent += stalled.operations;
      block = block_after_stall(block, m, opt, stalled);
      continue;
    }
    spent += pairs.operations;
    pairs.operations = spent;
    pairs.attempts = attempt;
    if(pairs.values.size() == 0 || !opt.check_completeness) return pairs;
    bool checking = false;
    const auto counted_below = [&](double tau) {
      if(!checking) report("checking completeness", spent);
      checking = true;
      return below(tau);
    };
    if(const Eigen::Index keep = verified_count(pairs.values, k, counted_below)) {
      pairs.values.conservativeResize(keep);
      pairs.vectors.conservativeResize(Eigen::NoChange, keep);
      return pairs;
    }
    // A member of a repeated eigenvalue was missed, or the cluster of lambda_{k-1} extends past
    // the computed pairs: ask for more.
    if(attempt >= 4 || m >= n - c - 2)
      throw Numerical_error("spectral solver: could not obtain a complete set of the " + std::to_string(k) +
                            " smallest eigenpairs (" + missed + " after " + std::to_string(attempt) + " attempts)");
    extra = 2 * extra + 4;
    // A block of b vectors finds at most b copies of an exactly repeated eigenvalue (in exact
    // arithmetic): b copies of one value suggest that there are more, and a larger block.
    if(opt.block_size <= 0 && largest_multiplicity(pairs.values, c) >= block) block *= 2;
  }
}

/// The k smallest eigenpairs by one shift-invert Krylov run from below zero, repeated with more
/// pairs until the inertia counts verify them. With `crowded`, a first block Lanczos run whose
/// wanted values crowd far above the shift (Crowding_watch) is given up: the result then holds
/// no pairs, and `crowded` the estimates.
template <typename Factor>
Spectral_pairs smallest_eigenpairs_with(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass,
                                        Eigen::Index k, const Spectral_options& opt,
                                        Eigen::VectorXd* crowded = nullptr)
{
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const Eigen::Index n = mass.size();
  auto elapsed = [&] { return std::chrono::duration<double>(clock::now() - t0).count(); };
  int attempt = 1;
  auto report = [&](const char* stage, long long ops) {
    if(opt.progress) opt.progress(Spectral_progress{stage, ops, attempt, elapsed()});
  };

  const Eigen::Index extra = extra_pairs(k, opt);
  // Small problems, or nearly the whole spectrum: Krylov needs m < n, use a dense solver.
  if(solved_densely(n, k + extra, opt)) {
    report("dense eigen-solver", 0);
    return dense_smallest_eigenpairs(stiffness, mass, std::min<Eigen::Index>(n, k + extra));
  }
  if(k >= n - 1)
    throw Numerical_error("spectral solver: k = " + std::to_string(k) + " needs the dense solver, which is limited to " +
                          std::to_string(opt.dense_limit) + " vertices");

  const double sigma = -opt.shift_factor / mass.sum();
  const Eigen::VectorXd sqrt_mass = mass.cwiseSqrt();
  Eigen::SparseMatrix<double> K = shifted_pencil(stiffness, mass, sigma);
  report("factorising", 0);
  Factor factor;
  prepare_for_many_solves(factor);
  factorise_or_throw(factor, K);
  release(K);
  // Made at the first check, after the Krylov basis is gone: its matrix and structure would
  // otherwise add to the run's peak memory.
  std::optional<Eigenvalue_counter<Factor>> counter;
  const Null_space_deflation null_space(stiffness, mass);
  const Eigen::Index c = null_space.count();  // 0 on a connected mesh
  const Deflated_solve<Factor> deflated(factor, null_space, mass);
  const std::function<void(long long)> on_op = [&](long long ops) {
    if(opt.progress) report("lanczos", ops);
  };
  bool factor_overwritten = false;
  const auto run = [&](Eigen::Index m, const Spectral_options& run_opt, long long spent) {
    if(factor_overwritten) {  // the last check used the factor's memory: factorise again (same analysis)
      report("factorising", spent);
      K = shifted_pencil(stiffness, mass, sigma);
      factor.factorize(K);
      if(factor.info() != Eigen::Success) factorise_or_throw(factor, K);
      release(K);
      factor_overwritten = false;
    }
    Crowding_watch watch;
    Crowding_watch* watching = attempt == 1 && crowded ? &watch : nullptr;
    constexpr int stall = stalled_run_restarts;
    Spectral_pairs pairs = c > 0 ? lanczos_run(deflated, sqrt_mass, sigma, m, run_opt, on_op, watching, stall)
                                 : lanczos_run(factor, sqrt_mass, sigma, m, run_opt, on_op, watching, stall);
    if(watch.estimates.size() > 0)
      *crowded = std::move(watch.estimates);  // given up: no pairs
    else if(c > 0)
      null_space.prepend_null_space(pairs, mass);
    return pairs;
  };
  // The eigenvalues below tau, by inertia; the counter is made at the first check.
  const auto count_below = [&](double tau) {
    if(!counter) counter.emplace(factor, stiffness, mass);
    factor_overwritten = counter->overwrites_factor();
    return counter->below(tau);
  };
  return verified_runs(n, k, c, extra, opt, 0, attempt, report, run, count_below, "repeated eigenvalues missed");
}

/// A shift for the eigenvalues that a given-up run's `estimates` (ascending) locate roughly: c
/// eigenvalues (the null space's) lie below it, and the smallest other one lies above it by less
/// than a tenth of the wanted ones' width, so that they are well separated seen from it. Both
/// the smallest non-null eigenvalue and the largest wanted one are bracketed by inertia counts
/// (`ldlt.factorize_at()`) and bisected; the estimates, Ritz values, bound them from above.
/// `sigma0` lies below every eigenvalue (where c == 0: a pencil with no known null space). None
/// when the counts contradict the estimates: an eigenvalue far below them, or fewer than c
/// eigenvalues at round-off from zero.
inline std::optional<double> shift_below_crowded(Shifted_ldlt& ldlt, Eigen::Index c, const Eigen::VectorXd& estimates,
                                                 double sigma0)
{
  const Eigen::Index last = estimates.size() - 1, first = first_beyond_zero(estimates);
  const Eigen::Index target = c + (last - first + 1);  // eigenvalues up to the largest wanted
  const double scale = std::abs(estimates[last]);
  const double spread = std::max(estimates[last] - estimates[first], 1e-12 * scale);
  // Brackets: c eigenvalues below a_lo, more below a_hi; fewer than `target` below b_lo, at least
  // as many below b_hi.
  const double lowest = 1e-3 * estimates[first];  // with a null space: clear of its round-off at 0
  double a_lo = estimates[first] - spread;
  for(double step = spread;;) {
    if(c == 0 && a_lo <= sigma0) {
      a_lo = sigma0;
      break;
    }
    const bool at_lowest = c > 0 && a_lo <= lowest;
    if(at_lowest) a_lo = lowest;
    const Eigen::Index count = ldlt.factorize_at(a_lo);
    if(count == c) break;
    if(count < c || at_lowest) return std::nullopt;
    step *= 4;  // an eigenvalue below the estimates
    a_lo = estimates[first] - step;
  }
  double b_hi = estimates[last] + 1e-9 * scale;
  for(double step = spread; ldlt.factorize_at(b_hi) < target; step *= 4) b_hi += step;
  double a_hi = b_hi, b_lo = a_lo;
  const double resolution = 1e-13 * scale;
  // Done when the a bracket is a tenth of the least width of the wanted values, b_lo - a_hi,
  // or at the resolution (a value repeated through the wanted range: no width).
  for(int i = 0; i < 200 && a_hi - a_lo > std::max(0.1 * (b_lo - a_hi), resolution); ++i) {
    // Bisect the a bracket, unless the b bracket is wider: the width is not yet known.
    const bool split_a = a_hi - a_lo >= b_hi - b_lo;
    const double mid = split_a ? 0.5 * (a_lo + a_hi) : 0.5 * (b_lo + b_hi);
    const Eigen::Index count = ldlt.factorize_at(mid);
    if(count < c) return std::nullopt;
    if(count == c) a_lo = std::max(a_lo, mid);
    else a_hi = std::min(a_hi, mid);
    if(count < target) b_lo = std::max(b_lo, mid);
    else b_hi = std::min(b_hi, mid);
  }
  return a_lo;
}

/// The k smallest eigenpairs when they crowd together far above the null space (Crowding_watch;
/// `estimates` are a given-up run's, ascending): a block Lanczos run from a shift just below
/// the smallest non-null eigenvalue, which inertia counts locate by bisection, on the complement
/// of the null space (the constants of every component, the one of a connected mesh too: it lies
/// below the shift). `operations` are those spent, since `start`, before. None when the shift
/// cannot be placed (shift_below_crowded()).
inline std::optional<Spectral_pairs> reshifted_eigenpairs(const Eigen::SparseMatrix<double>& stiffness,
                                                          const Eigen::VectorXd& mass, Eigen::Index k,
                                                          const Spectral_options& opt, const Eigen::VectorXd& estimates,
                                                          long long operations,
                                                          std::chrono::steady_clock::time_point start)
{
  using clock = std::chrono::steady_clock;
  int attempt = 1;
  auto report = [&](const char* stage, long long ops) {
    if(opt.progress)
      opt.progress(Spectral_progress{stage, ops, attempt, std::chrono::duration<double>(clock::now() - start).count()});
  };
  const Eigen::Index n = mass.size();
  const Eigen::VectorXd sqrt_mass = mass.cwiseSqrt();
  const Null_space_deflation null_space(stiffness, mass, 1);
  const Eigen::Index c = null_space.count();  // 0: not a Laplacian, no known null space
  report("locating the crowded eigenvalues", operations);
  Shifted_ldlt ldlt(stiffness, mass);

  const std::optional<double> shift = shift_below_crowded(ldlt, c, estimates, -opt.shift_factor / mass.sum());
  if(!shift) return std::nullopt;
  const double sigma = *shift;

  const Deflated_solve<Shifted_ldlt> deflated(ldlt, null_space, mass);
  long long run_start = operations;
  const std::function<void(long long)> on_op = [&](long long ops) {
    if(opt.progress) report("lanczos", run_start + ops);
  };
  const auto run = [&](Eigen::Index m, const Spectral_options& run_opt, long long spent) {
    run_start = spent;
    ldlt.factorize_at(sigma);  // again: the counts overwrite it
    constexpr int stall = stalled_run_restarts;
    Spectral_pairs pairs = c > 0 ? lanczos_run(deflated, sqrt_mass, sigma, m, run_opt, on_op, nullptr, stall)
                                 : lanczos_run(ldlt, sqrt_mass, sigma, m, run_opt, on_op, nullptr, stall);
    if(c > 0) null_space.prepend_null_space(pairs, mass);
    return pairs;
  };
  const auto count_below = [&](double tau) { return ldlt.factorize_at(tau); };
  return verified_runs(n, k, c, extra_pairs(k, opt), opt, operations, attempt, report, run, count_below,
                       "eigenvalues crowded above the shift " + message_number(sigma) + " missed");
}

/// smallest_eigenpairs_with(), and reshifted_eigenpairs() when its first run gives up; the first
/// run again, unwatched, when the second cannot place its shift.
template <typename Factor>
Spectral_pairs smallest_eigenpairs_reshifting(const Eigen::SparseMatrix<double>& stiffness,
                                              const Eigen::VectorXd& mass, Eigen::Index k, const Spectral_options& opt)
{
  const auto start = std::chrono::steady_clock::now();
  Eigen::VectorXd crowded;
  Spectral_pairs pairs = smallest_eigenpairs_with<Factor>(stiffness, mass, k, opt, &crowded);
  if(crowded.size() == 0) return pairs;
  // Given up: `pairs` holds no pairs, and the first run's factor is gone before the second.
  const long long spent = pairs.operations;
  if(std::optional<Spectral_pairs> reshifted = reshifted_eigenpairs(stiffness, mass, k, opt, crowded, spent, start))
    return std::move(*reshifted);
  pairs = smallest_eigenpairs_with<Factor>(stiffness, mass, k, opt);
  pairs.operations += spent;
  return pairs;
}

/// The k smallest eigenpairs of a pencil solved whole: bands or one run, the Cholesky chosen.
inline Spectral_pairs eigenpairs_of_pencil(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass,
                                           Eigen::Index k, const Spectral_options& opt)
{
  const Eigen::Index n = mass.size();
  // Measured (doc/spectral.md): one block Lanczos run re-orthogonalises a basis of about twice
  // k vectors at every step, bands of 40 pay a factorisation per band. The run's cost grows
  // faster with k, the bands' with n: since their exact windows the bands win from about
  // k = n / 175. Below k = 200 they lost on some meshes (an icosphere, identical parts). For
  // very large k they also keep the memory near the result's own.
  const bool bands_by_default = k >= 200 && (175 * k > n || k > 1000);
  const int band_size = opt.band_size >= 0 ? opt.band_size : (bands_by_default ? 40 : 0);
  if(band_size > 0 && k > band_size && !solved_densely(n, k, opt))
  {
    Spectral_options o = opt;
    o.band_size = band_size;
    return banded_eigenpairs(stiffness, mass, k, o);
  }
  if(opt.cholesky == Sparse_cholesky::cholmod) {
#ifdef LAPMESH_HAS_CHOLMOD
    return smallest_eigenpairs_reshifting<Cholmod_supernodal_llt>(stiffness, mass, k, opt);
#else
    throw std::invalid_argument("Sparse_cholesky::cholmod requested, but lapmesh was compiled without "
                                "LAPMESH_HAS_CHOLMOD");
#endif
  }
  using Simplicial_llt = Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower>;
  return smallest_eigenpairs_reshifting<Simplicial_llt>(stiffness, mass, k, opt);
}

/// A part of a pencil with copies (eigenpairs_of_copies()): a class of copies, solved on its
/// first component, or the components without a copy, solved together.
struct Copied_part
{
  std::vector<const std::vector<int>*> placements;  ///< the rows of each copy in the whole (one for the rest)
  Eigen::SparseMatrix<double> stiffness;
  Eigen::VectorXd mass;
  Eigen::Index asked = 0;
  Eigen::Index null_pairs = 0;  ///< its first pairs, the null space's, taken exactly instead
  Spectral_pairs pairs;
  double complete_below = 0;  ///< every eigenvalue of the part below it is held
};

/// The pairs of a class's first component carried to another copy: a Rayleigh-Ritz step on the
/// copy's own S and M (which agree with the first's to round-off) in the span of the vectors,
/// so that the copy's vectors are M-orthonormal for its own M.
inline Spectral_pairs pairs_on_copy(const Spectral_pairs& first, const Eigen::SparseMatrix<double>& stiffness,
                                    const Eigen::VectorXd& mass)
{
  const Eigen::MatrixXd& Phi = first.vectors;
  Eigen::MatrixXd H = -(Phi.transpose() * (stiffness * Phi));
  Eigen::MatrixXd G = Phi.transpose() * (mass.asDiagonal() * Phi);
  H = 0.5 * (H + H.transpose()).eval();
  G = 0.5 * (G + G.transpose()).eval();
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> ritz(H, G);
  if(ritz.info() != Eigen::Success) throw Numerical_error("spectral solver: the Rayleigh-Ritz step on a copied part failed");
  Spectral_pairs out;
  out.values = ritz.eigenvalues();
  out.vectors = Phi * ritz.eigenvectors();
  return out;
}

/// The k smallest eigenpairs of a pencil whose components include copies of one another (an
/// assembly's repeated parts, see component_copies.h): each class solved once, on its first
/// component, for a share of the k pairs (one more than k over its copies), the components
/// without a copy solved together, and the values merged. A class's pairs reach its other
/// copies by pairs_on_copy(), and one inertia count of the whole pencil checks the merge at the
/// first gap past lambda_{k-1}. A part whose held values do not reach that gap is asked for
/// twice as many, up to four rounds. The held set ends at the gap, or one past lambda_{k-1}
/// inside its eigenspace (as a run's, verified_count()), or after the whole null space. None
/// when a part needs the dense solver past its limit, the rounds run out, or the count
/// disagrees with the merge: the caller then solves the pencil whole. `operations` receives the
/// shift-invert solves spent, held or not (a solve whole after it counts them too).
inline std::optional<Spectral_pairs> eigenpairs_of_copies(const Eigen::SparseMatrix<double>& stiffness,
                                                          const Eigen::VectorXd& mass, Eigen::Index k,
                                                          const Spectral_options& opt, const Component_copies& copies,
                                                          long long& operations)
{
  const Eigen::Index n = mass.size();
  operations = 0;
  // On a Laplacian of several components lambda = 0 once per component: those pairs are taken
  // exactly (the M-normalised indicators, as the whole pencil's solve takes them), in place of
  // each part's first ones (a class's first component: one; the rest: one per component).
  const bool null_space = rows_sum_to_zero(stiffness);
  std::vector<Copied_part> parts;
  for(const std::vector<int>& members : copies.classes) {
    Copied_part part;
    part.null_pairs = null_space ? 1 : 0;
    for(const int c : members) part.placements.push_back(&copies.rows[std::size_t(c)]);
    std::tie(part.stiffness, part.mass) = restricted_pencil(stiffness, mass, *part.placements.front(), copies.position);
    // Its share of the k pairs and a quarter more: a symmetric part's last group of values
    // often crosses the bare share, and a second round costs more than the margin.
    const Eigen::Index count = Eigen::Index(members.size()), share = (k + count - 1) / count;
    part.asked = share + 1 + share / 4;
    parts.push_back(std::move(part));
  }
  std::vector<int> rest;
  if(!copies.singles.empty()) {
    for(const int c : copies.singles) rest.insert(rest.end(), copies.rows[std::size_t(c)].begin(), copies.rows[std::size_t(c)].end());
    std::sort(rest.begin(), rest.end());
    std::vector<int> position(std::size_t(n), -1);
    for(std::size_t i = 0; i < rest.size(); ++i) position[std::size_t(rest[i])] = int(i);
    Copied_part part;
    part.null_pairs = null_space ? Eigen::Index(copies.singles.size()) : 0;
    part.placements.push_back(&rest);
    std::tie(part.stiffness, part.mass) = restricted_pencil(stiffness, mass, rest, position);
    part.asked = k + 1;
    parts.push_back(std::move(part));
  }

  Spectral_pairs out;
  out.dense = true;
  // The parts' solves report as one solve: their time from this call's start, their solves
  // after those of the parts before them.
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  Spectral_options part_opt = opt;
  if(opt.progress)
    part_opt.progress = [&](const Spectral_progress& p) {
      opt.progress(Spectral_progress{p.stage, out.operations + p.operations, p.attempt, elapsed()});
    };
  struct Entry
  {
    double value;
    int part;  // -1: the null vector of component `copy`
    Eigen::Index pair;
    int copy;
  };
  const auto by_value = [](const Entry& a, const Entry& b) { return a.value < b.value; };
  std::vector<Entry> merged;
  Eigen::VectorXd values;
  Eigen::Index end = -1;  // the last member of lambda_{k-1}'s eigenspace among the merged values
  double tau = 0;
  for(int round = 0;; ++round) {
    for(Copied_part& part : parts) {
      const Eigen::Index size = part.mass.size();
      part.asked = std::min(part.asked, size);
      if(part.pairs.values.size() >= part.asked) continue;
      if(part.asked >= size - 1 && size > opt.dense_limit) return std::nullopt;
      // A part solved densely for twice the pairs a run would seek (a small part, or one a
      // Krylov basis would mostly span) is solved whole: its every eigenspace is then complete,
      // and no second round asks it again.
      const bool dense = solved_densely(size, 2 * (part.asked + extra_pairs(part.asked, opt)), opt);
      part.pairs = dense ? dense_smallest_eigenpairs(part.stiffness, part.mass, size)
                         : eigenpairs_of_pencil(part.stiffness, part.mass, part.asked, part_opt);
      out.operations += part.pairs.operations;
      operations = out.operations;
      out.attempts = std::max(out.attempts, part.pairs.attempts);
      out.dense = out.dense && part.pairs.dense;
      const Eigen::VectorXd& v = part.pairs.values;
      part.complete_below =
        v.size() == size ? std::numeric_limits<double>::infinity() : v[eigenspace_start(v, v.size() - 1)];
    }
    merged.clear();
    if(null_space)
      for(int c = 0; c < int(copies.rows.size()); ++c) merged.push_back({0.0, -1, 0, c});
    double complete_below = std::numeric_limits<double>::infinity();
    for(int p = 0; p < int(parts.size()); ++p) {
      complete_below = std::min(complete_below, parts[std::size_t(p)].complete_below);
      const Eigen::VectorXd& v = parts[std::size_t(p)].pairs.values;
      for(Eigen::Index i = parts[std::size_t(p)].null_pairs; i < v.size(); ++i)
        for(int c = 0; c < int(parts[std::size_t(p)].placements.size()); ++c) merged.push_back({v[i], p, i, c});
    }
    std::stable_sort(merged.begin(), merged.end(), by_value);
    values.resize(Eigen::Index(merged.size()));
    for(std::size_t i = 0; i < merged.size(); ++i) values[Eigen::Index(i)] = merged[i].value;
    end = values.size() >= k ? cluster_end(values, k) : -1;
    tau = end >= 0 ? 0.5 * (values[end] + values[end + 1]) : std::numeric_limits<double>::infinity();
    if(end >= 0 && tau < complete_below) break;
    bool more = false;
    for(Copied_part& part : parts)
      if(part.complete_below <= tau && part.pairs.values.size() < part.mass.size()) {
        part.asked = 2 * part.pairs.values.size() + 2;
        more = true;
      }
    if(!more || round == 3) return std::nullopt;
  }
  if(opt.check_completeness) {
    if(opt.progress) opt.progress(Spectral_progress{"checking completeness", out.operations, 1, elapsed()});
    Shifted_ldlt ldlt(stiffness, mass);
    if(ldlt.factorize_at(tau) != end + 1) return std::nullopt;
  }
  const Eigen::Index keep = end == k - 1 || eigenspace_start(values, k - 1) == 0 ? end + 1 : k + 1;

  // Each part's leading pairs that the held set uses, to the end of the last one's eigenspace
  // (an invariant subspace, for the Rayleigh-Ritz step); then those pairs on each copy that holds
  // one of them.
  std::vector<Spectral_pairs> leading(parts.size());
  std::vector<Eigen::Index> used(parts.size(), 0);
  for(Eigen::Index j = 0; j < keep; ++j)
    if(const Entry& e = merged[std::size_t(j)]; e.part >= 0)
      used[std::size_t(e.part)] = std::max(used[std::size_t(e.part)], e.pair + 1);
  for(std::size_t p = 0; p < parts.size(); ++p) {
    if(used[p] == 0) continue;
    const Eigen::VectorXd& v = parts[p].pairs.values;
    const Eigen::Index last = cluster_end(v, used[p]);
    const Eigen::Index count = last >= 0 ? last + 1 : v.size();
    leading[p].values = v.head(count);
    leading[p].vectors = parts[p].pairs.vectors.leftCols(count);
  }
  std::vector<std::vector<Spectral_pairs>> on_copy(parts.size());
  for(std::size_t p = 0; p < parts.size(); ++p) on_copy[p].resize(parts[p].placements.size());
  for(Eigen::Index j = 0; j < keep; ++j) {
    const Entry& e = merged[std::size_t(j)];
    if(e.part < 0) continue;
    Spectral_pairs& pairs = on_copy[std::size_t(e.part)][std::size_t(e.copy)];
    if(pairs.values.size() > 0) continue;
    const Copied_part& part = parts[std::size_t(e.part)];
    if(e.copy == 0) {
      pairs = leading[std::size_t(e.part)];
    } else {
      const auto copy = restricted_pencil(stiffness, mass, *part.placements[std::size_t(e.copy)], copies.position);
      pairs = pairs_on_copy(leading[std::size_t(e.part)], copy.first, copy.second);
    }
  }
  std::vector<Entry> held(merged.begin(), merged.begin() + keep);
  for(Entry& e : held)
    if(e.part >= 0) e.value = on_copy[std::size_t(e.part)][std::size_t(e.copy)].values[e.pair];
  std::stable_sort(held.begin(), held.end(), by_value);
  out.values.resize(keep);
  out.vectors = Eigen::MatrixXd::Zero(n, keep);
  for(Eigen::Index j = 0; j < keep; ++j) {
    const Entry& e = held[std::size_t(j)];
    out.values[j] = e.value;
    if(e.part < 0) {
      const std::vector<int>& rows = copies.rows[std::size_t(e.copy)];
      double component_mass = 0;
      for(const int r : rows) component_mass += mass[r];
      for(const int r : rows) out.vectors(r, j) = 1.0 / std::sqrt(component_mass);
      continue;
    }
    const std::vector<int>& rows = *parts[std::size_t(e.part)].placements[std::size_t(e.copy)];
    const Eigen::MatrixXd& vectors = on_copy[std::size_t(e.part)][std::size_t(e.copy)].vectors;
    for(std::size_t i = 0; i < rows.size(); ++i) out.vectors(rows[i], j) = vectors(Eigen::Index(i), e.pair);
  }
  return out;
}

inline Spectral_pairs smallest_eigenpairs(const Eigen::SparseMatrix<double>& stiffness, const Eigen::VectorXd& mass,
                                          Eigen::Index k, const Spectral_options& opt)
{
  const Eigen::Index n = mass.size();
  if(k < 1 || k > n)
    throw std::invalid_argument("the number of eigenpairs k = " + std::to_string(k) + " is outside [1, " +
                                std::to_string(n) + "]");
  if(!(mass.array() > 0).all()) throw Numerical_error("spectral solver: the mass matrix must be positive");
  if(opt.solve_copies_once)
    if(const std::optional<Component_copies> copies = find_component_copies(stiffness, mass)) {
      const auto start = std::chrono::steady_clock::now();
      long long spent = 0;
      if(std::optional<Spectral_pairs> pairs = eigenpairs_of_copies(stiffness, mass, k, opt, *copies, spent))
        return std::move(*pairs);
      // Solved whole after all: its reports go on from the copies path's time and solves, and
      // its count includes them.
      Spectral_options whole = opt;
      const double before = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if(opt.progress)
        whole.progress = [&](const Spectral_progress& p) {
          opt.progress(Spectral_progress{p.stage, spent + p.operations, p.attempt, before + p.elapsed_seconds});
        };
      Spectral_pairs pairs = eigenpairs_of_pencil(stiffness, mass, k, whole);
      pairs.operations += spent;
      return pairs;
    }
  return eigenpairs_of_pencil(stiffness, mass, k, opt);
}

} // namespace internal
} // namespace lapmesh

#endif
