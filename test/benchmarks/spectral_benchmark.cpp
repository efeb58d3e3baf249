// Spectral basis timings (doc/spectral.md): lapmesh's solver (shift-invert Lanczos on the
// standardised pencil, SimplicialLLT or CHOLMOD) against Spectra's SymGEigsShiftSolver
// (ShiftInvert mode) with Eigen's SimplicialLDLT (the usual public set-up) and with Spectra's own
// SymShiftInvert operator (a SparseLU), on the same pencils, in one run so that ratios are
// comparable; and, on meshes of copies, each class of copies solved once against the whole pencil.
// Meshes: CGAL's data set, Loop-subdivided to reach the sizes (closed or with boundary).
//   ./spectral_benchmark --benchmark_filter=...   (peak memory: /usr/bin/time -v, one filter at a time)
#include "test_helpers.h"

#include <lapmesh/io.h>
#include <lapmesh/spectral_reconstruction.h>

#include <CGAL/subdivision_method_3.h>

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/MatOp/SymShiftInvert.h>
#include <Spectra/SymGEigsShiftSolver.h>

#include <Eigen/SparseCholesky>

#include <benchmark/benchmark.h>

#include <chrono>
#include <limits>
#include <map>
#include <stdexcept>

namespace {

struct Case
{
  const char* file;
  int loop_steps;
};

// 0: ChineseDragon 10k; 1: armadillo x1 Loop ~104k; 2: man x2 Loop ~280k; 3: refined_elephant 44k;
// 4: the bunny00 scan, 37.7k; 5: mannequin-devil x1 Loop ~52k; 6: camel x1 Loop ~39k (the vertex
// counts are printed as the counter n).
const Case cases[] = {{"ChineseDragon-10kv.off", 0}, {"armadillo.off", 1},       {"man.off", 2},
                      {"refined_elephant.off", 0},   {"bunny00.off", 0},         {"mannequin-devil.off", 1},
                      {"camel.off", 1}};

lapmesh_test::Mesh case_mesh(int id)
{
  lapmesh_test::Mesh m;
  lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh(cases[id].file), m);
  if(cases[id].loop_steps > 0)
    CGAL::Subdivision_method_3::Loop_subdivision(m, CGAL::parameters::number_of_iterations(cases[id].loop_steps));
  return m;
}
const lapmesh::Laplacian_pencil& pencil(int id)
{
  static std::map<int, lapmesh::Laplacian_pencil> cache;
  auto it = cache.find(id);
  if(it != cache.end()) return it->second;
  const lapmesh_test::Mesh m = case_mesh(id);
  // Scale to unit area, as the public comparisons do.
  auto p = lapmesh::laplacian_pencil(m);
  const double area = p.mass.sum();
  p.stiffness *= 1.0;  // C is scale-invariant
  p.mass /= area;
  return cache.emplace(id, std::move(p)).first->second;
}

void BM_lapmesh(benchmark::State& state, lapmesh::Sparse_cholesky chol, lapmesh::Krylov_method method)
{
  const auto& p = pencil(int(state.range(0)));
  const int k = int(state.range(1));
  lapmesh::Spectral_options opt;
  opt.cholesky = chol;
  opt.method = method;
  long long ops = 0;
  double lambda_last = 0;
  for(auto _ : state) {
    const auto b = lapmesh::Spectral_basis::from_pencil(p, k, opt);
    ops = b.operations();
    lambda_last = b.eigenvalues()[k - 1];
    benchmark::DoNotOptimize(b.eigenvectors().data());
  }
  state.counters["n"] = double(p.mass.size());
  state.counters["solves"] = double(ops);
  state.counters["lambda_k-1"] = lambda_last;
}

void BM_lapmesh_nocheck(benchmark::State& state)
{
  const auto& p = pencil(int(state.range(0)));
  const int k = int(state.range(1));
  lapmesh::Spectral_options opt;
  opt.check_completeness = false;
  opt.extra = 0;
  for(auto _ : state) {
    const auto b = lapmesh::Spectral_basis::from_pencil(p, k, opt);
    benchmark::DoNotOptimize(b.eigenvectors().data());
  }
  state.counters["n"] = double(p.mass.size());
}

/// (A - sigma B)^-1 by Eigen's SimplicialLDLT (AMD ordering): the operator of the usual public
/// set-up of Spectra's SymGEigsShiftSolver in ShiftInvert mode.
class Simplicial_ldlt_shift_invert
{
public:
  using Scalar = double;
  Simplicial_ldlt_shift_invert(const Eigen::SparseMatrix<double>& A, const Eigen::SparseMatrix<double>& B) : m_A(A), m_B(B) {}
  Eigen::Index rows() const { return m_A.rows(); }
  Eigen::Index cols() const { return m_A.cols(); }
  void set_shift(double sigma)
  {
    m_ldlt.compute(Eigen::SparseMatrix<double>(m_A - sigma * m_B));
    if(m_ldlt.info() != Eigen::Success) throw std::runtime_error("SimplicialLDLT of A - sigma B failed");
  }
  void perform_op(const double* x, double* y) const
  {
    Eigen::Map<Eigen::VectorXd>(y, rows()).noalias() = m_ldlt.solve(Eigen::Map<const Eigen::VectorXd>(x, rows()));
  }

private:
  const Eigen::SparseMatrix<double>& m_A;
  const Eigen::SparseMatrix<double>& m_B;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> m_ldlt;
};

