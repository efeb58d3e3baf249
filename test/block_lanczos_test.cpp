// The block Lanczos's dense kernels without a BLAS library: this file is compiled into a test
// executable that does not link CHOLMOD, so LAPMESH_HAS_BLAS is not defined and tall_gemm takes
// its Eigen path (the one a header-only user without SuiteSparse gets).
#include <lapmesh/internal/block_lanczos.h>

#include <gtest/gtest.h>

#include <limits>

TEST(BlockLanczos, EigenFallbackProductsAndEigenpairs)
{
#ifdef LAPMESH_HAS_BLAS
  FAIL() << "this test must be built without LAPMESH_HAS_BLAS";
#endif
  using Eigen::MatrixXd;
  const Eigen::Index n = 20000;  // several row panels (of 65536 / 7 rows)
  const MatrixXd big = MatrixXd::Random(n, 12), W = MatrixXd::Random(n, 3);
  const auto V = big.middleCols(2, 7);  // a block with an outer stride, as the basis slices are
  MatrixXd C(7, 3);
  C.setConstant(std::numeric_limits<double>::quiet_NaN());  // beta = 0 must not read C
  lapmesh::internal::panel_product_tn(V, W, C);
  EXPECT_LE((C - V.transpose() * W).cwiseAbs().maxCoeff(), 1e-10);
  MatrixXd W2 = W;
  lapmesh::internal::panel_subtract_product(V, C, W2);
  EXPECT_LE((W2 - (W - V * C)).cwiseAbs().maxCoeff(), 1e-10);
  // The restart's and the result's product, in place: the first 4 columns become V[:, 0:7] Z.
  const MatrixXd Z = MatrixXd::Random(7, 4);
  MatrixXd rotated = big, panel;
  lapmesh::internal::rotate_in_place(rotated, 7, Z, panel);
  EXPECT_LE((rotated.leftCols(4) - big.leftCols(7) * Z).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_TRUE(rotated.rightCols(8) == big.rightCols(8));

  // The whole solver on a diagonal operator with known eigenpairs: diag(1, ..., 400).
  const Eigen::Index m = 400;
  const Eigen::VectorXd d = Eigen::VectorXd::LinSpaced(m, 1.0, double(m));
  lapmesh::internal::Block_lanczos_options opt;
  opt.block_size = 4;
  const auto r = lapmesh::internal::block_lanczos_largest(
    m, 6, [&](const MatrixXd& X, MatrixXd& Yx) { Yx = d.asDiagonal() * X; }, opt);
  ASSERT_EQ(r.values.size(), 6);
  ASSERT_EQ(r.vectors.cols(), 6);  // the basis, shrunk to the Ritz vectors
  for(Eigen::Index i = 0; i < 6; ++i) {
    EXPECT_NEAR(r.values[i], double(m - i), 1e-8 * double(m));
    EXPECT_NEAR(std::abs(r.vectors(m - 1 - i, i)), 1.0, 1e-6);  // the unit vector e_{m-1-i}
  }
  EXPECT_LE((r.vectors.transpose() * r.vectors - MatrixXd::Identity(6, 6)).cwiseAbs().maxCoeff(), 1e-10);
}
