// Smoothing benchmarks: 10 implicit iterations with re-assembly (100k, 250k, 1M vertices)
// and 10 explicit iterations (operator built once, as the public libraries do, and rebuilt) on 1M,
// single- and multi-threaded, and the explicit stability bound's Lanczos estimate. Meshes:
// generated tori (closed, genus 1) and Loop-subdivided scans from CGAL's data set, scaled to unit
// area (test_arrays).
// Counters split the time into assembly, symbolic analysis, numeric factorisation and solves.
//
//   smoothing_benchmark --benchmark_filter=Implicit/250
#include "test_helpers.h"

#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/shapes.h>

#include <CGAL/Eigen_solver_traits.h>
#include <CGAL/Polygon_mesh_processing/smooth_shape.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/subdivision_method_3.h>

#include <benchmark/benchmark.h>

#include <map>

namespace {

using Mesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;

struct Arrays
{
  lapmesh::internal::Mesh_topology topology;
  /// The corner incidence alone, on which the explicit scheme with a fixed cotangent operator
  /// builds its operator's rows, as the CGAL front end hands it (assembles_operator_by_rows()).
  lapmesh::internal::Mesh_topology incidence;
  lapmesh::internal::Positions positions;
};

// Test meshes, scaled to unit area. id >= 100: an nu x nv torus of id thousand vertices with
// ~square cells (nu / nv = R / r = 2.5): a regular grid, the hard case for AMD ordering.
// id 1-3: scans from CGAL's data set, Loop-subdivided, closer to the subdivided armadillo
// that the public libraries are usually timed on: 1 armadillo + 1 Loop step (104k vertices), 2 refined_elephant + 1 step (178k),
// 3 armadillo + 2 steps (416k). (man + 2 steps, 280k, is not used: its thin fingers collapse
// into zero-area faces within 10 steps of one mean edge length squared.)
const Arrays& test_arrays(int id)
{
  static std::map<int, Arrays> cache;
  auto it = cache.find(id);
  if(it != cache.end()) return it->second;
  lapmesh::Triangle_soup soup;
  if(id >= 100) {
    const int nv = int(std::lround(std::sqrt(id * 1000.0 / 2.5))), nu = int(std::lround(id * 1000.0 / nv));
    soup = lapmesh::torus(nu, nv, 1.0, 0.4);
  } else {
    Mesh m;
    lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh(id == 2 ? "refined_elephant.off" : "armadillo.off"), m);
    CGAL::Subdivision_method_3::Loop_subdivision(m, CGAL::parameters::number_of_iterations(id == 3 ? 2 : 1));
    for(auto v : vertices(m)) soup.points.push_back({m.point(v).x(), m.point(v).y(), m.point(v).z()});
    for(auto f : faces(m)) {
      std::array<int, 3> t;
      int k = 0;
      for(auto v : vertices_around_face(halfedge(f, m), m)) t[std::size_t(k++)] = int(v.idx());
      soup.triangles.push_back(t);
    }
  }
  Arrays a;
  lapmesh::internal::Working_array<lapmesh::internal::Index> tris;
  for(const auto& t : soup.triangles) tris.insert(tris.end(), t.begin(), t.end());
  a.incidence = lapmesh::internal::build_corner_incidence(lapmesh::internal::Index(soup.points.size()), tris);
  a.topology = lapmesh::internal::build_topology(lapmesh::internal::Index(soup.points.size()), std::move(tris));
  a.positions.resize(Eigen::Index(soup.points.size()), 3);
  for(std::size_t i = 0; i < soup.points.size(); ++i)
    a.positions.row(Eigen::Index(i)) << soup.points[i][0], soup.points[i][1], soup.points[i][2];
  lapmesh::Laplacian_pencil pencil;
  lapmesh::internal::assemble_pencil(a.topology, a.positions, lapmesh::Laplacian::cotangent,
                                     lapmesh::Vertex_area::barycentric, false, pencil);
  a.positions /= std::sqrt(pencil.mass.sum());
  return cache.emplace(id, std::move(a)).first->second;
}

