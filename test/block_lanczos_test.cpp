// The block Lanczos's dense kernels without a BLAS library: this file is compiled into a test
// executable that does not link CHOLMOD, so LAPMESH_HAS_BLAS is not defined and tall_gemm takes
// its Eigen path (the one a header-only user without SuiteSparse gets).
#include <lapmesh/internal/block_lanczos.h>

#include <gtest/gtest.h>

#include <algorithm>
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
  // lapmesh's kernels for V^T W and (as a fused pass with only its subtraction) W - V C with W of 1
  // to 8 columns, in every build (the baseline and, where the CPU has them, AVX2 + FMA and
  // AVX-512): every width, column counts that leave every remainder of the groups of 8, 4, 2 and
  // 1 columns, heights around the row panels (256 rows) and others, and slices with outer strides
  // whose neighbouring columns must stay untouched.
  using Eigen::Index;
  using Eigen::MatrixXd;
  namespace k = lapmesh::internal::thin_kernels;
  using Product = void (*)(k::Columns, Index, Index, k::Columns, Index, double*, Index);
  using Fused = void (*)(const k::Fused_pass&);
  std::vector<std::pair<Product, Fused>> builds = {{k::product_tn_baseline, k::fused_baseline}};
#ifdef LAPMESH_THIN_PRODUCTS_AVX2
  if(k::use_avx2()) builds.emplace_back(k::product_tn_avx2, k::fused_avx2);
  if(k::use_avx512()) builds.emplace_back(k::product_tn_avx512, k::fused_avx512);
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

          Index lanes;
          std::vector<double> coefficients;
          k::Fused_pass subtract = lapmesh::internal::fused_pass(big_w.middleCols(1, b), big_w.data() + n, n, lanes);
          subtract.Va = {V.data(), V.outerStride()};
          subtract.ma = m;
          subtract.all_coefficients = lapmesh::internal::in_lanes(C_ref, lanes, coefficients);
          build.second(subtract);
          const MatrixXd W_ref = w_before.middleCols(1, b) - V * C_ref;
          ASSERT_LE((big_w.middleCols(1, b) - W_ref).cwiseAbs().maxCoeff(), tolerance) << n << " " << m << " " << b;
          EXPECT_TRUE(big_w.col(0) == w_before.col(0));
          EXPECT_TRUE(big_w.col(b + 1) == w_before.col(b + 1));
          ++cases;
        }
  EXPECT_EQ(cases, int(builds.size()) * 7 * 10 * 8);

  // The entry point that the block Lanczos calls, on Eigen blocks.
  const MatrixXd V = MatrixXd::Random(1000, 37), W = MatrixXd::Random(1000, 6);
  MatrixXd C;
  lapmesh::internal::thin_product_tn(V, W, C);
  ASSERT_EQ(C.rows(), 37);
  ASSERT_EQ(C.cols(), 6);
  EXPECT_LE((C - V.transpose() * W).cwiseAbs().maxCoeff(), 1e-12);
}
#endif

TEST(BlockLanczos, FusedPassesEqualEigenProducts)
{
  // The three fused passes of a block step against Eigen's products: every block width (those past
  // thin_block_max_columns take the products one at a time), heights around the row panels,
  // slices with outer strides whose neighbouring columns must stay untouched, and the last pass
  // writing into another slice, as it writes the new block into the basis.
  using Eigen::Index;
  using Eigen::MatrixXd;
  int cases = 0;
  for(const Index n : {1, 5, 255, 257, 600})
    for(const Index m : {1, 3, 8, 9, 14})
      for(Index b = 1; b <= lapmesh::internal::thin_block_max_columns + 2; ++b) {
        const MatrixXd big_v = MatrixXd::Random(n, m + 3);
        const auto Va = big_v.middleCols(1, m);
        const Index local_columns = std::min<Index>(m, 2);
        const auto Vl = big_v.middleCols(1 + m - local_columns, local_columns);
        const MatrixXd Cl = MatrixXd::Random(local_columns, b), Cg = MatrixXd::Random(m, b);
        const double tolerance = 1e-13 * double(n + m);
        MatrixXd big_w = MatrixXd::Random(n, b + 2);
        const MatrixXd w_before = big_w;
        auto W = big_w.middleCols(1, b);
        const auto untouched = [&](const MatrixXd& now, const MatrixXd& before, Index last) {
          return now.col(0) == before.col(0) && now.col(last) == before.col(last);
        };

        MatrixXd product;
        lapmesh::internal::subtract_then_product_tn(Vl, Cl, W, Va, product);
        const MatrixXd W1 = w_before.middleCols(1, b) - Vl * Cl;
        ASSERT_LE((MatrixXd(W) - W1).cwiseAbs().maxCoeff(), tolerance) << n << " " << m << " " << b;
        ASSERT_EQ(product.rows(), m);
        ASSERT_EQ(product.cols(), b);
        ASSERT_LE((product - Va.transpose() * W1).cwiseAbs().maxCoeff(), tolerance) << n << " " << m << " " << b;

        MatrixXd gram;
        lapmesh::internal::subtract_then_gram(Va, Cg, W, gram);
        const MatrixXd W2 = W1 - Va * Cg;
        ASSERT_LE((MatrixXd(W) - W2).cwiseAbs().maxCoeff(), tolerance) << n << " " << m << " " << b;
        ASSERT_LE((gram - W2.transpose() * W2).cwiseAbs().maxCoeff(), tolerance * W2.squaredNorm())
          << n << " " << m << " " << b;

        const MatrixXd F = MatrixXd::Random(b, b);
        lapmesh::internal::multiply_then_gram(W, F, W, &gram);  // in place
        const MatrixXd W3 = W2 * F;
        ASSERT_LE((MatrixXd(W) - W3).cwiseAbs().maxCoeff(), tolerance * (1 + W2.cwiseAbs().maxCoeff()));
        ASSERT_LE((gram - W3.transpose() * W3).cwiseAbs().maxCoeff(), tolerance * (1 + W3.squaredNorm()));
        EXPECT_TRUE(untouched(big_w, w_before, b + 1));

        MatrixXd big_out = MatrixXd::Random(n, b + 2);
        const MatrixXd out_before = big_out;
        lapmesh::internal::multiply_then_gram(W, F, big_out.middleCols(1, b), nullptr);
        ASSERT_LE((big_out.middleCols(1, b) - W3 * F).cwiseAbs().maxCoeff(),
                  tolerance * (1 + W3.cwiseAbs().maxCoeff()) * (1 + F.cwiseAbs().maxCoeff()));
        EXPECT_TRUE(untouched(big_out, out_before, b + 1));
        ++cases;
      }
  EXPECT_EQ(cases, 5 * 5 * int(lapmesh::internal::thin_block_max_columns + 2));
}

