// lapmesh — the dense products under the block eigensolver and the supernodal LDL^T: C = alpha
// op(A) B + beta C on column-major blocks, by the BLAS when lapmesh has one; and the products of a
// tall basis with a block of at most 8 columns by lapmesh's own kernels: V^T W alone, and the
// passes of a block Lanczos step (block_lanczos.h) that fuse W - V C with V^T W or W^T W.
//
// Why own kernels for the thin products. They are memory bound: each value of the basis is used
// for at most 8 multiply-adds. A BLAS first copies the basis into its blocked format (OpenBLAS's
// packing took as long as its multiplication kernel in a profile of 100 eigenpairs at 44k
// vertices), so it reads the basis from memory and then computes from cache, one after the
// other. The kernels below read each column of the basis once, in row panels, and multiply as
// they read: the rows of the thin block sit side by side in a small buffer that stays in the
// first-level cache. On x86-64 they are compiled for the baseline, for AVX2 + FMA and for
// AVX-512, chosen at run time: in the AVX-512 build a row of a block of 8 columns is one
// register, where the others hold it in two and run short of registers for the accumulators.
#ifndef LAPMESH_INTERNAL_DENSE_PRODUCTS_H
#define LAPMESH_INTERNAL_DENSE_PRODUCTS_H

#include <lapmesh/internal/cpu_features.h>
#include <lapmesh/internal/vector_registers.h>

#include <Eigen/Core>

#include <algorithm>
#include <cassert>
#include <cstddef>
#include <vector>

// The baseline build passes 32-byte vectors between inlined helpers, for which GCC notes that the
// ABI differs with AVX (Clang too): nothing crosses a call boundary.
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
// The kernels need vector registers (GCC and Clang); elsewhere the BLAS or Eigen does all.
#ifdef LAPMESH_VECTOR_REGISTERS
#define LAPMESH_THIN_PRODUCTS 1
#ifdef LAPMESH_X86_KERNEL_BUILDS
#define LAPMESH_THIN_PRODUCTS_AVX2 1
#endif
#endif

