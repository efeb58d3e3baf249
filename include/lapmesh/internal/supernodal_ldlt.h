// lapmesh — a supernodal LDL^T without pivoting, for the inertia of the shifted pencil
// -S - tau M inside the spectrum (needs LAPMESH_HAS_CHOLMOD), and for the shift-invert factor
// where its supernodes are small (internal/cholmod.h, Cholmod_supernodal_llt::Numeric).
//
// Why. The spectral solver certifies its eigenpairs by Sylvester's law of inertia: the number
// of negative pivots of an LDL^T factorisation of -S - tau M is the number of eigenvalues below
// tau. That matrix is indefinite, so CHOLMOD's supernodal LL^T refuses it, and a simplicial
// LDL^T (Eigen's, or CHOLMOD's) works column by column without dense kernels: on meshes of a
// few hundred thousand vertices it costs several times the supernodal factorisation of the same
// pattern, and was the largest single stage of a spectral run. This is the same unpivoted LDL^T
// arranged by supernodes: a left-looking factorisation on the supernodal structure of a CHOLMOD
// analysis (the fill-reducing ordering, the supernodes and their row patterns), with the updates
// from descendant supernodes and inside a supernode done as dense matrix products.
//
// The factor is held as L |D|^1/2 with the signs of D, in the layout of a CHOLMOD supernodal
// L L^T (which it is when D > 0): the row-wise kernels of internal/supernodal_solve.h solve with
// it, the signs applied between their two triangular solves (Eigen's dense products, one
// supernode at a time, were the largest part of a run of block Lanczos in spectrum slices).
//
// Pivots are taken in the order of the analysis, as in any sparse LDL^T without pivoting (the
// simplicial ones included): a zero pivot makes factorize() fail, a tiny one is accepted. The
// callers place tau in a spectral gap, where the matrix is far from singular.
#ifndef LAPMESH_INTERNAL_SUPERNODAL_LDLT_H
#define LAPMESH_INTERNAL_SUPERNODAL_LDLT_H

#ifdef LAPMESH_HAS_CHOLMOD

#include <lapmesh/internal/dense_products.h>
#include <lapmesh/internal/supernodal_solve.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cholmod.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace lapmesh {
namespace internal {

class Supernodal_ldlt
{
public:
  /// The columns of an update block made by one matrix product. As tall as the descendant's
  /// rows from the chunk's first on, such a block is small beside a whole update, whose work
  /// space would stay resident beside the factor, and it skips the rows above the chunk that the
  /// lower triangle does not take.
  static constexpr int update_chunk_columns = 64;

  using Permutation = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;

  /// How the structure of the CHOLMOD factor is held.
  enum class Structure_use {
    copy,  ///< copied: the factor may be freed or changed afterwards
    view   ///< read from the factor, which must outlive this object with its structure unchanged
  };

  /// Takes the structure of a supernodal CHOLMOD factor (analysed only, or factorised) of a
  /// matrix with the pattern of the matrices to be factorised; the factor's values are not read.
  explicit Supernodal_ldlt(const cholmod_factor& symbolic, Structure_use use = Structure_use::copy)
  {
    const int* super = static_cast<const int*>(symbolic.super);
    const int* pi = static_cast<const int*>(symbolic.pi);
    const int* px = static_cast<const int*>(symbolic.px);
    const int* rows = static_cast<const int*>(symbolic.s);
    const int* perm = static_cast<const int*>(symbolic.Perm);
    m_nsuper = symbolic.nsuper;
    m_n = Eigen::Index(symbolic.n);
    if(use == Structure_use::view) {
      m_super = super, m_pi = pi, m_px = px, m_rows = rows, m_matrix_row = perm;
    } else {  // one block: supernodes, row pointers, value pointers, rows, the matrix's rows
      const std::size_t pointers = m_nsuper + 1, row_count = std::size_t(pi[m_nsuper]);
      m_structure_copy.resize(3 * pointers + row_count + std::size_t(m_n));
      int* out = m_structure_copy.data();
      const auto take = [&out](const int* from, std::size_t count) {
        const int* start = out;
        out = std::copy(from, from + count, out);
        return start;
      };
      m_super = take(super, pointers);
      m_pi = take(pi, pointers);
      m_px = take(px, pointers);
      m_rows = take(rows, row_count);
      m_matrix_row = take(perm, std::size_t(m_n));
    }
    m_values_size = std::size_t(m_px[m_nsuper]);
    // CHOLMOD: row i of the factor is row Perm[i] of the matrix; Eigen: P maps old to new.
    m_perm.resize(m_n);
    for(Eigen::Index i = 0; i < m_n; ++i) m_perm.indices()[perm[i]] = int(i);
    m_super_of_column.resize(std::size_t(m_n));
    for(std::size_t s = 0; s < m_nsuper; ++s)
      for(int j = m_super[s]; j < m_super[s + 1]; ++j) m_super_of_column[std::size_t(j)] = int(s);
  }
  // The structure may point into m_structure_copy, whose buffer a move hands over but a copy
  // does not.
  Supernodal_ldlt(const Supernodal_ldlt&) = delete;
  Supernodal_ldlt& operator=(const Supernodal_ldlt&) = delete;
  Supernodal_ldlt(Supernodal_ldlt&&) = default;
  Supernodal_ldlt& operator=(Supernodal_ldlt&&) = default;

