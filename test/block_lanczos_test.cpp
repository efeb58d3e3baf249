// The block Lanczos's dense kernels without a BLAS library: this file is compiled into a test
// executable that does not link CHOLMOD, so LAPMESH_HAS_BLAS is not defined and tall_gemm takes
// its Eigen path (the one a header-only user without SuiteSparse gets).
#include <lapmesh/internal/block_lanczos.h>

#include <gtest/gtest.h>

#include <limits>
#include <utility>
#include <vector>

TEST(BlockLanczos, EigenFallbackProductsAndEigenpairs)
{
#ifdef LAPMESH_HAS_BLAS
  FAIL() << "this test must be built without LAPMESH_HAS_BLAS";
#endif
  using Eigen::MatrixXd;
  const Eigen::Index n = 20000;  // several row panels (of 65536 / 7 rows)
  // W wider than the thin kernels take (thin_block_max_columns), so that tall_gemm runs.
  const MatrixXd big = MatrixXd::Random(n, 12), W = MatrixXd::Random(n, 10);
  const auto V = big.middleCols(2, 7);  // a block with an outer stride, as the basis slices are
  MatrixXd C(7, 10);
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

#ifdef LAPMESH_THIN_PRODUCTS  // GCC and Clang
TEST(BlockLanczos, ThinKernelsEqualEigenProducts)
{
  // lapmesh's kernels for V^T W and W - V C with W of 1 to 8 columns, in both builds (the
  // baseline and, where the CPU has it, AVX2 + FMA): every width, column counts that leave every
  // remainder of the groups of 8, 4, 2 and 1 columns, heights around the row panels (128 and 256
  // rows), and slices with outer strides whose neighbouring columns must stay untouched.
  using Eigen::Index;
  using Eigen::MatrixXd;
  namespace k = lapmesh::internal::thin_kernels;
  using Product = void (*)(k::Columns, Index, Index, k::Columns, Index, double*, Index);
  using Subtract = void (*)(k::Columns, Index, Index, k::Columns, double*, Index, Index);
  std::vector<std::pair<Product, Subtract>> builds = {{k::product_tn_baseline, k::subtract_baseline}};
#ifdef LAPMESH_THIN_PRODUCTS_AVX2
  if(k::use_avx2()) builds.emplace_back(k::product_tn_avx2, k::subtract_avx2);
#endif
  int cases = 0;
  for(const auto& build : builds)
    for(const Index n : {1, 3, 127, 129, 256, 257, 700})
      for(const Index m : {1, 2, 3, 5, 7, 8, 9, 13, 15, 30})
        for(Index b = 1; b <= lapmesh::internal::thin_block_max_columns; ++b) {
          const MatrixXd big_v = MatrixXd::Random(n, m + 3);
          const auto V = big_v.middleCols(1, m);
          MatrixXd big_w = MatrixXd::Random(n, b + 2);
          const MatrixXd w_before = big_w;
          const double tolerance = 1e-14 * double(n + m);

          MatrixXd C = MatrixXd::Constant(m + 1, b, std::numeric_limits<double>::quiet_NaN());
          build.first(k::Columns{V.data(), V.outerStride()}, n, m, k::Columns{big_w.data() + n, n}, b, C.data(),
                      C.outerStride());
          const MatrixXd C_ref = V.transpose() * big_w.middleCols(1, b);
          ASSERT_LE((C.topRows(m) - C_ref).cwiseAbs().maxCoeff(), tolerance) << n << " " << m << " " << b;
          EXPECT_TRUE(C.row(m).hasNaN());  // past the leading dimension's m rows: not written

          build.second(k::Columns{V.data(), V.outerStride()}, n, m, k::Columns{C_ref.data(), C_ref.outerStride()},
                       big_w.data() + n, n, b);
          const MatrixXd W_ref = w_before.middleCols(1, b) - V * C_ref;
          ASSERT_LE((big_w.middleCols(1, b) - W_ref).cwiseAbs().maxCoeff(), tolerance) << n << " " << m << " " << b;
          EXPECT_TRUE(big_w.col(0) == w_before.col(0));
          EXPECT_TRUE(big_w.col(b + 1) == w_before.col(b + 1));
          ++cases;
        }
  EXPECT_EQ(cases, int(builds.size()) * 7 * 10 * 8);

  // The entry points that the block Lanczos calls, on Eigen blocks.
  const MatrixXd V = MatrixXd::Random(1000, 37), W = MatrixXd::Random(1000, 6);
  MatrixXd C;
  lapmesh::internal::thin_product_tn(V, W, C);
  ASSERT_EQ(C.rows(), 37);
  ASSERT_EQ(C.cols(), 6);
  EXPECT_LE((C - V.transpose() * W).cwiseAbs().maxCoeff(), 1e-12);
  MatrixXd W2 = W;
  lapmesh::internal::thin_subtract_product(V, C, W2);
  EXPECT_LE((W2 - (W - V * C)).cwiseAbs().maxCoeff(), 1e-12);
}
#endif