namespace lapmesh {
namespace internal {

#ifdef LAPMESH_HAS_BLAS
// Fortran BLAS (every BLAS has it; the trailing lengths are gfortran's hidden string arguments).
extern "C" void dgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k,
                       const double* alpha, const double* a, const int* lda, const double* b, const int* ldb,
                       const double* beta, double* c, const int* ldc, std::size_t, std::size_t);
#endif

/// C = alpha op(A) B + beta C in one product: the BLAS's dgemm with LAPMESH_HAS_BLAS, else Eigen.
/// As in BLAS, C's old content is not read when beta = 0 (it may be uninitialised, even NaN).
inline void product_block(bool transpose_a, double alpha, const Eigen::Ref<const Eigen::MatrixXd>& A,
                          const Eigen::Ref<const Eigen::MatrixXd>& B, double beta, Eigen::Ref<Eigen::MatrixXd> C)
{
#ifdef LAPMESH_HAS_BLAS
  const int m = int(C.rows()), n = int(C.cols()), k = int(transpose_a ? A.rows() : A.cols()),
            lda = int(std::max<Eigen::Index>(1, A.outerStride())), ldb = int(std::max<Eigen::Index>(1, B.outerStride())),
            ldc = int(std::max<Eigen::Index>(1, C.outerStride()));
  dgemm_(transpose_a ? "T" : "N", "N", &m, &n, &k, &alpha, A.data(), &lda, B.data(), &ldb, &beta, C.data(), &ldc, 1, 1);
#else
  if(beta == 0.0)
    C.setZero();
  else if(beta != 1.0)
    C *= beta;
  if(transpose_a)
    C.noalias() += alpha * (A.transpose() * B);
  else
    C.noalias() += alpha * (A * B);
#endif
}

/// C = alpha op(A) B + beta C with op(A) = A or A^T, on column-major blocks (any outer stride),
/// for a tall A. With LAPMESH_HAS_BLAS the BLAS library's dgemm does it: these products of a tall
/// basis with a thin block are memory bound, and an optimised BLAS (OpenBLAS, run-time
/// dispatched to the CPU's vector width) streams the basis faster than Eigen compiled for
/// generic x86-64. Either library packs the whole tall operand into its blocked format before
/// multiplying, which costs about as much as the product: a tall A with a thin B goes in row
/// panels that stay in cache (measured in doc/spectral.md).
inline void tall_gemm(bool transpose_a, double alpha, const Eigen::Ref<const Eigen::MatrixXd>& A,
                      const Eigen::Ref<const Eigen::MatrixXd>& B, double beta, Eigen::Ref<Eigen::MatrixXd> C)
{
  const Eigen::Index m = transpose_a ? A.cols() : A.rows();
  if(m == 0 || B.cols() == 0) return;
#ifdef LAPMESH_HAS_BLAS
  const Eigen::Index panel = 1024, widest_in_panels = 16;  // OpenBLAS packs wide blocks well
#else
  const Eigen::Index panel = std::max<Eigen::Index>(64, (Eigen::Index(1) << 16) / std::max<Eigen::Index>(1, A.cols()));
  const Eigen::Index widest_in_panels = B.cols();
#endif
  const Eigen::Index tall = A.rows();
  if(tall <= panel || B.cols() > widest_in_panels) {
    product_block(transpose_a, alpha, A, B, beta, C);
    return;
  }
  for(Eigen::Index r = 0; r < tall; r += panel) {
    const Eigen::Index h = std::min(panel, tall - r);
    if(transpose_a)  // C = alpha sum_p A_p^T B_p + beta C
      product_block(true, alpha, A.middleRows(r, h), B.middleRows(r, h), r == 0 ? beta : 1.0, C);
    else  // C_p = alpha A_p B + beta C_p
      product_block(false, alpha, A.middleRows(r, h), B, beta, C.middleRows(r, h));
  }
}

#ifdef LAPMESH_THIN_PRODUCTS
namespace thin_kernels {

using Index = std::ptrdiff_t;
// The kernels' registers: 4 doubles (AVX2 and the baseline, where GCC splits them), or 8 (AVX-512
// only). A row of a block of Lanes values is Lanes / width<Vec> such vectors.
using vector_registers::load;
using vector_registers::store;
using vector_registers::Vec4;
using vector_registers::Vec8;
using vector_registers::width;

/// Rows per panel of the product V^T W: the panel of W (at most 8 values a row) fills 16 KB.
constexpr Index panel_rows = 256;

/// A view of a column-major block: column j starts at data + j * stride.
struct Columns
{
  const double* data;
  Index stride;
};

/// Copies rows [r0, r0 + h) of the b columns of W into `rows`, Lanes values a row. The values
/// past b are left as they are: the lanes of a row never mix, and only the first b are read back.
template <int Lanes>
LAPMESH_KERNEL_INLINE void gather_rows(Columns W, Index b, Index r0, Index h, double* rows)
{
  for(Index c = 0; c < b; ++c) {
    const double* w = W.data + c * W.stride + r0;
    for(Index r = 0; r < h; ++r) rows[r * Lanes + c] = w[r];
  }
}

/// The inverse of gather_rows().
template <int Lanes>
LAPMESH_KERNEL_INLINE void scatter_rows(const double* rows, Index b, Index r0, Index h, double* W, Index ldw)
{
  for(Index c = 0; c < b; ++c) {
    double* w = W + c * ldw + r0;
    for(Index r = 0; r < h; ++r) w[r] = rows[r * Lanes + c];
  }
}

/// sums (rows j .. j + Cols - 1 of Lanes values each) += V[r0 : r0 + h, j : j + Cols]^T rows,
/// with Lanes = width<Vec> Vecs: Cols Vecs vectors accumulate independently.
template <typename Vec, int Vecs, int Cols>
LAPMESH_KERNEL_INLINE void accumulate_tn_columns(Columns V, Index j, Index r0, Index h, const double* rows, double* sums)
{
  constexpr int Lanes = width<Vec> * Vecs;
  const double* v = V.data + j * V.stride + r0;
  Vec acc[Cols][Vecs] = {};
  for(Index r = 0; r < h; ++r) {
    Vec w[Vecs];
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) w[q] = load<Vec>(rows + r * Lanes + width<Vec> * q);
#pragma GCC unroll 8
    for(int c = 0; c < Cols; ++c) {
      const double s = v[c * V.stride + r];
#pragma GCC unroll 2
      for(int q = 0; q < Vecs; ++q) acc[c][q] += s * w[q];
    }
  }
#pragma GCC unroll 8
  for(int c = 0; c < Cols; ++c)
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) {
      double* out = sums + (j + c) * Lanes + width<Vec> * q;
      store<Vec>(out, load<Vec>(out) + acc[c][q]);
    }
}

