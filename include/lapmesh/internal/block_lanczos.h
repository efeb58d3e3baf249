// lapmesh — thick-restart block Lanczos for the largest eigenpairs of a symmetric operator
// that is applied to blocks of vectors (Y = A X, X of size n x b).
//
// Why a block method. In shift-invert mode every Krylov step is a pair of sparse triangular
// solves, which are memory bound: a supernodal factor read once serves b right-hand sides in a
// fraction of the time of b single solves (doc/benchmarks-history.md has the figures). The
// re-orthogonalisation against the basis also becomes matrix-matrix products, where
// single-vector Lanczos (Spectra) spends much of its time in repeated matrix-vector products
// over the whole basis. The price is more operator applications than single-vector Lanczos:
// the block method wins as soon as a block solve costs less than half of b single ones.
//
// Method. Block Lanczos with full re-orthogonalisation: the new block is orthogonalised
// against the last two blocks (the three-term recurrence), then once against the whole basis
// (which removes the round-off drift of the recurrence), and made orthonormal by CholeskyQR2
// (Householder QR plus random refill when the block is rank deficient, i.e. an invariant
// subspace was found). After the first product with the last two blocks, each of these steps
// shares its pass over the block with the product that follows it (below). The projected matrix T = V^T A V is kept in full; after every block
// step, Rayleigh-Ritz on T gives Ritz pairs whose residual norms come for free from the
// coupling to the unprocessed block. When the basis is full, it restarts thickly: the best Ritz
// vectors plus the unprocessed block form the new basis (no information from converged
// directions is lost, and T stays exact).
//
// Rayleigh-Ritz costs O(m^3) for a basis of m vectors, as much as a block solve on a mesh of tens
// of thousands of vertices, and most steps cannot end the run. It is done when the basis is full
// (the restart needs the Ritz vectors), at every step while it is cheap beside the step's
// re-orthogonalisation, and otherwise at checkpoints: the rate at which the previous checks saw
// Ritz pairs converge predicts the step that ends the run, and the next check comes halfway
// there, so the checks close in on the end (every step once it is a step away).
#ifndef LAPMESH_INTERNAL_BLOCK_LANCZOS_H
#define LAPMESH_INTERNAL_BLOCK_LANCZOS_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/dense_products.h>
#include <lapmesh/internal/memory.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace lapmesh {
namespace internal {

/// C = V^T W for a tall V and a thin W: lapmesh's kernels up to thin_block_max_columns columns,
/// the BLAS (or Eigen) in row panels beyond.
inline void panel_product_tn(const Eigen::Ref<const Eigen::MatrixXd>& V, const Eigen::Ref<const Eigen::MatrixXd>& W,
                             Eigen::MatrixXd& C)
{
#ifdef LAPMESH_THIN_PRODUCTS
  if(W.cols() >= 1 && W.cols() <= thin_block_max_columns && V.cols() >= 1) {
    thin_product_tn(V, W, C);
    return;
  }
#endif
  C.resize(V.cols(), W.cols());
  tall_gemm(true, 1.0, V, W, 0.0, C);
}

/// W -= V C by the BLAS (or Eigen) in row panels. The block steps subtract blocks of up to
/// thin_block_max_columns in their fused passes (below); this is their fallback.
inline void panel_subtract_product(const Eigen::Ref<const Eigen::MatrixXd>& V, const Eigen::MatrixXd& C,
                                   Eigen::Ref<Eigen::MatrixXd> W)
{
  tall_gemm(false, -1.0, V, C, 1.0, W);
}

#ifdef LAPMESH_THIN_PRODUCTS
/// C (m x b) as m rows of `lanes` values, the lanes past b zero: the layout of the fused kernels.
inline const double* in_lanes(const Eigen::MatrixXd& C, Eigen::Index lanes, std::vector<double>& out)
{
  out.assign(std::size_t(C.rows() * lanes), 0.0);
  for(Eigen::Index j = 0; j < C.rows(); ++j)
    for(Eigen::Index c = 0; c < C.cols(); ++c) out[std::size_t(j * lanes + c)] = C(j, c);
  return out.data();
}

/// A fused pass that reads the block W and writes it to `out` (which may be W), with nothing else
/// to do yet; `lanes` is the kernel's width for W.
inline thin_kernels::Fused_pass fused_pass(const Eigen::Ref<const Eigen::MatrixXd>& W, double* out, Eigen::Index ldo,
                                           Eigen::Index& lanes)
{
  thin_kernels::Fused_pass p{};
  p.n = W.rows();
  p.W = {W.data(), W.outerStride()};
  p.b = W.cols();
  p.out = out;
  p.ldo = ldo;
  lanes = W.cols() <= 4 ? 4 : 8;
  return p;
}
#endif

// The passes of a block step after the operator, fused so that the block is read from memory once
// per pass over the basis rather than once per product: a subtraction and the product or Gram
// matrix that follows it, and each multiplication of CholeskyQR2 with the next Gram matrix, share
// a pass over rows that sit in the first-level cache. Blocks wider than thin_block_max_columns
// (and compilers without the kernels) take the same steps one product at a time.

/// W -= Vl Cl, then Cg = Va^T W (Vl is usually a part of Va).
inline void subtract_then_product_tn(const Eigen::Ref<const Eigen::MatrixXd>& Vl, const Eigen::MatrixXd& Cl,
                                     Eigen::Ref<Eigen::MatrixXd> W, const Eigen::Ref<const Eigen::MatrixXd>& Va,
                                     Eigen::MatrixXd& Cg)
{
#ifdef LAPMESH_THIN_PRODUCTS
  if(W.cols() >= 1 && W.cols() <= thin_block_max_columns && Vl.cols() >= 1 && Va.cols() >= 1) {
    Eigen::Index lanes;
    std::vector<double> local;
    Cg.resize(Va.cols(), W.cols());
    thin_kernels::Fused_pass p = fused_pass(W, W.data(), W.outerStride(), lanes);
    p.Vl = {Vl.data(), Vl.outerStride()};
    p.ml = Vl.cols();
    p.local_coefficients = in_lanes(Cl, lanes, local);
    p.Va = {Va.data(), Va.outerStride()};
    p.ma = Va.cols();
    p.product = Cg.data();
    p.ldp = Cg.outerStride();
    thin_kernels::kernels().fused(p);
    return;
  }
#endif
  panel_subtract_product(Vl, Cl, W);
  panel_product_tn(Va, W, Cg);
}

/// W -= Va Cg, then G = W^T W.
inline void subtract_then_gram(const Eigen::Ref<const Eigen::MatrixXd>& Va, const Eigen::MatrixXd& Cg,
                               Eigen::Ref<Eigen::MatrixXd> W, Eigen::MatrixXd& G)
{
#ifdef LAPMESH_THIN_PRODUCTS
  if(W.cols() >= 1 && W.cols() <= thin_block_max_columns && Va.cols() >= 1) {
    Eigen::Index lanes;
    std::vector<double> all;
    G.resize(W.cols(), W.cols());
    thin_kernels::Fused_pass p = fused_pass(W, W.data(), W.outerStride(), lanes);
    p.Va = {Va.data(), Va.outerStride()};
    p.ma = Va.cols();
    p.all_coefficients = in_lanes(Cg, lanes, all);
    p.gram = G.data();
    thin_kernels::kernels().fused(p);
    return;
  }
#endif
  panel_subtract_product(Va, Cg, W);
  panel_product_tn(W, W, G);
}

/// Out = W F for a small square F (Out may be W), then G = Out^T Out unless G is null.
inline void multiply_then_gram(const Eigen::Ref<const Eigen::MatrixXd>& W, const Eigen::MatrixXd& F,
                               Eigen::Ref<Eigen::MatrixXd> Out, Eigen::MatrixXd* G)
{
#ifdef LAPMESH_THIN_PRODUCTS
  if(W.cols() >= 1 && W.cols() <= thin_block_max_columns) {
    Eigen::Index lanes;
    std::vector<double> factor;
    if(G) G->resize(W.cols(), W.cols());
    thin_kernels::Fused_pass p = fused_pass(W, Out.data(), Out.outerStride(), lanes);
    Eigen::MatrixXd square = Eigen::MatrixXd::Zero(lanes, lanes);  // the kernel reads lanes x lanes
    square.topLeftCorner(F.rows(), F.cols()) = F;
    p.factor = in_lanes(square, lanes, factor);
    p.gram = G ? G->data() : nullptr;
    thin_kernels::kernels().fused(p);
    return;
  }
#endif
  const Eigen::MatrixXd product = W * F;
  Out = product;
  if(G) panel_product_tn(Out, Out, *G);
}

/// V[:, 0:Z.cols()] = V[:, 0:used] Z, in row panels that stay in cache: a thick restart and
/// the final Ritz vectors need no second tall matrix (on a large mesh its fresh pages cost more
/// than the product).
inline void rotate_in_place(Eigen::MatrixXd& V, Eigen::Index used, const Eigen::Ref<const Eigen::MatrixXd>& Z,
                            Eigen::MatrixXd& panel)
{
  const Eigen::Index rows = V.rows(), height = 1024;
  panel.resize(std::min(height, rows), Z.cols());
  for(Eigen::Index r = 0; r < rows; r += height) {
    const Eigen::Index h = std::min(height, rows - r);
    tall_gemm(false, 1.0, V.block(r, 0, h, used), Z, 0.0, panel.topRows(h));
    V.block(r, 0, h, Z.cols()) = panel.topRows(h);
  }
}

struct Block_lanczos_options
{
  Eigen::Index block_size = 8;   ///< vectors per block (operator applications per step)
  Eigen::Index max_basis = 0;    ///< basis size before a restart; 0: max(2 nev, nev + 6 b)
  double tolerance = 1e-10;      ///< converged when ||A y - theta y|| <= tolerance * |theta|
  int max_restarts = 1000;
  std::uint64_t seed = 0x5eed;   ///< of the random starting block (reproducible runs)
  /// When the operator works on a permutation of the caller's rows: row i of its vectors is row
  /// row_order[i] of the caller's (n entries). Random vectors are drawn in the caller's order,
  /// so that a run gives the same pairs in either order.
  const int* row_order = nullptr;
  bool by_magnitude = false;     ///< wanted: largest |theta| (interior shift-invert) instead of largest theta
  /// Removes from a vector the part that the operator maps to zero (if it is known): the random
  /// start and refill vectors then carry none of it. Otherwise, once the Krylov space of the rest
  /// is exhausted (one value repeated in every part of a mesh of identical parts), those parts
  /// come back as Ritz pairs of theta = 0 and zero residual, converged but not wanted.
  std::function<void(Eigen::Ref<Eigen::VectorXd>)> remove_null_space;
  /// Asked at every restart with the wanted Ritz values (in the order of `values` below) and the
  /// number of restarts so far: true ends the run unconverged (a caller that sees the run will
  /// not converge in reasonable time and knows a better operator).
  std::function<bool(const Eigen::VectorXd& theta, int restart)> give_up;
  /// > 0: the run ends unconverged (`stalled` in the result) after this many restarts in a row
  /// that converged no further wanted pair (a value repeated more often than the Krylov space of
  /// a block holds it: a larger block finds the copies).
  int stall_restarts = 0;
};

struct Block_lanczos_result
{
  Eigen::VectorXd values;    ///< the nev wanted eigenvalues, largest (or largest |theta|) first
  Eigen::MatrixXd vectors;   ///< orthonormal eigenvectors, one per column
  long long operations = 0;  ///< operator applications (vectors, not blocks)
  int restarts = 0;
  int rayleigh_ritz = 0;     ///< projected eigenproblems solved (convergence checks)
  bool converged = true;     ///< false: given up (options' give_up or stall_restarts); `values`
                             ///< are then the last Ritz values and `vectors` is empty
  bool stalled = false;      ///< given up by the options' stall_restarts
  Eigen::Index converged_pairs = 0;  ///< wanted pairs converged when the run ended
};

/// The nev largest eigenpairs of the symmetric operator `apply(X, Y)`: Y = A X, X a block of
/// columns of the basis (an `apply` that takes it as `Eigen::Ref<const Eigen::MatrixXd>` reads
/// it in place; one that takes `const Eigen::MatrixXd&` gets a copy).
/// `on_step(operations)` is called after every block step (progress reports).
template <typename Apply>
Block_lanczos_result block_lanczos_largest(Eigen::Index n, Eigen::Index nev, Apply&& apply,
                                           const Block_lanczos_options& opt,
                                           const std::function<void(long long)>& on_step = {})
{
  using Eigen::Index;
  using Eigen::MatrixXd;
  const Index b = std::max<Index>(1, std::min(opt.block_size, n / 4));
  Index m_max = opt.max_basis > 0 ? opt.max_basis : std::max(2 * nev, nev + 6 * b);
  m_max = std::min<Index>(((m_max + b - 1) / b) * b, ((n - b) / b) * b);  // leave room for one more block
  if(nev < 1 || nev + b > m_max)
    throw Numerical_error("block Lanczos: " + std::to_string(nev) + " eigenpairs do not fit a basis of " +
                          std::to_string(m_max) + " vectors (n = " + std::to_string(n) + ")");

  MatrixXd V(n, m_max + b);                             // basis; columns [0, filled) are valid
  advise_huge_pages(V);  // written a block at a time: one fault per 2 MiB instead of per 4 KiB
  MatrixXd T = MatrixXd::Zero(m_max + b, m_max + b);  // V^T A V on the processed columns
  std::mt19937_64 rng(opt.seed);
  Eigen::VectorXd drawn;
  auto random_unit = [&](Eigen::Ref<Eigen::VectorXd> x) {
    // Uniform in [-1, 1) from the 53 high bits: the same start on every platform.
    if(opt.row_order) {
      drawn.resize(n);
      for(Index i = 0; i < n; ++i) drawn[i] = double(rng() >> 11) * 0x1.0p-52 - 1.0;
      for(Index i = 0; i < n; ++i) x[i] = drawn[opt.row_order[i]];
    } else {
      for(Index i = 0; i < n; ++i) x[i] = double(rng() >> 11) * 0x1.0p-52 - 1.0;
    }
    if(opt.remove_null_space) opt.remove_null_space(x);
  };

  // Orthonormalises W (n x b, already orthogonal to V[:, 0:filled]) into Q with W = Q R. `scale`
  // is the size of W before it was made orthogonal to V: rank is judged against it, because a
  // block that the projections reduced to round-off (the Krylov space became invariant) is noise
  // that is not orthogonal to V, and normalising it would corrupt the basis.
  //
  // CholeskyQR2 with W's Gram matrix G given (the pass that made W orthogonal to V computed it):
  // each of its two passes multiplies W by the inverse of a Cholesky factor, the first one also
  // forms the next Gram matrix and the second writes the result to `out`.
  MatrixXd R1, R2, inverse;
  auto orthonormalise = [&](MatrixXd& W, MatrixXd& G, MatrixXd& R, Index filled, double scale,
                            Eigen::Ref<MatrixXd> out) {
    scale = std::max(scale, 1e-300);
    Eigen::LLT<MatrixXd> llt1(G);
    if(llt1.info() == Eigen::Success) {
      R1 = llt1.matrixU();
      const double dmin = R1.diagonal().cwiseAbs().minCoeff();
      if(dmin > 1e-7 * scale) {  // condition number < 1e7: CholeskyQR2 is accurate
        inverse = R1.triangularView<Eigen::Upper>().solve(MatrixXd::Identity(W.cols(), W.cols()));
        multiply_then_gram(W, inverse, W, &G);
        Eigen::LLT<MatrixXd> llt2(G);
        if(llt2.info() == Eigen::Success) {
          R2 = llt2.matrixU();
          inverse = R2.triangularView<Eigen::Upper>().solve(MatrixXd::Identity(W.cols(), W.cols()));
          multiply_then_gram(W, inverse, out, nullptr);
          R = R2 * R1;
          return;
        }
        W = W * R1;  // undo the first pass: the fallback below factors W itself
      }
    }
    // Rank deficient (an invariant subspace was found) or ill-conditioned: Householder QR, and
    // random directions orthogonal to everything for the columns W does not span.
    Eigen::HouseholderQR<MatrixXd> qr(W);
    R = qr.matrixQR().topRows(W.cols()).template triangularView<Eigen::Upper>();
    MatrixXd Q = qr.householderQ() * MatrixXd::Identity(n, W.cols());
    for(Index j = 0; j < W.cols(); ++j) {
      if(std::abs(R(j, j)) > 1e-10 * scale) continue;
      R.row(j).setZero();
      Eigen::VectorXd x(n);
      random_unit(x);
      for(int pass = 0; pass < 2; ++pass) {
        x -= V.leftCols(filled) * (V.leftCols(filled).transpose() * x);
        for(Index i = 0; i < W.cols(); ++i)
          if(i != j) x -= Q.col(i) * Q.col(i).dot(x);
      }
      Q.col(j) = x.normalized();
    }
    // Columns of Q that come from a small R_jj are W's round-off divided by R_jj: not orthogonal
    // to V. Project them out and orthonormalise again; the dropped components are O(eps ||W||).
    for(int pass = 0; pass < 2; ++pass) {
      // The round-off of the columns that W does not span also carries the null space, and the
      // refills took some of it when they were made orthogonal to those columns.
      if(opt.remove_null_space)
        for(Index j = 0; j < W.cols(); ++j) opt.remove_null_space(Q.col(j));
      Q -= V.leftCols(filled) * (V.leftCols(filled).transpose() * Q);
      Eigen::HouseholderQR<MatrixXd> again(Q);
      const MatrixXd R_again = again.matrixQR().topRows(W.cols()).template triangularView<Eigen::Upper>();
      MatrixXd Q_again = again.householderQ() * MatrixXd::Identity(n, W.cols());
      // Keep the signs: Q_again R_again = Q with diag(R_again) ~ +-1.
      for(Index j = 0; j < W.cols(); ++j)
        if(R_again(j, j) < 0) Q_again.col(j) = -Q_again.col(j);
      Q = std::move(Q_again);
      MatrixXd S = R_again;
      for(Index j = 0; j < W.cols(); ++j)
        if(R_again(j, j) < 0) S.row(j) = -S.row(j);
      R = S * R;
    }
    out = Q;
  };

  Block_lanczos_result out;
  {
    MatrixXd W(n, b), R, G;
    for(Index j = 0; j < b; ++j) random_unit(W.col(j));
    panel_product_tn(W, W, G);
    orthonormalise(W, G, R, 0, W.colwise().norm().maxCoeff(), V.leftCols(b));
  }
  Index processed = 0, filled = b, restart_start = 0;
  MatrixXd W, C, R, Cg, G, kept, next;
  // The convergence checks' schedule (see the top of the file), in operator applications.
  long long next_check = 0, last_check = 0;
  Index last_settled = -1;
  Index most_settled = -1;  // the most wanted pairs converged at a check, and the restart it came in
  int progress_restart = 0;
  for(int restart = 0;; ++restart) {
    while(filled <= m_max) {
      const Index cur = processed;
      W.resize(n, b);
      apply(V.middleCols(cur, b), W);
      out.operations += b;
      const double applied_scale = W.colwise().norm().maxCoeff();
      // Three-term recurrence against the last two blocks (the large components), then one pass
      // against the whole basis; T gets the sum of both coefficient sets. The first block after
      // a restart couples to every kept Ritz vector: it gets two full passes instead.
      const Index lo = cur == restart_start ? 0 : cur - b;
      const Index local = filled - lo;
      panel_product_tn(V.middleCols(lo, local), W, C);
      subtract_then_product_tn(V.middleCols(lo, local), C, W, V.leftCols(filled), Cg);
      subtract_then_gram(V.leftCols(filled), Cg, W, G);
      Cg.middleRows(lo, local) += C;
      T.block(0, cur, filled, b) = Cg;
      T.block(cur, 0, b, filled) = Cg.transpose();
      T.block(cur, cur, b, b) = 0.5 * (Cg.middleRows(cur, b) + Cg.middleRows(cur, b).transpose());
      orthonormalise(W, G, R, filled, applied_scale, V.middleCols(filled, b));
      T.block(filled, cur, b, b) = R;
      T.block(cur, filled, b, b) = R.transpose();
      processed += b;
      filled += b;
      if(on_step) on_step(out.operations);
      if(processed < nev) continue;
      // A projected problem whose solution (about 9 p^3 flops) costs less than a tenth of the
      // step's re-orthogonalisation (4 n p b flops) is solved at every step.
      const bool basis_full = filled > m_max;
      const bool cheap_check = 9.0 * double(processed) * double(processed) <= 0.4 * double(n) * double(b);
      if(!basis_full && !cheap_check && out.operations < next_check) continue;

      // Rayleigh-Ritz on the processed columns; residual of the Ritz pair (theta, V z):
      // A V z - theta V z = V_next R_last z_last, so its norm is ||R_last z_last||.
      ++out.rayleigh_ritz;
      Eigen::SelfAdjointEigenSolver<MatrixXd> es(T.topLeftCorner(processed, processed));
      if(es.info() != Eigen::Success) throw Numerical_error("block Lanczos: the projected eigenproblem failed");
      Eigen::VectorXd theta = es.eigenvalues().reverse();
      MatrixXd Z = es.eigenvectors().rowwise().reverse();
      if(opt.by_magnitude) {
        std::vector<Index> order(std::size_t(theta.size()));
        for(Index i = 0; i < theta.size(); ++i) order[std::size_t(i)] = i;
        std::stable_sort(order.begin(), order.end(),
                         [&](Index a, Index c) { return std::abs(theta[a]) > std::abs(theta[c]); });
        const Eigen::VectorXd t0 = theta;
        const MatrixXd z0 = Z;
        for(Index i = 0; i < theta.size(); ++i) {
          theta[i] = t0[order[std::size_t(i)]];
          Z.col(i) = z0.col(order[std::size_t(i)]);
        }
      }
      const MatrixXd R_last = T.block(processed, processed - b, b, b);
      auto has_converged = [&](Index j) {
        return (R_last * Z.block(processed - b, j, b, 1)).norm() <=
               opt.tolerance * std::max(std::abs(theta[j]), 1e-300 + 1e-14 * std::abs(theta[0]));
      };
      Index converged = 0;
      while(converged < nev && has_converged(converged)) ++converged;
      if(converged >= nev) {
        // The Ritz vectors overwrite the basis, which then shrinks in place: no second tall
        // matrix beside the basis at the peak of the run.
        out.values = theta.head(nev);
        rotate_in_place(V, processed, Z.leftCols(nev), kept);
        V.conservativeResize(Eigen::NoChange, nev);
        out.vectors = std::move(V);
        out.restarts = restart;
        return out;
      }
      // The next check: halfway to the end that the convergence rate since the last check
      // predicts; at the restart when no progress was seen (the rate is unknown).
      Index settled = converged;  // wanted pairs converged, in any position
      for(Index j = converged + 1; j < nev; ++j) settled += has_converged(j) ? 1 : 0;
      if(last_settled < 0)
        next_check = out.operations + b;  // the next step measures a rate
      else if(settled > last_settled)
        next_check = out.operations + (long long)(0.5 * double(nev - settled) * double(out.operations - last_check) /
                                                  double(settled - last_settled));
      else
        next_check = std::numeric_limits<long long>::max();
      last_settled = settled;
      last_check = out.operations;
      if(settled > most_settled) {
        most_settled = settled;
        progress_restart = restart;
      }
      if(basis_full) {  // thick restart
        if(opt.stall_restarts > 0 && restart - progress_restart >= opt.stall_restarts) {
          out.values = theta.head(nev);
          out.restarts = restart;
          out.converged = false;
          out.stalled = true;
          out.converged_pairs = converged;
          return out;
        }
        if(opt.give_up && opt.give_up(theta.head(nev), restart)) {
          out.values = theta.head(nev);
          out.restarts = restart;
          out.converged = false;
          return out;
        }
        if(restart >= opt.max_restarts)
          throw Numerical_error("block Lanczos: " + std::to_string(converged) + " of " + std::to_string(nev) +
                                " eigenpairs converged after " + std::to_string(restart) +
                                " restarts (tolerance " + message_number(opt.tolerance) + ", blocks of " +
                                std::to_string(opt.block_size) + ")");
        // Keep the wanted Ritz vectors and a third of the rest: the rest speeds up convergence of
        // the last wanted ones; the new room lets the Krylov space grow again.
        const Index keep = std::min(processed - b, std::max(nev, nev + (processed - nev) / 3));
        next = V.middleCols(processed, b);
        rotate_in_place(V, processed, Z.leftCols(keep), kept);
        V.middleCols(keep, b) = next;
        T.setZero();
        T.topLeftCorner(keep, keep).diagonal() = theta.head(keep);
        const MatrixXd coupling = R_last * Z.block(processed - b, 0, b, keep);
        T.block(keep, 0, b, keep) = coupling;
        T.block(0, keep, keep, b) = coupling.transpose();
        processed = keep;
        filled = keep + b;
        restart_start = keep;
        break;
      }
    }
  }
}

} // namespace internal
} // namespace lapmesh

#endif