#ifdef LAPMESH_THIN_PRODUCTS
TEST(BlockLanczos, FusedKernelBuildsEqualEigenProducts)
{
  // Every build of the fused kernel (the baseline and, where the CPU has them, AVX2 + FMA and
  // AVX-512) with every part of a pass switched on at once: W -= Vl Cl + Va Cg, the product
  // Va^T W, W = W F, the Gram matrix, the result written to another slice.
  using Eigen::Index;
  using Eigen::MatrixXd;
  namespace k = lapmesh::internal::thin_kernels;
  std::vector<void (*)(const k::Fused_pass&)> builds = {k::fused_baseline};
#ifdef LAPMESH_THIN_PRODUCTS_AVX2
  if(k::use_avx2()) builds.push_back(k::fused_avx2);
  if(k::use_avx512()) builds.push_back(k::fused_avx512);
#endif
  int cases = 0;
  for(const auto build : builds)
    for(const Index n : {1, 255, 257, 600})
      for(const Index m : {1, 7, 9})
        for(Index b = 1; b <= lapmesh::internal::thin_block_max_columns; ++b) {
          const MatrixXd V = MatrixXd::Random(n, m + 1), W = MatrixXd::Random(n, b);
          MatrixXd product(m, b), gram(b, b), out = MatrixXd::Zero(n, b);
          Index lanes;
          k::Fused_pass p = lapmesh::internal::fused_pass(W, out.data(), n, lanes);
          const MatrixXd Cl = MatrixXd::Random(1, b), Cg = MatrixXd::Random(m, b);
          MatrixXd F = MatrixXd::Zero(lanes, lanes);
          F.topLeftCorner(b, b).setRandom();
          std::vector<double> local, all, factor;
          p.Vl = {V.data() + m * n, n};  // the last column
          p.ml = 1;
          p.local_coefficients = lapmesh::internal::in_lanes(Cl, lanes, local);
          p.Va = {V.data(), n};
          p.ma = m;
          p.all_coefficients = lapmesh::internal::in_lanes(Cg, lanes, all);
          p.product = product.data();
          p.ldp = m;
          p.factor = lapmesh::internal::in_lanes(F, lanes, factor);
          p.gram = gram.data();
          build(p);
          const MatrixXd W1 = W - V.rightCols(1) * Cl - V.leftCols(m) * Cg;
          const MatrixXd W2 = W1 * F.topLeftCorner(b, b);
          const double tolerance = 1e-13 * double(n + m);
          ASSERT_LE((product - V.leftCols(m).transpose() * W1).cwiseAbs().maxCoeff(), tolerance * (1 + m));
          ASSERT_LE((out - W2).cwiseAbs().maxCoeff(), tolerance * (1 + W1.cwiseAbs().maxCoeff()));
          ASSERT_LE((gram - W2.transpose() * W2).cwiseAbs().maxCoeff(), tolerance * (1 + W2.squaredNorm()));
          ++cases;
        }
  EXPECT_EQ(cases, int(builds.size()) * 4 * 3 * int(lapmesh::internal::thin_block_max_columns));
}
#endif
