// lapmesh — the two triangular solves with a supernodal Cholesky factor L (L L^T X = B), on a
// block of right-hand sides stored row by row (the values of one row of X side by side).
//
// Why not CHOLMOD's own solves. The factors of surface meshes have many small supernodes (a few
// columns each), and a block Krylov method solves with a handful of right-hand sides. CHOLMOD
// calls the BLAS (dtrsm, dgemm) on each supernode, where the call and packing overhead of such
// small products outweighs the arithmetic. Here each column of L is read once, contiguously, and
// applied to the few values of the rows it touches; the rows are stored side by side so that one
// cache line holds all the right-hand sides of a row. Four columns of a supernode go together
// below its diagonal block, so that a row of X is loaded and stored once for four columns.
// On x86-64 the kernels are compiled twice, for the baseline and for AVX2 + FMA, chosen at run
// time (the generic build otherwise uses two-wide vectors only).
#ifndef LAPMESH_INTERNAL_SUPERNODAL_SOLVE_H
#define LAPMESH_INTERNAL_SUPERNODAL_SOLVE_H

#include <cassert>
#include <cstddef>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define LAPMESH_SUPERNODAL_SOLVE_AVX2 1
#define LAPMESH_ALWAYS_INLINE __attribute__((always_inline)) inline
#else
#define LAPMESH_ALWAYS_INLINE inline
#endif