  Eigen::Index rows() const { return m_n; }
  /// The fill-reducing permutation P: the factorisation is of P A P^T.
  const Permutation& permutation() const { return m_perm; }

  /// The lower triangle of P A P^T, ready for factorize(): A is symmetric and given by its lower
  /// triangle (the entries above the diagonal are not read).
  Eigen::SparseMatrix<double> permuted_lower(const Eigen::SparseMatrix<double>& A) const
  {
    Eigen::SparseMatrix<double> out(A.rows(), A.cols());
    out.selfadjointView<Eigen::Lower>() = A.selfadjointView<Eigen::Lower>().twistedBy(m_perm);
    return out;
  }

  /// Factorises B - shift diag(d) as L D L^T, B = permuted_lower(A) and d indexed as A (not read,
  /// and may be empty, when the shift is zero). False on a zero pivot (the matrix is singular to
  /// working precision at that pivot).
  bool factorize(const Eigen::SparseMatrix<double>& permuted_lower_triangle, const Eigen::VectorXd& d,
                 double shift)
  {
    m_own_values.resize(m_values_size);
    return factorize_in(m_own_values.data(), permuted_lower_triangle, d, shift);
  }

  /// The number of values of the factor: the size of a CHOLMOD supernodal factor of the same
  /// structure.
  std::size_t values_size() const { return m_values_size; }

  /// factorize(), with the factor written to `storage` (values_size() doubles, overwritten): the
  /// memory of a CHOLMOD factor of the same structure that is no longer needed, which spares the
  /// fresh pages of a second factor on a large mesh. `storage` must outlive the use of the
  /// factorisation.
  bool factorize_in(double* storage, const Eigen::SparseMatrix<double>& permuted_lower_triangle,
                    const Eigen::VectorXd& d, double shift)
  {
    const std::size_t nsuper = m_nsuper;
    m_values = storage;
    std::fill(m_values, m_values + m_values_size, 0.0);
    m_pivots.setZero(m_n);
    m_signs.resize(m_n);
    m_position.assign(std::size_t(m_n), 0);
    m_head.assign(nsuper, -1);
    m_next.assign(nsuper, -1);
    m_progress.assign(nsuper, 0);
    for(std::size_t s = 0; s < nsuper; ++s) {
      const int k1 = m_super[s], k2 = m_super[s + 1], ncol = k2 - k1;
      const int nrow = m_pi[s + 1] - m_pi[s];
      const int* srows = m_rows + m_pi[s];
      double* X = m_values + m_px[s];
      for(int i = 0; i < nrow; ++i) m_position[std::size_t(srows[i])] = i;
      // The matrix's columns k1..k2-1, shifted.
      for(int j = k1; j < k2; ++j) {
        double* column = X + std::size_t(j - k1) * std::size_t(nrow);
        for(Eigen::SparseMatrix<double>::InnerIterator it(permuted_lower_triangle, j); it; ++it)
          if(it.row() >= j) column[m_position[std::size_t(it.row())]] += it.value();
        if(shift != 0) column[j - k1] -= shift * d[m_matrix_row[std::size_t(j)]];
      }
      // The updates of every descendant supernode with rows in [k1, k2).
      for(int desc = m_head[s]; desc >= 0;) {
        const int following = m_next[std::size_t(desc)];
        apply_update(std::size_t(desc), s, X, nrow);
        queue(std::size_t(desc));
        desc = following;
      }
      if(!factor_supernode(X, nrow, ncol, k1)) return false;
      m_progress[s] = ncol;
      queue(s);
    }
    scale_by_root_pivots();
    return true;
  }

