// lapmesh — the two triangular solves with a supernodal factor L (L L^T X = B, or L S L^T X = B
// for an L D L^T held as L |D|^1/2 and the signs S of D), on a block of right-hand sides stored
// row by row (the values of one row of X side by side).
//
// Why not CHOLMOD's own solves. The factors of surface meshes have many small supernodes (a few
// columns each), and a block Krylov method solves with a handful of right-hand sides. CHOLMOD
// calls the BLAS (dtrsm, dgemm) on each supernode, where the call and packing overhead of such
// small products outweighs the arithmetic. Here each column of L is read once, contiguously, and
// applied to the few values of the rows it touches; the rows are stored side by side so that one
// cache line holds all the right-hand sides of a row. Up to eight columns of a supernode go
// together below its diagonal block, so that a row of X is loaded and stored once for all of them.
// On x86-64 the kernels are compiled for the baseline, for AVX2 + FMA and (blocks of 8) for AVX-512,
// chosen at run time (the generic build otherwise uses two-wide vectors only).
#ifndef LAPMESH_INTERNAL_SUPERNODAL_SOLVE_H
#define LAPMESH_INTERNAL_SUPERNODAL_SOLVE_H

#include <lapmesh/internal/cpu_features.h>
#include <lapmesh/internal/vector_registers.h>

#include <Eigen/Core>

#include <algorithm>
#include <cassert>
#include <cstddef>
#include <vector>

// The baseline build of the kernels passes 32-byte vectors between inlined helpers, for which
// GCC and Clang note that the ABI differs with AVX: nothing crosses a call boundary.
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

#ifdef LAPMESH_X86_KERNEL_BUILDS
#define LAPMESH_SUPERNODAL_SOLVE_AVX2 1
#endif