/// Spectra's generalized shift-invert, k pairs, ncv = max(2k + 1, 20), tolerance 1e-10, with the
/// shift-invert operator Op: Eigen's SimplicialLDLT (the usual public set-up) or Spectra's own
/// SymShiftInvert (a SparseLU).
template <typename Op>
void BM_plain_spectra(benchmark::State& state)
{
  const auto& p = pencil(int(state.range(0)));
  const int k = int(state.range(1));
  const Eigen::SparseMatrix<double> A = -p.stiffness;
  Eigen::SparseMatrix<double> B(p.mass.size(), p.mass.size());
  B.reserve(Eigen::VectorXi::Constant(p.mass.size(), 1));
  for(Eigen::Index i = 0; i < p.mass.size(); ++i) B.insert(i, i) = p.mass[i];
  double lambda_last = 0;
  long long ops = 0;
  for(auto _ : state) {
    using BOpType = Spectra::SparseSymMatProd<double>;
    Op op(A, B);
    BOpType bop(B);
    const double sigma = -1e-2 / p.mass.sum();
    Spectra::SymGEigsShiftSolver<Op, BOpType, Spectra::GEigsMode::ShiftInvert> eigs(
      op, bop, k, std::min<Eigen::Index>(p.mass.size(), std::max(2 * k + 1, 20)), sigma);
    eigs.init();
    eigs.compute(Spectra::SortRule::LargestMagn, 1000, 1e-10, Spectra::SortRule::SmallestAlge);
    if(eigs.info() != Spectra::CompInfo::Successful) state.SkipWithError("not converged");
    lambda_last = eigs.eigenvalues()[k - 1];
    ops = eigs.num_operations();
    benchmark::DoNotOptimize(eigs.eigenvectors().data());
  }
  state.counters["n"] = double(p.mass.size());
  state.counters["solves"] = double(ops);
  state.counters["lambda_k-1"] = lambda_last;
}

void sizes(benchmark::internal::Benchmark* b)
{
  b->Args({0, 30})->Args({1, 30})->Args({2, 30})->Args({3, 100})->Args({3, 300})->Args({0, 1000});
  b->Unit(benchmark::kMillisecond)->Iterations(1)->Repetitions(1);
}

} // namespace

// Default: block Lanczos on CHOLMOD; then each of the two choices changed alone.
#ifdef LAPMESH_HAS_CHOLMOD
BENCHMARK_CAPTURE(BM_lapmesh, block_cholmod, lapmesh::Sparse_cholesky::cholmod, lapmesh::Krylov_method::block_lanczos)
  ->Apply(sizes);
BENCHMARK_CAPTURE(BM_lapmesh, spectra_cholmod, lapmesh::Sparse_cholesky::cholmod, lapmesh::Krylov_method::spectra)
  ->Apply(sizes);
#endif
BENCHMARK_CAPTURE(BM_lapmesh, block_simplicial, lapmesh::Sparse_cholesky::simplicial,
                  lapmesh::Krylov_method::block_lanczos)
  ->Apply(sizes);
BENCHMARK_CAPTURE(BM_lapmesh, spectra_simplicial, lapmesh::Sparse_cholesky::simplicial, lapmesh::Krylov_method::spectra)
  ->Apply(sizes);
BENCHMARK(BM_lapmesh_nocheck)->Apply(sizes);
BENCHMARK_TEMPLATE(BM_plain_spectra, Simplicial_ldlt_shift_invert)->Apply(sizes);
BENCHMARK_TEMPLATE(BM_plain_spectra, Spectra::SymShiftInvert<double, Eigen::Sparse, Eigen::Sparse>)->Apply(sizes);

// k = 100 and 300 on three more meshes of about 50k vertices (a scan among them): the default
// against the usual public set-up only.
void more_meshes(benchmark::internal::Benchmark* b)
{
  b->ArgsProduct({{4, 5, 6}, {100, 300}});
  b->Unit(benchmark::kMillisecond)->Iterations(1)->Repetitions(1);
}
#ifdef LAPMESH_HAS_CHOLMOD
BENCHMARK_CAPTURE(BM_lapmesh, block_cholmod_more, lapmesh::Sparse_cholesky::cholmod, lapmesh::Krylov_method::block_lanczos)
  ->Apply(more_meshes);
#endif
BENCHMARK_TEMPLATE(BM_plain_spectra, Simplicial_ldlt_shift_invert)->Name("BM_plain_spectra_more")->Apply(more_meshes);