namespace lapmesh {
namespace internal {

/// The structure and values of a supernodal factor in CHOLMOD's layout: supernode s holds the
/// columns super[s] .. super[s+1]-1, its row indices are rows[pi[s] .. pi[s+1]) (the first ones
/// are its own columns), its values the column-major block at values + px[s] (leading dimension:
/// its number of rows).
struct Supernodal_factor_view
{
  const int* super = nullptr;
  const int* pi = nullptr;
  const int* px = nullptr;
  const int* rows = nullptr;
  std::size_t nsuper = 0;
  const double* values = nullptr;
};

namespace supernodal_kernels {

// X holds W right-hand sides row by row. W is a compile-time constant: the compiler keeps a row
// in vector registers.
template <int W>
LAPMESH_ALWAYS_INLINE void forward(const Supernodal_factor_view& L, double* X)
{
  constexpr std::size_t stride = W;
  for(std::size_t s = 0; s < L.nsuper; ++s) {
    const int k1 = L.super[s], ncol = L.super[s + 1] - k1, nrow = L.pi[s + 1] - L.pi[s];
    const int* rows = L.rows + L.pi[s];
    const double* Ls = L.values + L.px[s];
    double* Xs = X + std::size_t(k1) * stride;
    for(int j = 0; j < ncol; ++j) {  // the dense triangle of the supernode
      const double* col = Ls + std::size_t(j) * std::size_t(nrow);
      double* xj = Xs + std::size_t(j) * stride;
      const double inv = 1.0 / col[j];
      for(int c = 0; c < W; ++c) xj[c] *= inv;
      for(int i = j + 1; i < ncol; ++i) {
        double* xi = Xs + std::size_t(i) * stride;
        const double l = col[i];
        for(int c = 0; c < W; ++c) xi[c] -= l * xj[c];
      }
    }
    int j = 0;
    for(; j + 4 <= ncol; j += 4) {  // the rows below it, four columns at a time
      const double* c0 = Ls + std::size_t(j) * std::size_t(nrow);
      const double *c1 = c0 + nrow, *c2 = c1 + nrow, *c3 = c2 + nrow;
      const double* v0 = Xs + std::size_t(j) * stride;
      const double *v1 = v0 + stride, *v2 = v1 + stride, *v3 = v2 + stride;
      for(int i = ncol; i < nrow; ++i) {
        double* xi = X + std::size_t(rows[i]) * stride;
        const double l0 = c0[i], l1 = c1[i], l2 = c2[i], l3 = c3[i];
        for(int c = 0; c < W; ++c) xi[c] -= (l0 * v0[c] + l1 * v1[c]) + (l2 * v2[c] + l3 * v3[c]);
      }
    }
    for(; j < ncol; ++j) {
      const double* c0 = Ls + std::size_t(j) * std::size_t(nrow);
      const double* v0 = Xs + std::size_t(j) * stride;
      for(int i = ncol; i < nrow; ++i) {
        double* xi = X + std::size_t(rows[i]) * stride;
        const double l0 = c0[i];
        for(int c = 0; c < W; ++c) xi[c] -= l0 * v0[c];
      }
    }
  }
}

template <int W>
LAPMESH_ALWAYS_INLINE void backward(const Supernodal_factor_view& L, double* X)
{
  constexpr std::size_t stride = W;
  for(std::size_t s = L.nsuper; s-- > 0;) {
    const int k1 = L.super[s], ncol = L.super[s + 1] - k1, nrow = L.pi[s + 1] - L.pi[s];
    const int* rows = L.rows + L.pi[s];
    const double* Ls = L.values + L.px[s];
    double* Xs = X + std::size_t(k1) * stride;
    int j = 0;
    for(; j + 4 <= ncol; j += 4) {  // the rows below the triangle, four columns at a time
      const double* c0 = Ls + std::size_t(j) * std::size_t(nrow);
      const double *c1 = c0 + nrow, *c2 = c1 + nrow, *c3 = c2 + nrow;
      double a0[W] = {}, a1[W] = {}, a2[W] = {}, a3[W] = {};
      for(int i = ncol; i < nrow; ++i) {
        const double* xi = X + std::size_t(rows[i]) * stride;
        const double l0 = c0[i], l1 = c1[i], l2 = c2[i], l3 = c3[i];
        for(int c = 0; c < W; ++c) {
          a0[c] += l0 * xi[c];
          a1[c] += l1 * xi[c];
          a2[c] += l2 * xi[c];
          a3[c] += l3 * xi[c];
        }
      }
      double* v0 = Xs + std::size_t(j) * stride;
      double *v1 = v0 + stride, *v2 = v1 + stride, *v3 = v2 + stride;
      for(int c = 0; c < W; ++c) {
        v0[c] -= a0[c];
        v1[c] -= a1[c];
        v2[c] -= a2[c];
        v3[c] -= a3[c];
      }
    }
    for(; j < ncol; ++j) {  // two partial sums: the additions of one sum form a dependency chain
      const double* c0 = Ls + std::size_t(j) * std::size_t(nrow);
      double a0[W] = {}, a1[W] = {};
      int i = ncol;
      for(; i + 1 < nrow; i += 2) {
        const double* x0 = X + std::size_t(rows[i]) * stride;
        const double* x1 = X + std::size_t(rows[i + 1]) * stride;
        const double l0 = c0[i], l1 = c0[i + 1];
        for(int c = 0; c < W; ++c) {
          a0[c] += l0 * x0[c];
          a1[c] += l1 * x1[c];
        }
      }
      if(i < nrow) {
        const double* x0 = X + std::size_t(rows[i]) * stride;
        for(int c = 0; c < W; ++c) a0[c] += c0[i] * x0[c];
      }
      double* v0 = Xs + std::size_t(j) * stride;
      for(int c = 0; c < W; ++c) v0[c] -= a0[c] + a1[c];
    }
    for(int jj = ncol; jj-- > 0;) {  // the dense triangle, backwards
      const double* col = Ls + std::size_t(jj) * std::size_t(nrow);
      double* xj = Xs + std::size_t(jj) * stride;
      for(int i = jj + 1; i < ncol; ++i) {
        const double* xi = Xs + std::size_t(i) * stride;
        const double l = col[i];
        for(int c = 0; c < W; ++c) xj[c] -= l * xi[c];
      }
      const double inv = 1.0 / col[jj];
      for(int c = 0; c < W; ++c) xj[c] *= inv;
    }
  }
}

template <int W>
LAPMESH_ALWAYS_INLINE void solve_width(const Supernodal_factor_view& L, double* X)
{
  forward<W>(L, X);
  backward<W>(L, X);
}

// One pass over the factor for the block (its width checked by supernodal_kernels_fit()).
LAPMESH_ALWAYS_INLINE void solve_all(const Supernodal_factor_view& L, double* X, std::size_t width)
{
  switch(width) {
    case 2: solve_width<2>(L, X); return;
    case 3: solve_width<3>(L, X); return;
    case 4: solve_width<4>(L, X); return;
    case 5: solve_width<5>(L, X); return;
    case 6: solve_width<6>(L, X); return;
    case 7: solve_width<7>(L, X); return;
    case 8: solve_width<8>(L, X); return;
    default: assert(false && "supernodal kernels: width outside supernodal_kernels_fit()"); return;
  }
}

inline void solve_baseline(const Supernodal_factor_view& L, double* X, std::size_t width) { solve_all(L, X, width); }

#ifdef LAPMESH_SUPERNODAL_SOLVE_AVX2
__attribute__((target("avx2,fma"))) inline void solve_avx2(const Supernodal_factor_view& L, double* X,
                                                            std::size_t width)
{
  solve_all(L, X, width);
}
#endif

} // namespace supernodal_kernels

/// Whether supernodal_llt_solve_rows() takes a block of `width` right-hand sides. A single vector
/// is memory bound either way (CHOLMOD's solve was as fast, or faster on a factor read from
/// memory); beyond 8, the BLAS products of CHOLMOD's supernodal solves are large enough to pay
/// for their overhead.
inline bool supernodal_kernels_fit(std::size_t width) { return width >= 2 && width <= 8; }

/// Solves L L^T X = B in place: X holds B's `width` columns (supernodal_kernels_fit(width)) row
/// by row (row i of B at X + i * width), in the factor's (permuted) numbering.
inline void supernodal_llt_solve_rows(const Supernodal_factor_view& L, double* X, std::size_t width)
{
#ifdef LAPMESH_SUPERNODAL_SOLVE_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  if(avx2) {
    supernodal_kernels::solve_avx2(L, X, width);
    return;
  }
#endif
  supernodal_kernels::solve_baseline(L, X, width);
}

} // namespace internal
} // namespace lapmesh

#undef LAPMESH_ALWAYS_INLINE

#endif