  /// x = (B - shift diag(d))^-1 b in A's numbering, with the last successful factorisation.
  template <typename Rhs>
  Eigen::Matrix<double, Eigen::Dynamic, Rhs::ColsAtCompileTime> solve(const Rhs& b) const
  {
    Eigen::MatrixXd x;
    scaled_solve_by_rows([this](Eigen::Index i) { return Eigen::Index(m_matrix_row[i]); }, nullptr, b, x);
    return x;
  }

  /// Y = D K^-1 D X, K = B - shift diag(d), D = diag(scale) (nullptr: the identity): row i of the
  /// factor's system is row row_of(i) of X, Y and scale.
  template <typename RowOf>
  void scaled_solve_by_rows(const RowOf& row_of, const double* scale, const Eigen::Ref<const Eigen::MatrixXd>& X,
                            Eigen::MatrixXd& Y) const
  {
    supernodal_scaled_solve(factor_view(), row_of, scale, X, Y, m_solve_rows);
  }

  /// The last factorisation's supernodes, values (L |D|^1/2) and signs, for the supernodal kernels.
  Supernodal_factor_view factor_view() const
  {
    Supernodal_factor_view view;
    view.super = m_super;
    view.pi = m_pi;
    view.px = m_px;
    view.rows = m_rows;
    view.nsuper = m_nsuper;
    view.values = m_values;
    view.signs = m_signs.data();
    return view;
  }

  /// The row of the matrix at each row of the factor (the fill-reducing ordering).
  const int* matrix_rows() const { return m_matrix_row; }

  /// Whether every pivot of the last factorisation is positive: its values are then the
  /// Cholesky factor L D^1/2 (the layout of a CHOLMOD supernodal L L^T).
  bool positive_definite() const { return (m_pivots.array() > 0).all(); }

  /// The diagonal D of the last factorisation, in the permuted numbering.
  const Eigen::VectorXd& pivots() const { return m_pivots; }
  /// The number of negative pivots: by Sylvester's law, the number of negative eigenvalues.
  Eigen::Index negative_pivots() const { return (m_pivots.array() < 0).count(); }

private:
  using Block = Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>>;

  /// L to L |D|^1/2, D's signs set aside: the form the solves take. After the whole
  /// factorisation rather than supernode by supernode, so that the updates, and with them the
  /// pivots and the Cholesky factor of a positive definite matrix, are those of L D L^T.
  void scale_by_root_pivots()
  {
    for(std::size_t s = 0; s < m_nsuper; ++s) {
      const int k1 = m_super[s], ncol = m_super[s + 1] - k1, nrow = m_pi[s + 1] - m_pi[s];
      Block X(m_values + m_px[s], nrow, ncol, Eigen::OuterStride<>(nrow));
      for(int c = 0; c < ncol; ++c) {
        const double pivot = m_pivots[k1 + c], root = std::sqrt(std::abs(pivot));
        m_signs[k1 + c] = pivot > 0 ? 1.0 : -1.0;
        X(c, c) = root;  // the unit diagonal of L, which held the pivot
        X.col(c).tail(nrow - c - 1) *= root;
      }
    }
  }

  /// Queues supernode d on the supernode that holds its first row not yet used, if any.
  void queue(std::size_t d)
  {
    const int row_count = m_pi[d + 1] - m_pi[d];
    if(m_progress[d] >= row_count) return;
    const int row = m_rows[std::size_t(m_pi[d] + m_progress[d])];
    const std::size_t target = std::size_t(m_super_of_column[std::size_t(row)]);
    m_next[d] = m_head[target];
    m_head[target] = int(d);
  }

  /// A rows x cols block (column-major) in `storage`, which is enlarged when too small.
  static Block work_block(std::vector<double>& storage, int rows, int cols)
  {
    const std::size_t size = std::size_t(rows) * std::size_t(cols);
    if(storage.size() < size) {
      std::vector<double>().swap(storage);  // freed first: its values need not be kept
      storage.resize(size);
    }
    return Block(storage.data(), rows, cols, Eigen::OuterStride<>(rows));
  }