/// rows -= V[r0 : r0 + h, j : j + Cols] coefficients[j : j + Cols], rows and coefficients of
/// Lanes = width<Vec> Vecs values each.
template <typename Vec, int Vecs, int Cols>
LAPMESH_KERNEL_INLINE void subtract_lanes_columns(Columns V, Index j, Index r0, Index h, const double* coefficients,
                                                double* rows)
{
  constexpr int Lanes = width<Vec> * Vecs;
  const double* v = V.data + j * V.stride + r0;
  Vec k[Cols][Vecs];
#pragma GCC unroll 8
  for(int c = 0; c < Cols; ++c)
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) k[c][q] = load<Vec>(coefficients + (j + c) * Lanes + width<Vec> * q);
  for(Index r = 0; r < h; ++r) {
    Vec w[Vecs];
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) w[q] = load<Vec>(rows + r * Lanes + width<Vec> * q);
#pragma GCC unroll 8
    for(int c = 0; c < Cols; ++c) {
      const double s = v[c * V.stride + r];
#pragma GCC unroll 2
      for(int q = 0; q < Vecs; ++q) w[q] -= s * k[c][q];
    }
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) store<Vec>(rows + r * Lanes + width<Vec> * q, w[q]);
  }
}

/// Runs `step.template columns<Cols>(j)` over columns [0, m) of V: Widest columns at a time, the
/// rest in groups of 4, 2 and 1.
template <int Widest, typename Step>
LAPMESH_KERNEL_INLINE void over_column_groups(Index m, const Step& step)
{
  Index j = 0;
  for(; j + Widest <= m; j += Widest) step.template columns<Widest>(j);
  if(Widest > 4 && j + 4 <= m) {
    step.template columns<4>(j);
    j += 4;
  }
  if(j + 2 <= m) {
    step.template columns<2>(j);
    j += 2;
  }
  if(j < m) step.template columns<1>(j);
}

// The panel steps as objects (not lambdas, which would not be compiled for the caller's target).
template <typename Vec, int Vecs>
struct Accumulate_tn
{
  Columns V;
  Index r0, h;
  const double* rows;
  double* sums;
  template <int Cols>
  LAPMESH_KERNEL_INLINE void columns(Index j) const
  {
    accumulate_tn_columns<Vec, Vecs, Cols>(V, j, r0, h, rows, sums);
  }
};

template <typename Vec, int Vecs>
struct Subtract_lanes
{
  Columns V;
  Index r0, h;
  const double* coefficients;
  double* rows;
  template <int Cols>
  LAPMESH_KERNEL_INLINE void columns(Index j) const
  {
    subtract_lanes_columns<Vec, Vecs, Cols>(V, j, r0, h, coefficients, rows);
  }
};

/// C (m x b, leading dimension ldc) = V[:, 0:m]^T W, V and W of n rows, 1 <= b <= 8.
template <typename Vec, int Vecs>
LAPMESH_KERNEL_INLINE void product_tn(Columns V, Index n, Index m, Columns W, Index b, double* C, Index ldc)
{
  constexpr int Lanes = width<Vec> * Vecs;
  std::vector<double> sums(std::size_t(m * Lanes), 0.0);
  alignas(32) double rows[panel_rows * Lanes] = {};
  for(Index r0 = 0; r0 < n; r0 += panel_rows) {
    const Index h = std::min(panel_rows, n - r0);
    gather_rows<Lanes>(W, b, r0, h, rows);
    over_column_groups<8 / Vecs>(m, Accumulate_tn<Vec, Vecs>{V, r0, h, rows, sums.data()});
  }
  for(Index c = 0; c < b; ++c)
    for(Index j = 0; j < m; ++j) C[c * ldc + j] = sums[std::size_t(j * Lanes + c)];
}

/// product_tn() for a block of b columns: four lanes up to 4, eight beyond, in registers of type
/// Wide (two Vec4 or one Vec8).
template <typename Wide>
LAPMESH_KERNEL_INLINE void product_tn_any_width(Columns V, Index n, Index m, Columns W, Index b, double* C, Index ldc)
{
  if(b <= 4)
    product_tn<Vec4, 1>(V, n, m, W, b, C, ldc);
  else
    product_tn<Wide, 8 / width<Wide>>(V, n, m, W, b, C, ldc);
}

