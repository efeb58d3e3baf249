// lapmesh — the dense product under the block eigensolver and the supernodal LDL^T: C = alpha
// op(A) B + beta C on column-major blocks, by the BLAS when lapmesh has one.
#ifndef LAPMESH_INTERNAL_DENSE_PRODUCTS_H
#define LAPMESH_INTERNAL_DENSE_PRODUCTS_H

#include <Eigen/Core>

#include <algorithm>
#include <cstddef>

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

} // namespace internal
} // namespace lapmesh

#endif
