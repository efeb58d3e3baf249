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

/// C = alpha op(A) B + beta C with op(A) = A or A^T, on column-major blocks (any outer stride).
/// With LAPMESH_HAS_BLAS the BLAS library's dgemm does it: these products of a tall basis with a
/// thin block are memory bound, and an optimised BLAS (OpenBLAS, run-time dispatched to the
/// CPU's vector width) streams the basis faster than Eigen compiled for generic x86-64. Without
/// it, Eigen in row panels that stay in cache (Eigen's product would otherwise copy the whole
/// tall operand into its packed format first).
inline void tall_gemm(bool transpose_a, double alpha, const Eigen::Ref<const Eigen::MatrixXd>& A,
                      const Eigen::Ref<const Eigen::MatrixXd>& B, double beta, Eigen::Ref<Eigen::MatrixXd> C)
{
  const Eigen::Index m = transpose_a ? A.cols() : A.rows(), k = transpose_a ? A.rows() : A.cols();
  if(m == 0 || B.cols() == 0) return;
#ifdef LAPMESH_HAS_BLAS
  const int in = int(B.cols()), lda = int(std::max<Eigen::Index>(1, A.outerStride())),
            ldb = int(std::max<Eigen::Index>(1, B.outerStride())), ldc = int(std::max<Eigen::Index>(1, C.outerStride()));
  // A tall operand times a thin one: the BLAS packs the whole tall operand into its blocked
  // format before multiplying, which costs about as much as the product. Row panels that stay
  // in cache make the packing cheap (measured in doc/benchmarks.md).
  const Eigen::Index tall = A.rows(), panel = 1024;
  if(tall <= 2 * panel || B.cols() > 16) {
    const int im = int(m), ik = int(k);
    dgemm_(transpose_a ? "T" : "N", "N", &im, &in, &ik, &alpha, A.data(), &lda, B.data(), &ldb, &beta, C.data(), &ldc,
           1, 1);
    return;
  }
  for(Eigen::Index r = 0; r < tall; r += panel) {
    const int h = int(std::min(panel, tall - r));
    if(transpose_a) {  // C = alpha sum_p A_p^T B_p + beta C
      const int im = int(m);
      const double panel_beta = r == 0 ? beta : 1.0;
      dgemm_("T", "N", &im, &in, &h, &alpha, A.data() + r, &lda, B.data() + r, &ldb, &panel_beta, C.data(), &ldc, 1, 1);
    } else {  // C_p = alpha A_p B + beta C_p
      const int ik = int(k);
      dgemm_("N", "N", &h, &in, &ik, &alpha, A.data() + r, &lda, B.data(), &ldb, &beta, C.data() + r, &ldc, 1, 1);
    }
  }
#else
  if(beta == 0.0)
    C.setZero();  // as in BLAS: C's old content is not read (it may be uninitialised, even NaN)
  else if(beta != 1.0)
    C *= beta;
  if(k == 0) return;
  const Eigen::Index tall = A.rows();
  const Eigen::Index panel = std::max<Eigen::Index>(64, (Eigen::Index(1) << 16) / std::max<Eigen::Index>(1, A.cols()));
  for(Eigen::Index r = 0; r < tall; r += panel) {
    const Eigen::Index h = std::min(panel, tall - r);
    if(transpose_a)
      C.noalias() += alpha * (A.middleRows(r, h).transpose() * B.middleRows(r, h));
    else
      C.middleRows(r, h).noalias() += alpha * (A.middleRows(r, h) * B);
  }
#endif
}

} // namespace internal
} // namespace lapmesh

#endif