/// gram (Lanes x Lanes, row c at gram + c Lanes) += rows^T rows over h rows of Lanes values.
template <typename Vec, int Vecs>
LAPMESH_KERNEL_INLINE void accumulate_gram(Index h, const double* rows, double* gram)
{
  constexpr int Lanes = width<Vec> * Vecs;
  Vec acc[Lanes][Vecs] = {};
  for(Index r = 0; r < h; ++r) {
    Vec w[Vecs];
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) w[q] = load<Vec>(rows + r * Lanes + width<Vec> * q);
#pragma GCC unroll 8
    for(int c = 0; c < Lanes; ++c) {
      const double s = rows[r * Lanes + c];
#pragma GCC unroll 2
      for(int q = 0; q < Vecs; ++q) acc[c][q] += s * w[q];
    }
  }
#pragma GCC unroll 8
  for(int c = 0; c < Lanes; ++c)
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) store<Vec>(gram + c * Lanes + width<Vec> * q, load<Vec>(gram + c * Lanes + width<Vec> * q) + acc[c][q]);
}

/// rows = rows F over h rows of Lanes values, F Lanes x Lanes (row c at factor + c Lanes).
template <typename Vec, int Vecs>
LAPMESH_KERNEL_INLINE void multiply_rows(Index h, const double* factor, double* rows)
{
  constexpr int Lanes = width<Vec> * Vecs;
  Vec f[Lanes][Vecs];
#pragma GCC unroll 8
  for(int c = 0; c < Lanes; ++c)
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) f[c][q] = load<Vec>(factor + c * Lanes + width<Vec> * q);
  for(Index r = 0; r < h; ++r) {
    Vec y[Vecs] = {};
#pragma GCC unroll 8
    for(int c = 0; c < Lanes; ++c) {
      const double s = rows[r * Lanes + c];
#pragma GCC unroll 2
      for(int q = 0; q < Vecs; ++q) y[q] += s * f[c][q];
    }
#pragma GCC unroll 2
    for(int q = 0; q < Vecs; ++q) store<Vec>(rows + r * Lanes + width<Vec> * q, y[q]);
  }
}

/// One fused pass over the block W (see fused_panels()): what it subtracts, computes and writes.
struct Fused_pass
{
  Index n;
  Columns Vl;
  Index ml;
  const double* local_coefficients;  ///< ml rows of Lanes values
  Columns Va;
  Index ma;
  const double* all_coefficients;    ///< ma rows of Lanes values, or null: no second subtraction
  Columns W;
  Index b;
  double* product;  ///< ma x b, leading dimension ldp, or null
  Index ldp;
  const double* factor;  ///< Lanes x Lanes, or null
  double* gram;          ///< b x b, or null
  double* out;           ///< where the block goes (may be W's data)
  Index ldo;
};

/// One pass of a block Lanczos step over the block, reading the basis and the block once, in row
/// panels; its entry points in block_lanczos.h use it as
///   subtract_then_product_tn(): W -= Vl Cl, then Cg = Va^T W;
///   subtract_then_gram():       W -= Va Cg, then G = W^T W;
///   multiply_then_gram():       Out = W F, then G = Out^T Out (Out may be W).
/// A null pointer skips its part, a zero `ml` the first subtraction.
template <typename Vec, int Vecs>
LAPMESH_KERNEL_INLINE void fused_panels(const Fused_pass& p)
{
  constexpr int Lanes = width<Vec> * Vecs;
  std::vector<double> sums(std::size_t(p.product ? p.ma * Lanes : 0), 0.0);
  alignas(32) double rows[panel_rows * Lanes] = {};
  alignas(32) double gram_lanes[Lanes * Lanes] = {};
  for(Index r0 = 0; r0 < p.n; r0 += panel_rows) {
    const Index h = std::min(panel_rows, p.n - r0);
    gather_rows<Lanes>(p.W, p.b, r0, h, rows);
    if(p.ml > 0)
      over_column_groups<8 / Vecs>(p.ml, Subtract_lanes<Vec, Vecs>{p.Vl, r0, h, p.local_coefficients, rows});
    if(p.all_coefficients)
      over_column_groups<8 / Vecs>(p.ma, Subtract_lanes<Vec, Vecs>{p.Va, r0, h, p.all_coefficients, rows});
    if(p.product) over_column_groups<8 / Vecs>(p.ma, Accumulate_tn<Vec, Vecs>{p.Va, r0, h, rows, sums.data()});
    if(p.factor) multiply_rows<Vec, Vecs>(h, p.factor, rows);
    if(p.gram) accumulate_gram<Vec, Vecs>(h, rows, gram_lanes);
    scatter_rows<Lanes>(rows, p.b, r0, h, p.out, p.ldo);
  }
  if(p.product)
    for(Index c = 0; c < p.b; ++c)
      for(Index j = 0; j < p.ma; ++j) p.product[c * p.ldp + j] = sums[std::size_t(j * Lanes + c)];
  if(p.gram)
    for(Index c = 0; c < p.b; ++c)
      for(Index j = 0; j < p.b; ++j) p.gram[c * p.b + j] = gram_lanes[j * Lanes + c];
}