// Where the time goes: ordering + symbolic analysis, numeric factorisation, one solve pair.
void BM_breakdown(benchmark::State& state)
{
  const auto& p = pencil(int(state.range(0)));
  Eigen::SparseMatrix<double> K = -p.stiffness;
  K.diagonal() += 1e-2 / p.mass.sum() * p.mass;
  double t_analyse = 0, t_factor = 0, t_solve = 0, nnz = 0;
  for(auto _ : state) {
    using clock = std::chrono::steady_clock;
    Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
    auto t0 = clock::now();
    llt.analyzePattern(K);
    auto t1 = clock::now();
    llt.factorize(K);
    auto t2 = clock::now();
    Eigen::VectorXd b = Eigen::VectorXd::Ones(K.rows()), x;
    for(int i = 0; i < 10; ++i) x = llt.solve(b);
    auto t3 = clock::now();
    t_analyse = std::chrono::duration<double>(t1 - t0).count();
    t_factor = std::chrono::duration<double>(t2 - t1).count();
    t_solve = std::chrono::duration<double>(t3 - t2).count() / 10;
    nnz = double(llt.matrixL().nestedExpression().nonZeros());
  }
  state.counters["n"] = double(p.mass.size());
  state.counters["analyse_ms"] = 1e3 * t_analyse;
  state.counters["factor_ms"] = 1e3 * t_factor;
  state.counters["solve_ms"] = 1e3 * t_solve;
  state.counters["nnz_L"] = nnz;
}
// Times Spectral_basis::from_pencil on `p` for k pairs with `opt`.
void time_basis(benchmark::State& state, const lapmesh::Laplacian_pencil& p, Eigen::Index k,
                const lapmesh::Spectral_options& opt)
{
  long long ops = 0;
  for(auto _ : state) {
    const auto b = lapmesh::Spectral_basis::from_pencil(p, k, opt);
    ops = b.operations();
  }
  state.counters["n"] = double(p.mass.size());
  state.counters["solves"] = double(ops);
}
// The same on case range(0) for k = range(1).
void time_basis(benchmark::State& state, const lapmesh::Spectral_options& opt)
{
  time_basis(state, pencil(int(state.range(0))), state.range(1), opt);
}
// Krylov basis size: ncv_factor = range(2) / 10.
void BM_ncv(benchmark::State& state)
{
  lapmesh::Spectral_options opt;
  opt.ncv_factor = double(state.range(2)) / 10;
  time_basis(state, opt);
}
// Block Lanczos: block size range(2), basis size ncv_factor = range(3) / 10, one run.
void BM_block(benchmark::State& state)
{
  lapmesh::Spectral_options opt;
  opt.block_size = int(state.range(2));
  opt.ncv_factor = double(state.range(3)) / 10;
  opt.band_size = 0;
  time_basis(state, opt);
}
// Bands of range(2) pairs.
void BM_banded(benchmark::State& state)
{
  lapmesh::Spectral_options opt;
  opt.band_size = int(state.range(2));
  time_basis(state, opt);
}
// A mesh of copies (an assembly's repeated parts): case range(0) placed range(1) times side by
// side, not scaled, k = range(2); each class of copies solved once (range(3) = 1, the default)
// or the whole pencil (0).
const lapmesh::Laplacian_pencil& copies_pencil(int id, int copies)
{
  static std::map<std::pair<int, int>, lapmesh::Laplacian_pencil> cache;
  auto it = cache.find({id, copies});
  if(it != cache.end()) return it->second;
  const lapmesh_test::Mesh one = case_mesh(id);
  lapmesh_test::Mesh all;
  double low = std::numeric_limits<double>::infinity(), high = -low;
  for(const auto v : one.vertices()) {
    low = std::min(low, one.point(v).x());
    high = std::max(high, one.point(v).x());
  }
  for(int c = 0; c < copies; ++c) {
    lapmesh_test::Mesh part = one;
    for(const auto v : part.vertices()) {
      const lapmesh_test::Point& q = part.point(v);
      part.point(v) = lapmesh_test::Point(q.x() + 1.5 * (high - low) * c, q.y(), q.z());
    }
    all.join(part);
  }
  return cache.emplace(std::make_pair(id, copies), lapmesh::laplacian_pencil(all)).first->second;
}
void BM_copies(benchmark::State& state)
{
  lapmesh::Spectral_options opt;
  opt.solve_copies_once = state.range(3) != 0;
  time_basis(state, copies_pencil(int(state.range(0)), int(state.range(1))), state.range(2), opt);
}
BENCHMARK(BM_copies)->ArgsProduct({{4}, {2}, {30, 100}, {1, 0}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_copies)->ArgsProduct({{0}, {12}, {30, 100}, {1, 0}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_block)->ArgsProduct({{2}, {30}, {2, 3, 4, 6}, {20, 25, 30}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_block)->ArgsProduct({{3}, {100}, {4, 6, 8}, {15, 20, 25}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_block)->ArgsProduct({{3}, {300}, {4, 8}, {15, 17, 20}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_ncv)->ArgsProduct({{1, 3}, {30, 100}, {12, 15, 20, 30}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_banded)->ArgsProduct({{3}, {100, 300}, {25, 40, 60}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_banded)->ArgsProduct({{0}, {1000}, {40, 60, 100}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_banded)->ArgsProduct({{1, 2}, {30}, {15, 20}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_breakdown)->Arg(0)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond)->Iterations(1);

BENCHMARK_MAIN();