namespace lapmesh {
namespace internal {

/// The structure and values of a supernodal factor in CHOLMOD's layout: supernode s holds the
/// columns super[s] .. super[s+1]-1, its row indices are rows[pi[s] .. pi[s+1]) (the first ones
/// are its own columns), its values the column-major block at values + px[s] (leading dimension:
/// its number of rows). `signs` (one per column, +1 or -1) makes it the factor L |D|^1/2 of an
/// indefinite L D L^T = L |D|^1/2 S |D|^1/2 L^T, S = diag(signs); nullptr: a Cholesky factor.
struct Supernodal_factor_view
{
  const int* super = nullptr;
  const int* pi = nullptr;
  const int* px = nullptr;
  const int* rows = nullptr;
  std::size_t nsuper = 0;
  const double* values = nullptr;
  const double* signs = nullptr;
};

namespace supernodal_kernels {

// W values of one row of X (W = 1, 2, 4 or 8) as one vector (vector_registers.h): left to the
// compiler, the updates of a row stayed scalar at -O2, since a row may alias the row it is
// updated from. Without AVX-512, an 8-wide row, as a 64-byte vector or as a struct of two 4-wide
// ones (which went through the stack), was 2-3 times slower than two passes of 4: blocks wider
// than 4 are solved in passes of 4, 2 and 1 columns over the same rows (solve_passes). With
// AVX-512 a row of 8 is one register, and one pass over the factor for 8 columns costs far less
// than two (doc/benchmarks.md).
using vector_registers::load;
using vector_registers::store;
using vector_registers::zero;
template <int W>
struct Row_type;
template <>
struct Row_type<1>
{
  using type = double;
};
#ifdef LAPMESH_VECTOR_REGISTERS
template <>
struct Row_type<2>
{
  using type = vector_registers::Vec2;
};
template <>
struct Row_type<4>
{
  using type = vector_registers::Vec4;
};
template <>
struct Row_type<8>
{
  using type = vector_registers::Vec8;  // only in the AVX-512 build: one register there
};
#endif

// The rows below a supernode's triangle for C of its columns (c0 the first, ld apart): forward,
// each row of X is loaded and stored once for the C columns; backward, loaded once for C sums,
// which land in the C rows at xj. Most of a surface mesh's factor lies in supernodes of five or
// more columns, which passes of four and one took with two or more accesses to each row of X.
template <int C, typename R, std::size_t Stride>
LAPMESH_KERNEL_INLINE void forward_below(const double* c0, std::size_t ld, int ncol, int nrow, const int* rows,
                                         double* X, const double* xj)
{
  R v[C];
  for(int c = 0; c < C; ++c) v[c] = load<R>(xj + std::size_t(c) * Stride);
  for(int i = ncol; i < nrow; ++i) {
    double* xi = X + std::size_t(rows[i]) * Stride;
    if constexpr(C == 1) {
      store<R>(xi, load<R>(xi) - c0[i] * v[0]);
    } else {  // two partial sums: the additions of one sum form a dependency chain
      R even = c0[i] * v[0], odd = c0[ld + i] * v[1];
      for(int c = 2; c < C; c += 2) {
        even = even + c0[std::size_t(c) * ld + i] * v[c];
        if(c + 1 < C) odd = odd + c0[std::size_t(c + 1) * ld + i] * v[c + 1];
      }
      store<R>(xi, load<R>(xi) - (even + odd));
    }
  }
}

template <int C, typename R, std::size_t Stride>
LAPMESH_KERNEL_INLINE void backward_below(const double* c0, std::size_t ld, int ncol, int nrow, const int* rows,
                                          const double* X, double* xj)
{
  if constexpr(C == 1) {  // two partial sums, as above
    R a0 = zero<R>(), a1 = a0;
    int i = ncol;
    for(; i + 1 < nrow; i += 2) {
      a0 = a0 + c0[i] * load<R>(X + std::size_t(rows[i]) * Stride);
      a1 = a1 + c0[i + 1] * load<R>(X + std::size_t(rows[i + 1]) * Stride);
    }
    if(i < nrow) a0 = a0 + c0[i] * load<R>(X + std::size_t(rows[i]) * Stride);
    store<R>(xj, load<R>(xj) - (a0 + a1));
  } else {
    R a[C];
    for(int c = 0; c < C; ++c) a[c] = zero<R>();
    for(int i = ncol; i < nrow; ++i) {
      const R xi = load<R>(X + std::size_t(rows[i]) * Stride);
      for(int c = 0; c < C; ++c) a[c] = a[c] + c0[std::size_t(c) * ld + i] * xi;
    }
    for(int c = 0; c < C; ++c) store<R>(xj + std::size_t(c) * Stride, load<R>(xj + std::size_t(c) * Stride) - a[c]);
  }
}

template <bool Forward, int C, typename R, std::size_t Stride>
LAPMESH_KERNEL_INLINE void below_group(const double* Ls, int nrow, int ncol, int j, const int* rows, double* X,
                                       double* Xs)
{
  const double* c0 = Ls + std::size_t(j) * std::size_t(nrow);
  double* xj = Xs + std::size_t(j) * Stride;
  if constexpr(Forward)
    forward_below<C, R, Stride>(c0, std::size_t(nrow), ncol, nrow, rows, X, xj);
  else
    backward_below<C, R, Stride>(c0, std::size_t(nrow), ncol, nrow, rows, X, xj);
}

// Every column of a supernode below its triangle: groups of eight (the registers hold a group's
// values and the sums), then the rest in one group.
template <bool Forward, typename R, std::size_t Stride>
LAPMESH_KERNEL_INLINE void below_triangle(const double* Ls, int nrow, int ncol, const int* rows, double* X, double* Xs)
{
  int j = 0;
  for(; j + 8 <= ncol; j += 8) below_group<Forward, 8, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs);
  switch(ncol - j) {
    case 1: below_group<Forward, 1, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs); break;
    case 2: below_group<Forward, 2, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs); break;
    case 3: below_group<Forward, 3, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs); break;
    case 4: below_group<Forward, 4, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs); break;
    case 5: below_group<Forward, 5, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs); break;
    case 6: below_group<Forward, 6, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs); break;
    case 7: below_group<Forward, 7, R, Stride>(Ls, nrow, ncol, j, rows, X, Xs); break;
    default: break;
  }
}

// W of the right-hand sides of X, which holds Stride of them row by row (the W start at X).
template <int W, int Stride>
LAPMESH_KERNEL_INLINE void forward(const Supernodal_factor_view& L, double* X)
{
  using R = typename Row_type<W>::type;
  constexpr std::size_t stride = Stride;
  for(std::size_t s = 0; s < L.nsuper; ++s) {
    const int k1 = L.super[s], ncol = L.super[s + 1] - k1, nrow = L.pi[s + 1] - L.pi[s];
    const int* rows = L.rows + L.pi[s];
    const double* Ls = L.values + L.px[s];
    double* Xs = X + std::size_t(k1) * stride;
    for(int j = 0; j < ncol; ++j) {  // the dense triangle of the supernode
      const double* col = Ls + std::size_t(j) * std::size_t(nrow);
      double* xj = Xs + std::size_t(j) * stride;
      const R vj = (1.0 / col[j]) * load<R>(xj);
      store<R>(xj, vj);
      for(int i = j + 1; i < ncol; ++i) {
        double* xi = Xs + std::size_t(i) * stride;
        store<R>(xi, load<R>(xi) - col[i] * vj);
      }
    }
    below_triangle<true, R, stride>(Ls, nrow, ncol, rows, X, Xs);
  }
}