void run(benchmark::State& state, lapmesh::Smoothing_scheme scheme, bool fixed_operator, bool reuse = false)
{
  const Arrays& a = test_arrays(int(state.range(0)));
  const bool parallel = state.range(1) != 0;
  lapmesh::internal::Smoothing_settings s;
  s.scheme = scheme;
  s.iterations = 10;
  s.fixed_operator = fixed_operator;
  s.parallel = parallel;
  s.reuse_factorization = reuse;
  const double h = lapmesh::internal::mean_edge_length(a.topology, a.positions);
  s.lambda = scheme == lapmesh::Smoothing_scheme::explicit_euler ? 0.1 * h * h : 1.0 * h * h;
  lapmesh::Smoothing_report total;
  int runs = 0;
  for(auto _ : state) {
    state.PauseTiming();
    lapmesh::internal::Positions P = a.positions;
    state.ResumeTiming();
    const auto r = lapmesh::internal::smooth_positions(
      lapmesh::internal::assembles_operator_by_rows(s) ? a.incidence : a.topology, P, {}, s);
    benchmark::DoNotOptimize(P.data());
    total.assembly_seconds += r.assembly_seconds;
    total.analysis_seconds += r.analysis_seconds;
    total.factorization_seconds += r.factorization_seconds;
    total.solve_seconds += r.solve_seconds;
    total.factorizations += r.factorizations;
    total.cg_iterations += r.cg_iterations;
    ++runs;
  }
  state.counters["vertices"] = double(a.topology.num_vertices);
  state.counters["assembly_s"] = total.assembly_seconds / runs;
  state.counters["analysis_s"] = total.analysis_seconds / runs;
  state.counters["factor_s"] = total.factorization_seconds / runs;
  state.counters["solve_s"] = total.solve_seconds / runs;
  state.counters["factorizations"] = total.factorizations / runs;
  state.counters["cg_iterations"] = total.cg_iterations / runs;
}

void BM_Implicit(benchmark::State& state) { run(state, lapmesh::Smoothing_scheme::implicit_euler, false); }
void BM_ImplicitReuse(benchmark::State& state) { run(state, lapmesh::Smoothing_scheme::implicit_euler, false, true); }
void BM_ExplicitFixedOperator(benchmark::State& state) { run(state, lapmesh::Smoothing_scheme::explicit_euler, true); }
void BM_ExplicitRebuilt(benchmark::State& state) { run(state, lapmesh::Smoothing_scheme::explicit_euler, false); }

// The explicit scheme's stability bound (the Lanczos estimate of the top eigenvalue of -L on
// every vertex, barycentric mass). Arg 1: 0 uniform, 1 cotangent; arg 2: 0 runs to the residual
// tolerance or the cap, 1 also stops where the estimate stalls (the default).
void BM_StabilityBound(benchmark::State& state)
{
  using namespace lapmesh::internal;
  const Arrays& a = test_arrays(int(state.range(0)));
  const lapmesh::Laplacian laplacian = state.range(1) == 0 ? lapmesh::Laplacian::uniform : lapmesh::Laplacian::cotangent;
  lapmesh::Laplacian_pencil pencil;
  assemble_pencil(a.topology, a.positions, laplacian, lapmesh::Vertex_area::barycentric, false, pencil);
  const std::vector<char> free_mask(std::size_t(a.topology.num_vertices), 1);
  Top_eigenvalue_stopping stop;
  if(state.range(2) == 0) stop.stall_tol = 0;
  Top_eigenvalue_estimate estimate;
  for(auto _ : state) estimate = top_eigenvalue_of_minus_laplacian(pencil, free_mask, false, stop);
  state.counters["vertices"] = double(a.topology.num_vertices);
  state.counters["products"] = estimate.products;
  state.counters["converged"] = estimate.converged;
  state.counters["mu_max"] = estimate.value;
}

// The public libraries' implicit step (libigl, pmp-library and CGAL's smooth_shape
// with an LDL^T solver alike), as a same-run baseline: assemble, then a complete Eigen
// SimplicialLDLT (ordering included) of M - lambda S every iteration, and one 3-column solve.
// It is given lapmesh's assembly (faster than their triplet builds), so the ratio is conservative.
void BM_ImplicitPublicStyle(benchmark::State& state)
{
  const Arrays& a = test_arrays(int(state.range(0)));
  const double h = lapmesh::internal::mean_edge_length(a.topology, a.positions);
  const double lambda = 1.0 * h * h;
  for(auto _ : state) {
    state.PauseTiming();
    lapmesh::internal::Positions P = a.positions;
    state.ResumeTiming();
    for(int it = 0; it < 10; ++it) {
      lapmesh::Laplacian_pencil pencil;
      lapmesh::internal::assemble_pencil(a.topology, P, lapmesh::Laplacian::cotangent, lapmesh::Vertex_area::barycentric,
                                         false, pencil);
      Eigen::SparseMatrix<double> A = -lambda * pencil.stiffness;
      A.diagonal() += pencil.mass;
      Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
      if(ldlt.info() != Eigen::Success) state.SkipWithError("factorisation failed");
      const Eigen::MatrixXd X = ldlt.solve(pencil.mass.asDiagonal() * Eigen::MatrixXd(P));
      P = X;
    }
    benchmark::DoNotOptimize(P.data());
  }
  state.counters["vertices"] = double(a.topology.num_vertices);
}