/// fused_panels() for a block of b columns, as product_tn_any_width().
template <typename Wide>
LAPMESH_KERNEL_INLINE void fused_any_width(const Fused_pass& p)
{
  if(p.b <= 4)
    fused_panels<Vec4, 1>(p);
  else
    fused_panels<Wide, 8 / width<Wide>>(p);
}

inline void fused_baseline(const Fused_pass& p) { fused_any_width<Vec4>(p); }

inline void product_tn_baseline(Columns V, Index n, Index m, Columns W, Index b, double* C, Index ldc)
{
  product_tn_any_width<Vec4>(V, n, m, W, b, C, ldc);
}
#ifdef LAPMESH_THIN_PRODUCTS_AVX2
__attribute__((target("avx2,fma"))) inline void product_tn_avx2(Columns V, Index n, Index m, Columns W, Index b,
                                                                 double* C, Index ldc)
{
  product_tn_any_width<Vec4>(V, n, m, W, b, C, ldc);
}
__attribute__((target("avx2,fma"))) inline void fused_avx2(const Fused_pass& p) { fused_any_width<Vec4>(p); }
__attribute__((target("avx512f,avx512vl,avx2,fma"))) inline void product_tn_avx512(Columns V, Index n, Index m,
                                                                                 Columns W, Index b, double* C,
                                                                                 Index ldc)
{
  product_tn_any_width<Vec8>(V, n, m, W, b, C, ldc);
}
__attribute__((target("avx512f,avx512vl,avx2,fma"))) inline void fused_avx512(const Fused_pass& p)
{
  fused_any_width<Vec8>(p);
}
#endif

/// Whether the kernels are compiled for AVX2 + FMA and the CPU has both.
inline bool use_avx2()
{
#ifdef LAPMESH_THIN_PRODUCTS_AVX2
  return cpu_has_avx2_fma();
#else
  return false;
#endif
}

/// Whether the kernels are compiled for AVX-512 and the CPU has it.
inline bool use_avx512()
{
#ifdef LAPMESH_THIN_PRODUCTS_AVX2
  return cpu_has_avx512();
#else
  return false;
#endif
}

/// The build of the kernels that this CPU runs, chosen once.
struct Kernels
{
  void (*product_tn)(Columns V, Index n, Index m, Columns W, Index b, double* C, Index ldc);
  void (*fused)(const Fused_pass& pass);
};
inline const Kernels& kernels()
{
#ifdef LAPMESH_THIN_PRODUCTS_AVX2
  static const Kernels chosen = use_avx512() ? Kernels{&product_tn_avx512, &fused_avx512}
                                : use_avx2() ? Kernels{&product_tn_avx2, &fused_avx2}
                                             : Kernels{&product_tn_baseline, &fused_baseline};
#else
  static const Kernels chosen{&product_tn_baseline, &fused_baseline};
#endif
  return chosen;
}

} // namespace thin_kernels

/// The widest block that thin_product_tn() and the fused passes take.
constexpr Eigen::Index thin_block_max_columns = 8;

/// C = V^T W for a tall V (any outer stride) and a W of 1 to 8 columns (thin_block_max_columns).
inline void thin_product_tn(const Eigen::Ref<const Eigen::MatrixXd>& V, const Eigen::Ref<const Eigen::MatrixXd>& W,
                            Eigen::MatrixXd& C)
{
  assert(V.rows() == W.rows() && W.cols() >= 1 && W.cols() <= thin_block_max_columns);
  C.resize(V.cols(), W.cols());
  thin_kernels::kernels().product_tn({V.data(), V.outerStride()}, V.rows(), V.cols(), {W.data(), W.outerStride()},
                                     W.cols(), C.data(), C.outerStride());
}
#endif

} // namespace internal
} // namespace lapmesh

#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

#endif