template <int W, int Stride>
LAPMESH_KERNEL_INLINE void backward(const Supernodal_factor_view& L, double* X)
{
  using R = typename Row_type<W>::type;
  constexpr std::size_t stride = Stride;
  for(std::size_t s = L.nsuper; s-- > 0;) {
    const int k1 = L.super[s], ncol = L.super[s + 1] - k1, nrow = L.pi[s + 1] - L.pi[s];
    const int* rows = L.rows + L.pi[s];
    const double* Ls = L.values + L.px[s];
    double* Xs = X + std::size_t(k1) * stride;
    below_triangle<false, R, stride>(Ls, nrow, ncol, rows, X, Xs);
    for(int jj = ncol; jj-- > 0;) {  // the dense triangle, backwards
      const double* col = Ls + std::size_t(jj) * std::size_t(nrow);
      double* xj = Xs + std::size_t(jj) * stride;
      R acc = load<R>(xj);
      for(int i = jj + 1; i < ncol; ++i) acc = acc - col[i] * load<R>(Xs + std::size_t(i) * stride);
      store<R>(xj, (1.0 / col[jj]) * acc);
    }
  }
}

// X = S X between the two triangular solves of an indefinite factor.
template <int W, int Stride>
LAPMESH_KERNEL_INLINE void apply_signs(const Supernodal_factor_view& L, double* X)
{
  using R = typename Row_type<W>::type;
  const std::size_t n = std::size_t(L.super[L.nsuper]);
  for(std::size_t i = 0; i < n; ++i) store<R>(X + i * Stride, L.signs[i] * load<R>(X + i * Stride));
}

template <int W, int Stride>
LAPMESH_KERNEL_INLINE void solve_pass(const Supernodal_factor_view& L, double* X)
{
  forward<W, Stride>(L, X);
  if(L.signs) apply_signs<W, Stride>(L, X);
  backward<W, Stride>(L, X);
}

#ifdef LAPMESH_VECTOR_REGISTERS
constexpr int widest_pass = 4;
#else
constexpr int widest_pass = 1;  // plain doubles: one column per pass
#endif

// Columns [Offset, Stride) of a block of Stride columns, in passes of 4, 2 and 1 columns.
template <int Stride, int Offset = 0>
LAPMESH_KERNEL_INLINE void solve_passes(const Supernodal_factor_view& L, double* X)
{
  if constexpr(Offset < Stride) {
    constexpr int left = Stride - Offset;
    constexpr int lanes = left >= 4 && widest_pass >= 4 ? 4 : left >= 2 && widest_pass >= 2 ? 2 : 1;
    solve_pass<lanes, Stride>(L, X + Offset);
    solve_passes<Stride, Offset + lanes>(L, X);
  }
}

// The block, `width` a supernodal_row_width().
LAPMESH_KERNEL_INLINE void solve_all(const Supernodal_factor_view& L, double* X, std::size_t width)
{
  switch(width) {
    case 1: solve_passes<1>(L, X); return;
    case 2: solve_passes<2>(L, X); return;
    case 4: solve_passes<4>(L, X); return;
    case 5: solve_passes<5>(L, X); return;
    case 6: solve_passes<6>(L, X); return;
    case 8: solve_passes<8>(L, X); return;
    default: assert(false && "supernodal kernels: width is not a supernodal_row_width()"); return;
  }
}

inline void solve_baseline(const Supernodal_factor_view& L, double* X, std::size_t width) { solve_all(L, X, width); }

#ifdef LAPMESH_SUPERNODAL_SOLVE_AVX2
__attribute__((target("avx2,fma"))) inline void solve_avx2(const Supernodal_factor_view& L, double* X,
                                                            std::size_t width)
{
  solve_all(L, X, width);
}