  /// X_s -= L_d(rows >= k1) D_d L_d(rows in [k1, k2))^T, scattered into supernode s.
  void apply_update(std::size_t d, std::size_t s, double* X, int nrow)
  {
    const int dk1 = m_super[d], dcol = m_super[d + 1] - dk1;
    const int drow = m_pi[d + 1] - m_pi[d];
    const int* drows = m_rows + m_pi[d];
    const int k1 = m_super[s], k2 = m_super[s + 1];
    const int start = m_progress[d];
    int stop = start;
    while(stop < drow && drows[stop] < k2) ++stop;
    const int inside = stop - start, below = drow - start;
    const Block Ld(m_values + m_px[d], drow, dcol, Eigen::OuterStride<>(drow));
    for(int j0 = 0; j0 < inside; j0 += update_chunk_columns) {
      const int width = std::min(inside - j0, update_chunk_columns), rows = below - j0;
      Block scaled = work_block(m_scaled, dcol, width);  // D_d L_d(chunk rows)^T
      for(int j = 0; j < width; ++j)
        for(int c = 0; c < dcol; ++c) scaled(c, j) = m_pivots[dk1 + c] * Ld(start + j0 + j, c);
      Block update = work_block(m_update, rows, width);
      tall_gemm(false, 1.0, Ld.middleRows(start + j0, rows), scaled, 0.0, update);
      const int* update_rows = drows + start + j0;
      for(int j = 0; j < width; ++j) {
        double* column = X + std::size_t(update_rows[j] - k1) * std::size_t(nrow);
        for(int i = j; i < rows; ++i) column[m_position[std::size_t(update_rows[i])]] -= update(i, j);
      }
    }
    m_progress[d] = stop;
  }

  /// Dense L D L^T of a supernode's columns (nrow x ncol, the leading ncol x ncol block on the
  /// diagonal), right-looking in panels: a scalar kernel inside a panel, a matrix product for the
  /// columns to its right.
  bool factor_supernode(double* data, int nrow, int ncol, int k1)
  {
    Block X(data, nrow, ncol, Eigen::OuterStride<>(nrow));
    constexpr int panel = 32;
    for(int p0 = 0; p0 < ncol; p0 += panel) {
      const int p1 = std::min(ncol, p0 + panel);
      for(int j = p0; j < p1; ++j) {
        const double pivot = X(j, j);
        if(pivot == 0.0 || !std::isfinite(pivot)) return false;
        m_pivots[k1 + j] = pivot;
        const double inverse = 1.0 / pivot;
        for(int c = j + 1; c < p1; ++c) {
          const double factor = X(c, j);  // L(c, j) d_j, before the division below
          if(factor == 0.0) continue;
          for(int i = c; i < nrow; ++i) X(i, c) -= X(i, j) * (factor * inverse);
        }
        for(int i = j + 1; i < nrow; ++i) X(i, j) *= inverse;
      }
      if(p1 == ncol) break;
      // Columns p1.. ncol-1: X(i, c) -= sum over the panel of L(i, j) d_j L(c, j), i >= p1.
      const int w = p1 - p0, right = ncol - p1, below = nrow - p1;
      Block scaled = work_block(m_scaled, w, right);
      for(int c = 0; c < right; ++c)
        for(int j = 0; j < w; ++j) scaled(j, c) = m_pivots[k1 + p0 + j] * X(p1 + c, p0 + j);
      tall_gemm(false, -1.0, X.block(p1, p0, below, w), scaled, 1.0, X.block(p1, p1, below, right));
    }
    for(int c = 0; c < ncol; ++c) X.col(c).head(c).setZero();  // the unused upper triangle
    return true;
  }

  Eigen::Index m_n = 0;
  std::size_t m_nsuper = 0;
  // CHOLMOD's supernodal structure, in the factor or in m_structure_copy.
  const int* m_super = nullptr;
  const int* m_pi = nullptr;
  const int* m_px = nullptr;
  const int* m_rows = nullptr;
  const int* m_matrix_row = nullptr;  // the matrix's row (and column) at each row of the factor
  std::vector<int> m_structure_copy;
  std::vector<int> m_super_of_column;
  std::size_t m_values_size = 0;
  std::vector<double> m_own_values;
  double* m_values = nullptr;  // the last factorisation's values
  Eigen::VectorXd m_pivots;
  Eigen::VectorXd m_signs;  // of the pivots, +1 or -1
  Permutation m_perm;
  // Work space of factorize().
  std::vector<int> m_position, m_head, m_next, m_progress;
  // Work blocks of the updates: they only grow, so that the blocks of varying sizes, one per
  // update, are not allocated and freed thousands of times, which fragments the heap and leaves
  // a large factorisation's process tens of MiB above its live memory.
  std::vector<double> m_scaled, m_update;
  mutable std::vector<double> m_solve_rows;  // the solves' right-hand sides, row by row
};

} // namespace internal
} // namespace lapmesh

#endif // LAPMESH_HAS_CHOLMOD
#endif
