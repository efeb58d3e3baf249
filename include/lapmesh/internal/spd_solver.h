// Internal: sparse symmetric positive definite systems with Dirichlet constraints.
//
// Constrained_spd_system keeps the free block A_FF (lower triangle) of a matrix
// A = d_scale diag(d) + s_scale S, S symmetric with a fixed pattern, and moves the terms of the
// fixed (constrained) unknowns to the right-hand side, in the manner of pmp's
// cholesky_solve(A, B, is_constrained, C): A_FF X_F = B_F - A_FB X_B. Its pattern and the map
// slot-of-S -> slot-of-A_FF are built once; refilling only rewrites values.
//
// Spd_direct_solver factorises A_FF: Eigen's SimplicialLDLT, CHOLMOD's supernodal LL^T, or a
// user's CGAL solver; the symbolic analysis is done once, each refactorisation is numeric only.
// For CHOLMOD the free block is built in the order of its fill-reducing permutation: CHOLMOD
// then neither copies the matrix into that order at each factorisation (two copies of the
// block beside the factor) nor the right-hand sides at each solve.
#ifndef LAPMESH_INTERNAL_SPD_SOLVER_H
#define LAPMESH_INTERNAL_SPD_SOLVER_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/cholmod.h>
#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/parallel.h>
#include <lapmesh/internal/subnormals.h>
#include <lapmesh/internal/row_sort.h>
#include <lapmesh/internal/topology.h>

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace lapmesh {
namespace internal {

/// The free block of a symmetric sparse matrix and the right-hand side contribution of the
/// fixed unknowns.
class Constrained_spd_system
{
public:
  using SpMat = Eigen::SparseMatrix<double>;

  /// `pattern`: a compressed symmetric matrix (its values are not read); `free_mask[i]` = 0 for
  /// a fixed unknown; `order`: empty (the free unknowns in index order), or the order of the
  /// block's rows: row k is the order[k]-th free unknown (the solver's fill-reducing order).
  Constrained_spd_system(const SpMat& pattern, std::vector<char> free_mask, const std::vector<Index>& order = {})
      : m_free(std::move(free_mask))
  {
    const Index n = Index(pattern.rows());
    const Index* outer = pattern.outerIndexPtr();
    const Index* inner = pattern.innerIndexPtr();
    m_free_index.assign(std::size_t(n), -1);
    Index nf = 0;
    for(Index i = 0; i < n; ++i)
      if(m_free[i]) m_free_index[i] = nf++;
    if(!order.empty()) {
      if(Index(order.size()) != nf) throw std::logic_error("Constrained_spd_system: the order does not fit the free unknowns");
      std::vector<Index> row_of(static_cast<std::size_t>(nf));
      for(Index k = 0; k < nf; ++k) row_of[order[k]] = k;
      for(Index i = 0; i < n; ++i)
        if(m_free[i]) m_free_index[i] = row_of[m_free_index[i]];
    }
    std::vector<Index> unknown_of_row(static_cast<std::size_t>(nf));
    for(Index i = 0; i < n; ++i)
      if(m_free[i]) unknown_of_row[m_free_index[i]] = i;
    m_A.resize(nf, nf);
    m_diagonal.resize(std::size_t(nf));
    std::vector<Index> a_outer(nf + 1, 0), a_inner;
    a_inner.reserve(std::size_t(pattern.nonZeros()) / 2 + nf);
    m_source.reserve(a_inner.capacity());
    for(Index c = 0; c < nf; ++c) {
      const Index j = unknown_of_row[c];
      const std::size_t begin = a_inner.size();
      for(Index k = outer[j]; k < outer[j + 1]; ++k) {  // column j = row j (symmetric pattern)
        const Index i = inner[k];
        if(!m_free[i] || m_free_index[i] < c) continue;
        a_inner.push_back(m_free_index[i]);
        m_source.push_back(k);
      }
      // Rows in increasing order, as the solvers expect; in a given order they come unsorted.
      sort_row(a_inner.data() + begin, a_inner.size() - begin, m_source.data() + begin);
      if(a_inner.size() == begin || a_inner[begin] != c)
        throw std::logic_error("Constrained_spd_system: the pattern lacks a diagonal entry");
      m_diagonal[c] = Index(begin);
      a_outer[c + 1] = Index(a_inner.size());
    }
    m_A.resizeNonZeros(Index(a_inner.size()));
    std::copy(a_outer.begin(), a_outer.end(), m_A.outerIndexPtr());
    std::copy(a_inner.begin(), a_inner.end(), m_A.innerIndexPtr());
  }

  Index size() const { return Index(m_A.rows()); }
  /// Whether every unknown is free (no fixed one).
  bool all_free() const { return size() == Index(m_free.size()); }
  /// The lower triangle of A_FF (the pattern is set at construction; values by fill_matrix()).
  const SpMat& matrix() const { return m_A; }
  bool is_free(Index i) const { return m_free[i] != 0; }
  /// Row of unknown i in the free block (-1 for a fixed one).
  Index free_index(Index i) const { return m_free_index[i]; }

  /// A_FF = d_scale diag(d)_FF + s_scale S_FF, S with the pattern given at construction.
  void fill_matrix(const SpMat& S, double s_scale, const Eigen::VectorXd& d, double d_scale)
  {
    fill_matrix(S.valuePtr(), s_scale, d, d_scale);
  }
  /// fill_matrix() from S's values alone, in the pattern given at construction.
  void fill_matrix(const double* values, double s_scale, const Eigen::VectorXd& d, double d_scale)
  {
    if(m_source.size() != std::size_t(m_A.nonZeros()))
      throw std::logic_error("Constrained_spd_system: fill_matrix() after release_fill_map()");
    double* a = m_A.valuePtr();
    const Index na = m_A.nonZeros();
    for(Index k = 0; k < na; ++k) a[k] = s_scale * values[m_source[k]];
    for(Index i = 0; i < Index(m_free.size()); ++i)
      if(m_free[i]) a[m_diagonal[m_free_index[i]]] += d[i] * d_scale;
  }

  /// Makes the rows and columns of the free unknowns marked in `mask` those of the identity. For
  /// unknowns that couple with no unmarked one, where the factorisation's pattern needs no
  /// change: the solve then returns their right-hand side exactly.
  void set_identity_rows(const std::vector<char>& mask)
  {
    double* a = m_A.valuePtr();
    const Index* outer = m_A.outerIndexPtr();
    for(Index i = 0; i < Index(m_free.size()); ++i) {
      if(!m_free[i] || !mask[i]) continue;
      const Index c = m_free_index[i];
      std::fill(a + outer[c], a + outer[c + 1], 0.0);
      a[m_diagonal[c]] = 1;
    }
  }

  /// Frees the slots of S that fill_matrix() reads, for a caller that fills the matrix no more:
  /// they are not held beside a factorisation of the last matrix.
  void release_fill_map() { std::vector<Index>().swap(m_source); }

  /// B_F = d_scale diag(d)_FF X_F - A_FB X_B for A as in fill_matrix(): row i of B is the free
  /// row of unknown i; X holds the current values, its fixed rows the constraints. S: a
  /// compressed sparse matrix or a map of one, read only for the fixed unknowns' terms: not at
  /// all when every unknown is free (all_free()).
  template <typename Sparse, typename Values, typename Rhs>
  void fill_rhs(const Sparse& S, double s_scale, const Eigen::VectorXd& d, double d_scale, const Values& X, Rhs& B,
                bool parallel) const
  {
    const double* values = S.valuePtr();
    const Index* outer = S.outerIndexPtr();
    const Index* inner = S.innerIndexPtr();
    const bool fixed_terms = !all_free();
    for_each_index(Index(m_free.size()), parallel, [&](Index i) {
      if(!m_free[i]) return;
      Eigen::Vector3d b = (d[i] * d_scale) * X.row(i).transpose();
      if(fixed_terms)
        for(Index k = outer[i]; k < outer[i + 1]; ++k)
          if(!m_free[inner[k]]) b -= s_scale * values[k] * X.row(inner[k]).transpose();
      B.row(m_free_index[i]) = b.transpose();
    });
  }

  /// The free rows of X, in the order of the free block.
  template <typename Values, typename Block>
  void gather(const Values& X, Block& Y) const
  {
    for(Index i = 0; i < Index(m_free.size()); ++i)
      if(m_free[i]) Y.row(m_free_index[i]) = X.row(i);
  }
  /// Writes the free block Y back into the free rows of X; fixed rows are not touched.
  template <typename Block, typename Values>
  void scatter(const Block& Y, Values& X) const
  {
    for(Index i = 0; i < Index(m_free.size()); ++i)
      if(m_free[i]) X.row(i) = Y.row(m_free_index[i]);
  }

private:
  std::vector<char> m_free;
  std::vector<Index> m_free_index;
  std::vector<Index> m_source;    // slot of S feeding each slot of A_FF
  std::vector<Index> m_diagonal;  // slot of each diagonal entry of A_FF
  SpMat m_A;
};

/// Sparse Cholesky of an SPD matrix given by its lower triangle: Eigen's SimplicialLDLT (AMD),
/// or, when compiled with LAPMESH_HAS_CHOLMOD (and linked with libcholmod), CHOLMOD's
/// supernodal LL^T (internal/cholmod.h). Ordering: AMD, and METIS too where the planned
/// factorisations of AMD's ordering would take longer than METIS's analysis, or where AMD's
/// factor is large (Cholmod_supernodal_llt::Ordering::amd_or_metis): METIS orders much more
/// slowly than AMD and pays only through cheaper factorisations or a smaller factor.
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
    // A smoothing run factorises a new matrix at every step: lapmesh's numeric factorisation
    // where the supernodes are small (Cholmod_supernodal_llt::Numeric).
    m_chol.set_numeric(Cholmod_supernodal_llt::Numeric::fastest);
#else
    (void)use_cholmod;
#endif
  }
  const char* name() const
  {
    return m_external.factor ? "sparse_linear_solver" : m_cholmod ? "cholmod-supernodal" : "eigen-ldlt";
  }

  /// With CHOLMOD: the factor entries from which METIS is tried beside AMD for memory
  /// (Cholmod_supernodal_llt::Ordering::amd_or_metis).
  void set_large_factor_entries(double entries)
  {
#ifdef LAPMESH_HAS_CHOLMOD
    m_chol.set_large_factor_entries(entries);
#else
    (void)entries;
#endif
  }
  /// The memory of the factor's values when it holds at least `count` of them, for a caller that
  /// writes into it what the next factorize() reads no more; nullptr otherwise (no factor of
  /// CHOLMOD's with values).
  double* values_to_overwrite(std::size_t count)
  {
#ifdef LAPMESH_HAS_CHOLMOD
    const std::size_t held = factor_values();  // 0 without a factor of CHOLMOD's
    if(held > 0 && held >= count && m_chol.factor()->xtype == CHOLMOD_REAL) return m_chol.values_to_overwrite();
#endif
    (void)count;
    return nullptr;
  }

  /// The fill-reducing ordering of the last analyze(): "amd", "metis", or "" (Eigen's
  /// SimplicialLDLT, which orders by AMD, or a user's solver).
  const char* ordering() const { return m_ordering; }
  /// The entries of the factor that the last analysis planned (0 without CHOLMOD).
  double factor_entries()
  {
#ifdef LAPMESH_HAS_CHOLMOD
    if(m_cholmod && !m_external.factor) return m_chol.cholmod().lnz;
#endif
    return 0;
  }

  /// The values that the factor of the last analysis holds, explicit zeros of its supernodes
  /// included (0 without CHOLMOD).
  std::size_t factor_values() const
  {
#ifdef LAPMESH_HAS_CHOLMOD
    if(m_cholmod && !m_external.factor && m_chol.factor()) return std::size_t(m_chol.factor()->xsize);
#endif
    return 0;
  }

  /// The symbolic analysis of A. With CHOLMOD it returns the fill-reducing order it chose: the
  /// caller rebuilds the matrix in that order (Constrained_spd_system's `order`) and hands it to
  /// analyze_in_order(), after which CHOLMOD factorises it without permuted copies and solves in
  /// place. Otherwise the result is empty and the analysis is complete.
  std::vector<Index> analyze(const SpMat& A, int planned_factorizations)
  {
    // The analysis and the factor take much memory that the cache of working arrays does not
    // serve: emptied of its large mappings first, the cache does not add to the call's peak.
    release_cached_large_arrays();
    if(m_external.factor) return {};  // the user's solver analyses in its factor()
#ifdef LAPMESH_HAS_CHOLMOD
    if(m_cholmod) {
      m_chol.set_ordering(Cholmod_supernodal_llt::Ordering::amd_or_metis);
      m_chol.set_planned_factorizations(planned_factorizations);
      m_chol.analyzePattern(A);
      if(m_chol.info() != Eigen::Success) throw Numerical_error("the symbolic analysis (CHOLMOD) of the smoothing system failed");
      m_ordering = m_chol.factor()->ordering == CHOLMOD_METIS ? "metis" : "amd";
      const int* perm = m_chol.permutation();
      return std::vector<Index>(perm, perm + A.rows());
    }
#endif
    (void)planned_factorizations;
    m_ldlt.analyzePattern(A);
    if(m_ldlt.info() != Eigen::Success) throw Numerical_error("the symbolic analysis of the smoothing system failed");
    return {};
  }
  /// The analysis of the matrix in the order that analyze() returned.
  void analyze_in_order(const SpMat& A)
  {
#ifdef LAPMESH_HAS_CHOLMOD
    // Compact supernodes where lapmesh's numeric factorisation will make the factor (the flops
    // per entry of analyze()'s ordering are those of this analysis): the factor, most of a
    // step's memory, holds fewer explicit zeros, and the steps took no longer. CHOLMOD's
    // BLAS-based factorisation keeps the merged ones, on which it is faster (doc/smoothing.md).
    using Supernodes = Cholmod_supernodal_llt::Supernodes;
    m_chol.set_supernodes(m_chol.factorises_by_lapmesh_on(Supernodes::compact) ? Supernodes::compact
                                                                                : Supernodes::merged);
    m_chol.set_ordering(Cholmod_supernodal_llt::Ordering::given);
    m_chol.analyzePattern(A);
    if(m_chol.info() != Eigen::Success) throw Numerical_error("the symbolic analysis (CHOLMOD) of the smoothing system failed");
#else
    (void)A;
#endif
  }
  /// Whether the last factorize() was lapmesh's numeric factorisation on CHOLMOD's analysis.
  bool factorised_by_lapmesh() const
  {
#ifdef LAPMESH_HAS_CHOLMOD
    return m_cholmod && !m_external.factor && m_chol.factorised_by_lapmesh();
#else
    return false;
#endif
  }
  /// False if the matrix is not (numerically) positive definite; failure() then says why.
  bool factorize(const SpMat& A)
  {
    m_failure.clear();
    release_cached_large_arrays();  // as in analyze()
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
      // lapmesh's factorisation fails on a pivot that is not positive, with no message of CHOLMOD's.
      if(m_chol.factorised_by_lapmesh() && last_cholmod_message().empty())
        m_failure = "the supernodal LDL^T on CHOLMOD's analysis found a pivot that is not positive: not positive definite";
      else
        m_failure = "CHOLMOD " + (last_cholmod_message().empty() ? std::string("reported a numerical issue")
                                                                   : last_cholmod_message());
      return false;
    }
#endif
    {
      Subnormals_flushed_scope flushed;  // as CHOLMOD's factorize() does
      m_ldlt.factorize(A);
    }
    if(m_ldlt.info() == Eigen::Success && m_ldlt.vectorD().minCoeff() > 0) return true;
    m_failure = "Eigen's LDL^T found a pivot <= 0";
    return false;
  }
  /// Why the last factorize() failed (empty after a success).
  const std::string& failure() const { return m_failure; }
  /// Solves A X = B, X written over B (a column-major block).
  template <typename Block>
  bool solve_in_place(Block& B)
  {
    static_assert(!Block::IsRowMajor, "solve_in_place() takes a column-major block");
    if(m_external.solve) {
      Eigen::MatrixXd x;
      if(!m_external.solve(Eigen::MatrixXd(B), x) || x.rows() != B.rows() || x.cols() != B.cols()) return false;
      B = x;
      return true;
    }
    Subnormals_flushed_scope flushed;
#ifdef LAPMESH_HAS_CHOLMOD
    if(m_cholmod) {
      if(m_chol.in_given_order()) return m_chol.solve_in_place(B.data(), B.rows(), B.cols());
      const Eigen::MatrixXd x = m_chol.solve(B);
      B = x;
      return m_chol.info() == Eigen::Success;
    }
#endif
    const Eigen::MatrixXd x = m_ldlt.solve(B);
    B = x;
    return m_ldlt.info() == Eigen::Success;
  }
  /// The width of the rows that solve_rows_in_place() takes for `cols` right-hand sides: wider
  /// where CHOLMOD's factor (after analyze_in_order()) is solved by lapmesh's supernodal kernels,
  /// whose rows are padded.
  std::size_t row_width(std::size_t cols) const
  {
#ifdef LAPMESH_HAS_CHOLMOD
    if(solves_rows_in_place(cols)) return supernodal_row_width(cols);
#endif
    return cols;
  }
  /// Solves A X = B in place for B held row by row: row i at rows + i * width, its first `cols`
  /// values B's, the others (width from row_width(cols)) zero, as they stay. Where CHOLMOD's factor
  /// is in the given order the supernodal kernels solve the rows as they lie: a solve adds no copy
  /// of the block beside the factor. Through a column-major copy otherwise.
  bool solve_rows_in_place(double* rows, Index n, std::size_t width, std::size_t cols)
  {
#ifdef LAPMESH_HAS_CHOLMOD
    if(solves_rows_in_place(cols) && width == supernodal_row_width(cols)) {
      Subnormals_flushed_scope flushed;
      m_chol.solve_rows_in_place(rows, width);
      return true;
    }
#endif
    using Rows = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    Eigen::Map<Rows> by_rows(rows, n, Index(width));
    Eigen::MatrixXd B = by_rows.leftCols(Index(cols));
    if(!solve_in_place(B)) return false;
    by_rows.leftCols(Index(cols)) = B;
    return true;
  }
  /// Solves A X = B.
  template <typename Rhs, typename Solution>
  bool solve(const Rhs& B, Solution& X)
  {
    X = B;
    return solve_in_place(X);
  }

private:
#ifdef LAPMESH_HAS_CHOLMOD
  bool solves_rows_in_place(std::size_t cols) const
  {
    return m_cholmod && !m_external.solve && m_chol.factor() && m_chol.in_given_order() && supernodal_kernels_fit(cols);
  }
#endif
  External m_external;
  std::string m_failure;
  bool m_cholmod = false;
  const char* m_ordering = "";
  Eigen::SimplicialLDLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int>> m_ldlt;
#ifdef LAPMESH_HAS_CHOLMOD
  Cholmod_supernodal_llt m_chol;  // routes CHOLMOD's messages (internal/cholmod.h)
#endif
};

} // namespace internal
} // namespace lapmesh

#endif