/// Blocks of 8 in one pass over the factor; the other widths are the AVX2 build's (measured level
/// with an AVX-512 build of them), so that their kernels are not compiled a third time.
__attribute__((target("avx512f,avx512vl,avx2,fma"))) inline void solve_avx512(const Supernodal_factor_view& L,
                                                                            double* X, std::size_t width)
{
  if(width == 8)
    solve_pass<8, 8>(L, X);
  else
    solve_avx2(L, X, width);
}
#endif

} // namespace supernodal_kernels

/// Whether a block of `width` right-hand sides goes through these kernels rather than CHOLMOD's
/// solves, with a Cholesky factor that CHOLMOD can solve. A single vector is memory bound either
/// way (CHOLMOD's solve was as fast, or faster on a factor read from memory); beyond 8, the BLAS
/// products of CHOLMOD's supernodal solves are large enough to pay for their overhead.
inline bool supernodal_kernels_fit(std::size_t width) { return width >= 2 && width <= 8; }

/// Whether the build of the solve that this CPU runs takes a row of 8 right-hand sides in one
/// pass over the factor (the AVX-512 build); the others take it in two passes of 4.
inline bool supernodal_rows_of_eight_in_one_pass()
{
#ifdef LAPMESH_SUPERNODAL_SOLVE_AVX2
  return cpu_has_avx512();
#else
  return false;
#endif
}

/// How many values a row of the kernels' block holds for `width` right-hand sides (1 to 8): 3 and 7 are solved as 4 and 8 with zero columns, which is
/// faster than their passes of 2 + 1 and 4 + 2 + 1 columns; where 8 columns take one pass
/// (supernodal_rows_of_eight_in_one_pass()), 5 and 6 are solved as 8 as well, instead of in
/// passes of 4 + 1 and 4 + 2 (doc/spectral.md). A column's arithmetic is the same in either
/// layout.
inline std::size_t supernodal_row_width(std::size_t width)
{
  if(width == 3 || width == 7) return width + 1;
  if((width == 5 || width == 6) && supernodal_rows_of_eight_in_one_pass()) return 8;
  return width;
}

/// Solves L L^T X = B (L S L^T X = B with the view's signs) in place: X holds `width` columns row
/// by row (row i at X + i * width), in the factor's (permuted) numbering; `width` is the
/// supernodal_row_width() of B's columns (1 to 8), the columns past B's being zero.
inline void supernodal_solve_rows(const Supernodal_factor_view& L, double* X, std::size_t width)
{
#ifdef LAPMESH_SUPERNODAL_SOLVE_AVX2
  if(supernodal_rows_of_eight_in_one_pass()) {
    supernodal_kernels::solve_avx512(L, X, width);
    return;
  }
  if(cpu_has_avx2_fma()) {
    supernodal_kernels::solve_avx2(L, X, width);
    return;
  }
#endif
  supernodal_kernels::solve_baseline(L, X, width);
}

/// Y = D K^-1 D X for K = L L^T (or L S L^T), D = diag(scale) (nullptr: the identity), in blocks
/// of at most 8 columns: row i of the factor's system is row row_of(i) of X, Y and scale,
/// gathered into `rows` (kept between calls by the caller) and scattered back.
template <typename RowOf>
void supernodal_scaled_solve(const Supernodal_factor_view& L, const RowOf& row_of, const double* scale,
                             const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::MatrixXd& Y, std::vector<double>& rows)
{
  const Eigen::Index n = X.rows(), cols = X.cols();
  Y.resize(n, cols);
  for(Eigen::Index first = 0; first < cols; first += 8) {
    const Eigen::Index count = std::min<Eigen::Index>(8, cols - first);
    // A row may hold zero columns after the block's (supernodal_row_width()).
    const std::size_t width = supernodal_row_width(std::size_t(count));
    rows.resize(std::size_t(n) * width);
    for(Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index r = row_of(i);
      const double d = scale ? scale[r] : 1.0;
      double* row = rows.data() + std::size_t(i) * width;
      for(Eigen::Index j = 0; j < count; ++j) row[j] = d * X(r, first + j);
      for(std::size_t j = std::size_t(count); j < width; ++j) row[j] = 0.0;
    }
    supernodal_solve_rows(L, rows.data(), width);
    for(Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index r = row_of(i);
      const double d = scale ? scale[r] : 1.0;
      const double* row = rows.data() + std::size_t(i) * width;
      for(Eigen::Index j = 0; j < count; ++j) Y(r, first + j) = d * row[j];
    }
  }
}

} // namespace internal
} // namespace lapmesh

#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

#endif