// Public API on a Surface_mesh (extraction and write-back included).
void BM_ImplicitSurfaceMesh(benchmark::State& state)
{
  const int thousands = int(state.range(0));
  const int nv = int(std::lround(std::sqrt(thousands * 1000.0 / 2.5))), nu = int(std::lround(thousands * 1000.0 / nv));
  Mesh input;
  lapmesh::make_mesh(lapmesh::torus(nu, nv, 1.0, 0.4), input);
  const double lambda = lapmesh::scale_free_time_step(input, 1.0);
  for(auto _ : state) {
    state.PauseTiming();
    Mesh m = input;
    state.ResumeTiming();
    lapmesh::smooth_laplacian_implicit(m, lambda, CGAL::parameters::number_of_iterations(10));
  }
}

// Conformal flow against CGAL's smooth_shape on the same closed torus, time and iterations
// (10): CGAL's time t is lapmesh's lambda = 4t (CGAL's mass is half the barycentric area and
// its weights are twice lapmesh's C), and CGAL rescales to the volume, as restore_volume does.
// Arg 1: 0 lapmesh (default solver), 1 lapmesh with Eigen LDL^T, 2 CGAL with Eigen
// SimplicialLDLT traits, 3 CGAL with its default BiCGSTAB + ILUT.
void BM_ConformalVsSmoothShape(benchmark::State& state)
{
  const int thousands = int(state.range(0));
  const int nv = int(std::lround(std::sqrt(thousands * 1000.0 / 2.5))), nu = int(std::lround(thousands * 1000.0 / nv));
  Mesh input;
  lapmesh::make_mesh(lapmesh::torus(nu, nv, 1.0, 0.4), input);
  const double lambda = lapmesh::scale_free_time_step(input, 1.0), t = lambda / 4;
  using Ldlt = CGAL::Eigen_solver_traits<Eigen::SimplicialLDLT<CGAL::Eigen_sparse_matrix<double>::EigenType>>;
  for(auto _ : state) {
    state.PauseTiming();
    Mesh m = input;
    state.ResumeTiming();
    switch(state.range(1)) {
      case 0: lapmesh::smooth_conformal_flow(m, lambda, lapmesh::parameters::restore_volume(true).number_of_iterations(10)); break;
      case 1:
        lapmesh::smooth_conformal_flow(
          m, lambda, lapmesh::parameters::use_cholmod(false, lapmesh::parameters::restore_volume(true)).number_of_iterations(10));
        break;
      case 2:
        CGAL::Polygon_mesh_processing::smooth_shape(m, t, CGAL::parameters::number_of_iterations(10).sparse_linear_solver(Ldlt()));
        break;
      default: CGAL::Polygon_mesh_processing::smooth_shape(m, t, CGAL::parameters::number_of_iterations(10));
    }
  }
}

} // namespace

BENCHMARK(BM_ConformalVsSmoothShape)->ArgsProduct({{43, 100}, {0, 1, 2, 3}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_Implicit)->ArgsProduct({{1, 2, 3, 100, 250, 1000}, {0, 1}})->Unit(benchmark::kMillisecond)->Iterations(1)->Repetitions(1);
BENCHMARK(BM_ImplicitReuse)->ArgsProduct({{1, 2, 3, 100, 250, 1000}, {0}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_ImplicitPublicStyle)->Arg(1)->Arg(2)->Arg(3)->Arg(100)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_ImplicitSurfaceMesh)->Arg(250)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_ExplicitFixedOperator)->ArgsProduct({{1000}, {0, 1}})->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_StabilityBound)->ArgsProduct({{1, 3, 250}, {0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_ExplicitRebuilt)->ArgsProduct({{1000}, {0, 1}})->Unit(benchmark::kMillisecond)->Iterations(3);

BENCHMARK_MAIN();
