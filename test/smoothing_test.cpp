// Smoothing: mean curvature flow on a sphere against r(t)^2 = r0^2 - 4t, the explicit
// stability bound against a dense eigen-solve, implicit steps against dense Dirichlet solves,
// bitwise-fixed constraints, volume restoration, denoising a noisy sphere, the free block in
// the solver's order against the block in index order and Eigen's LDL^T, the release of memory
// between steps, and the command line's refusal of bad lambda/iterations (the noise itself:
// noise_test.cpp).
#include "test_helpers.h"

#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/noise.h>
#include <lapmesh/io.h>
#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/spd_solver.h>
#include <lapmesh/internal/stability_bound.h>
#include <lapmesh/internal/subnormals.h>

#include <CGAL/Eigen_solver_traits.h>
#include <CGAL/Exact_rational.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/smooth_shape.h>

#include <Eigen/Dense>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <numeric>
#include <random>
#include <limits>
#include <filesystem>
#include <set>
#include <fstream>
#include <iostream>
#include <sstream>
#include <functional>
#include <string>

using namespace lapmesh_test;
namespace LP = lapmesh::parameters;

namespace {

Mesh jittered(lapmesh::Triangle_soup soup, double amount, unsigned seed)
{
  std::mt19937_64 rng(seed);
  for(auto& p : soup.points)
    for(double& c : p) c += amount * (double(rng() >> 11) / double(1ull << 53) - 0.5);
  return to_mesh(soup);
}

double mean_squared_radius(const Mesh& m)
{
  const Eigen::MatrixXd P = positions(m);
  const Eigen::RowVector3d c = P.colwise().mean();
  double s = 0;
  for(Eigen::Index i = 0; i < P.rows(); ++i) s += (P.row(i) - c).squaredNorm();
  return s / double(P.rows());
}

// Dense reference of one implicit step with Dirichlet vertices:
// (M - lambda S)_FF X_F = M_FF P_F + lambda S_FB P_B, X_B = P_B.
Eigen::MatrixXd dense_implicit_step(const Eigen::MatrixXd& S, const Eigen::VectorXd& mass, const Eigen::MatrixXd& P,
                                    double lambda, const std::vector<bool>& fixed)
{
  const int n = int(P.rows());
  std::vector<int> F, B;
  for(int i = 0; i < n; ++i) (fixed[i] ? B : F).push_back(i);
  Eigen::MatrixXd A(F.size(), F.size()), rhs(F.size(), 3);
  for(std::size_t a = 0; a < F.size(); ++a) {
    for(std::size_t b = 0; b < F.size(); ++b) A(a, b) = -lambda * S(F[a], F[b]) + (a == b ? mass[F[a]] : 0.0);
    rhs.row(a) = mass[F[a]] * P.row(F[a]);
    for(int j : B) rhs.row(a) += lambda * S(F[a], j) * P.row(j);
  }
  const Eigen::MatrixXd X = A.ldlt().solve(rhs);
  Eigen::MatrixXd out = P;
  for(std::size_t a = 0; a < F.size(); ++a) out.row(F[a]) = X.row(a);
  return out;
}

// A soup as the smoothing engine's arrays (triangles, positions), each coordinate moved by a
// uniform amount in [-amount, amount) drawn from `seed`.
struct Engine_arrays
{
  lapmesh::internal::Index n = 0;
  lapmesh::internal::Working_array<lapmesh::internal::Index> triangles;
  lapmesh::internal::Positions positions;
};
Engine_arrays jittered_engine_arrays(lapmesh::Triangle_soup soup, double amount, unsigned seed)
{
  using lapmesh::internal::Index;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-amount, amount);
  for(auto& p : soup.points)
    for(double& x : p) x += jitter(rng);
  Engine_arrays out;
  out.n = Index(soup.points.size());
  for(const auto& f : soup.triangles) out.triangles.insert(out.triangles.end(), f.begin(), f.end());
  out.positions.resize(out.n, 3);
  for(Index i = 0; i < out.n; ++i)
    out.positions.row(i) = Eigen::RowVector3d(soup.points[i][0], soup.points[i][1], soup.points[i][2]);
  return out;
}

lapmesh::Triangle_soup bumpy_patch(int n)
{
  return lapmesh::height_field(n, [](double x, double y) { return 0.2 * std::sin(3 * x) * std::cos(2 * y); }, 0.3, 5);
}

} // namespace

TEST(Smoothing, SubnormalsAreFlushedOnlyInsideTheScope)
{
  // The factorisations of a mass-dominated smoothing system produce subnormal fill entries,
  // which Intel CPUs process on a slow path; lapmesh flushes them inside its factorisations and
  // restores the caller's floating-point state afterwards.
  volatile double tiny = 1e-300, factor = 1e-15;  // volatile: computed at run time
  const double before = tiny * factor;
  EXPECT_GT(before, 0.0);
  EXPECT_LT(before, std::numeric_limits<double>::min());  // a subnormal result
  {
    lapmesh::internal::Subnormals_flushed_scope flushed;
#ifdef LAPMESH_HAS_MXCSR
    EXPECT_EQ(tiny * factor, 0.0);
    volatile double subnormal = before;
    EXPECT_EQ(subnormal * 1.0, 0.0);  // subnormal operands read as zero
#endif
  }
  EXPECT_EQ(tiny * factor, before);
}

TEST(Smoothing, ImplicitCotangentFlowShrinksSphereLikeMeanCurvatureFlow)
{
  // x_t = L x = -2 H n with H = 1/r gives d(r^2)/dt = -4, so r(t)^2 = r0^2 - 4t.
  for(lapmesh::Vertex_area area : {lapmesh::Vertex_area::barycentric, lapmesh::Vertex_area::mixed}) {
    Mesh m = to_mesh(lapmesh::icosphere(4, 1.0));
    const double r0sq = mean_squared_radius(m);
    const double dt = 0.002;
    const int steps = 25;  // t = 0.05: r^2 falls by 0.2 (20%)
    const auto report = lapmesh::smooth_laplacian_implicit(
      m, dt, LP::vertex_area(area).number_of_iterations(steps));
    EXPECT_EQ(report.iterations, steps);
    EXPECT_EQ(report.factorizations, steps);  // rebuilt operator: refactorised every iteration
    const double expected = r0sq - 4.0 * dt * steps;
    const double got = mean_squared_radius(m);
    EXPECT_NEAR(got, expected, 0.02 * expected) << lapmesh::to_string(area);
    // The sphere stays round: every vertex at the same radius to 1%.
    const Eigen::MatrixXd P = positions(m);
    const Eigen::RowVector3d c = P.colwise().mean();
    for(Eigen::Index i = 0; i < P.rows(); ++i) ASSERT_NEAR((P.row(i) - c).squaredNorm(), got, 0.01 * got);
  }
}

#ifdef __linux__
TEST(Smoothing, TheFactorisationEmptiesTheCacheOfWorkingArraysFirst)
{
  // A cached mapping beside the factor would add to the call's peak. The sphere's arrays are far
  // below 4 MiB: the call neither takes the cached mapping nor gives one back.
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  const std::size_t bytes = std::size_t(8) << 20;
  const auto cache_some = [&] {
    lapmesh::release_working_memory();
    { lapmesh::internal::Working_array<double> freed(bytes / sizeof(double)); }
    ASSERT_EQ(lapmesh::cached_working_memory(), bytes);
  };
  Mesh m = to_mesh(lapmesh::icosphere(3, 1.0));
  cache_some();
  lapmesh::smooth_laplacian_explicit(m, 1e-6, CGAL::parameters::number_of_iterations(1));
  EXPECT_EQ(lapmesh::cached_working_memory(), bytes);  // nothing factorised
  lapmesh::smooth_laplacian_implicit(m, 1e-3, CGAL::parameters::number_of_iterations(1));
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  cache_some();
  lapmesh::smooth_laplacian_implicit(m, 1e-3, LP::use_cholmod(false).number_of_iterations(1));  // Eigen's LDL^T
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
}
#endif

// The CGAL front end gives the worker its topology to release: once the last operator is
// assembled, the corner lists and the pattern go (they are not held beside the factorisation);
// the triangles stay for shape restoration. The steps before the last keep everything, and
// the positions are those of the worker that releases nothing, to the bit.
TEST(Smoothing, TheLastFactorisationRunsWithoutTheCornerListsAndThePattern)
{
  using namespace lapmesh::internal;
  const Engine_arrays sphere = jittered_engine_arrays(lapmesh::icosphere(3), 0.01, 4);
  const Index n = sphere.n;
  const Working_array<Index>& triangles = sphere.triangles;
  const Positions& P0 = sphere.positions;

  struct Case { int iterations; bool fixed_operator, restore_volume; };
  for(const Case c : {Case{1, false, false}, Case{3, false, true}, Case{3, true, false}}) {
    Smoothing_settings s;
    s.area = lapmesh::Vertex_area::mixed;
    s.lambda = 1e-3;
    s.iterations = c.iterations;
    s.fixed_operator = c.fixed_operator;
    s.restore_volume = c.restore_volume;
    Mesh_topology kept = build_topology(n, triangles), released = build_topology(n, triangles);
    const std::size_t nonzeros = released.inner.size();
    Positions a = P0, b = P0;
    smooth_positions(kept, a, std::vector<char>(std::size_t(n), 0), s);
    std::vector<std::size_t> pattern_after_step;
    s.progress = [&](int, int) { pattern_after_step.push_back(released.inner.size()); };
    smooth_positions_releasing_topology(released, b, std::vector<char>(std::size_t(n), 0), s);
    EXPECT_EQ((a - b).norm(), 0.0) << c.iterations << " " << c.fixed_operator;
    // A rebuilt operator needs the pattern for every step but the last; a fixed one for none.
    ASSERT_EQ(pattern_after_step.size(), std::size_t(c.iterations));
    for(int it = 0; it < c.iterations; ++it)
      EXPECT_EQ(pattern_after_step[std::size_t(it)], c.fixed_operator || it + 1 == c.iterations ? 0u : nonzeros) << it;
    EXPECT_TRUE(released.corner_begin.empty() && released.vertex_corners.empty() && released.outer.empty() &&
                released.diagonal_slot.empty() && released.slot_corners.empty());
    EXPECT_TRUE(std::equal(released.triangles.begin(), released.triangles.end(), kept.triangles.begin()));
    EXPECT_EQ(released.triangles.size(), kept.triangles.size());
  }
}

// The explicit scheme on a fixed cotangent operator builds the operator's rows with their values
// on a topology of corner incidence alone (the CGAL front end's extraction): the steps, the free
// vertices and the stability bound must be those on the pattern's topology, to the bit, on a closed
// and an open mesh, with the boundary fixed or free, with constraints, and in parallel, where the
// rows are built in parts and an open mesh's parts are written again; the errors must be the same.
TEST(Smoothing, ExplicitStepsOnRowsBuiltWithTheirValuesAreThoseOnThePattern)
{
  using namespace lapmesh::internal;
  struct Case
  {
    std::string name;
    Engine_arrays mesh;
    bool fix_boundary;
  };
  std::vector<Case> cases;
  cases.push_back({"closed sphere", jittered_engine_arrays(lapmesh::icosphere(6), 0.002, 4), true});
  cases.push_back({"open patch, boundary fixed", jittered_engine_arrays(bumpy_patch(140), 0.002, 5), true});
  cases.push_back({"open patch, boundary free", jittered_engine_arrays(bumpy_patch(140), 0.002, 6), false});
  const auto settings = [](bool fix_boundary, double lambda, bool compute_bound, bool parallel) {
    Smoothing_settings s;
    s.scheme = lapmesh::Smoothing_scheme::explicit_euler;
    s.area = lapmesh::Vertex_area::mixed;
    s.fixed_operator = true;
    s.iterations = 3;
    s.lambda = lambda;
    s.fix_boundary = fix_boundary;
    s.compute_stability_bound = compute_bound;
    s.parallel = parallel;
    return s;
  };
  for(const Case& c : cases) {
    const Index n = c.mesh.n;
    std::vector<char> constrained(std::size_t(n), 0);
    for(Index i = 5; i < n; i += 11) constrained[std::size_t(i)] = 1;
    for(bool compute_bound : {false, true}) {
      // A time step well inside the Gershgorin bound, which a run with a tiny step reports: without
      // compute_stability_bound the bound stays Gershgorin's, with it Lanczos runs.
      Positions probe = c.mesh.positions;
      const double gershgorin =
        smooth_positions(build_topology(n, c.mesh.triangles), probe, constrained, settings(c.fix_boundary, 1e-12, false, false))
          .stability_bound;
      Smoothing_settings s = settings(c.fix_boundary, 0.5 * gershgorin, compute_bound, false);
      ASSERT_TRUE(assembles_operator_by_rows(s));
      Positions on_pattern = c.mesh.positions;
      const lapmesh::Smoothing_report expected = smooth_positions(build_topology(n, c.mesh.triangles), on_pattern, constrained, s);
      ASSERT_EQ(expected.stability_bound_exact, compute_bound);
      const auto check = [&](const std::string& label, bool parallel) {
        Smoothing_settings t = s;
        t.parallel = parallel;
        Mesh_topology incidence = build_corner_incidence(n, c.mesh.triangles);
        ASSERT_FALSE(incidence.has_pattern());
        Positions on_rows = c.mesh.positions;
        const lapmesh::Smoothing_report got = smooth_positions_releasing_topology(incidence, on_rows, constrained, t);
        EXPECT_TRUE(incidence.corner_begin.empty() && incidence.vertex_corners.empty()) << label;
        EXPECT_EQ(got.free_vertices, expected.free_vertices) << label;
        EXPECT_EQ(got.stability_bound, expected.stability_bound) << label;
        EXPECT_EQ(got.stability_bound_exact, expected.stability_bound_exact) << label;
        EXPECT_EQ(got.iterations, 3) << label;
        EXPECT_GT((on_rows - c.mesh.positions).cwiseAbs().maxCoeff(), 1e-6) << label;
        EXPECT_EQ((on_rows - on_pattern).cwiseAbs().maxCoeff(), 0.0) << label;
      };
      const std::string label = c.name + (compute_bound ? ", Lanczos bound" : ", Gershgorin bound");
      check(label, false);
#ifdef CGAL_LINKED_WITH_TBB
      for(int threads : {2, 5}) {
        tbb::global_control allowed(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
        tbb::task_arena(threads).execute([&] { check(label + ", " + std::to_string(threads) + " threads", true); });
      }
#else
      FAIL() << "lapmesh was built without TBB (libtbb-dev): its parallel path is not tested";
#endif
    }
  }
  // The errors of either topology, in the same words: an edge with three faces, a zero-area face
  // (both in one mesh: the edge is named first), and settings that need the pattern.
  const Smoothing_settings s = settings(true, 1e-3, false, false);
  const auto error_of = [&](const Mesh_topology& t, Positions P) {
    return mesh_error_message([&] { smooth_positions(t, P, {}, s); });
  };
  Engine_arrays flap = jittered_engine_arrays(bumpy_patch(6), 0.0, 1);
  const Index apex = flap.n++;
  flap.positions.conservativeResize(flap.n, 3);
  flap.positions.row(apex) = Eigen::RowVector3d(0.1, 0.1, 1.0);
  // A third face on the edge of the first face's first two vertices.
  flap.triangles.insert(flap.triangles.end(), {flap.triangles[0], flap.triangles[1], apex});
  Engine_arrays flat_face = flap;
  flat_face.positions.row(flat_face.triangles[2]) =
    0.5 * (flat_face.positions.row(flat_face.triangles[0]) + flat_face.positions.row(flat_face.triangles[1]));
  for(const Engine_arrays* a : {&flap, &flat_face}) {
    const std::string expected = error_of(build_topology(a->n, a->triangles), a->positions);
    EXPECT_NE(expected.find("non-manifold"), std::string::npos) << expected;
    EXPECT_EQ(error_of(build_corner_incidence(a->n, a->triangles), a->positions), expected);
  }
  Engine_arrays degenerate = jittered_engine_arrays(bumpy_patch(6), 0.0, 1);
  degenerate.positions.row(degenerate.triangles[2]) =
    0.5 * (degenerate.positions.row(degenerate.triangles[0]) + degenerate.positions.row(degenerate.triangles[1]));
  const std::string zero_area = error_of(build_topology(degenerate.n, degenerate.triangles), degenerate.positions);
  EXPECT_NE(zero_area.find("zero area"), std::string::npos) << zero_area;
  EXPECT_EQ(error_of(build_corner_incidence(degenerate.n, degenerate.triangles), degenerate.positions), zero_area);
  Smoothing_settings rebuilt = s;
  rebuilt.fixed_operator = false;
  EXPECT_FALSE(assembles_operator_by_rows(rebuilt));
  Positions P = degenerate.positions;
  EXPECT_THROW(smooth_positions(build_corner_incidence(degenerate.n, degenerate.triangles), P, {}, rebuilt),
               std::logic_error);
}

// The denoising study measures the positions in the progress callback: after each explicit step
// they must hold that step's result, and the run without a callback (whose steps alternate
// between the positions and an array of the engine's) must end at the same positions, to the
// bit, for an odd and an even number of steps and when it diverges.
TEST(Smoothing, ExplicitPositionsAreThoseOfEachStepInTheProgressCallback)
{
  using namespace lapmesh::internal;
  const lapmesh::Triangle_soup soup = lapmesh::icosphere(3);
  const Index n = Index(soup.points.size());
  Working_array<Index> triangles;
  for(const auto& f : soup.triangles) triangles.insert(triangles.end(), f.begin(), f.end());
  const Mesh_topology t = build_topology(n, triangles);
  Positions P0(n, 3);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> jitter(-0.01, 0.01);
  for(Index i = 0; i < n; ++i)
    P0.row(i) = Eigen::RowVector3d(soup.points[i][0] + jitter(rng), soup.points[i][1] + jitter(rng),
                                   soup.points[i][2] + jitter(rng));
  for(const lapmesh::Laplacian lap : {lapmesh::Laplacian::uniform, lapmesh::Laplacian::cotangent}) {
    Smoothing_settings s;
    s.scheme = lapmesh::Smoothing_scheme::explicit_euler;
    s.laplacian = lap;
    s.area = lapmesh::Vertex_area::mixed;
    s.fixed_operator = true;
    lapmesh::Laplacian_pencil pencil;
    assemble_pencil(t, P0, lap, s.area, false, pencil);
    const double bound = explicit_stability_bound(pencil, std::vector<char>(std::size_t(n), 1), false);
    s.lambda = 0.5 * bound;
    s.iterations = 4;
    std::vector<Positions> seen;
    Positions P = P0;
    s.progress = [&](int, int) { seen.push_back(P); };
    smooth_positions(t, P, {}, s);
    ASSERT_EQ(seen.size(), 4u);
    s.progress = nullptr;
    for(int steps = 1; steps <= 4; ++steps) {
      s.iterations = steps;
      Positions Q = P0;
      smooth_positions(t, Q, {}, s);
      EXPECT_EQ((Q - seen[std::size_t(steps - 1)]).cwiseAbs().maxCoeff(), 0.0)
        << lapmesh::to_string(lap) << ", " << steps;
      EXPECT_GT((Q - P0).cwiseAbs().maxCoeff(), 1e-6) << lapmesh::to_string(lap) << ", " << steps;
    }
    // Far above the bound: the error, and the positions that diverged in the caller's array,
    // whether the step that diverged wrote into the engine's array (odd) or the caller's (even).
    s.iterations = 400;
    bool odd = false, even = false;
    for(double above = 1e6; above < 1e16 && !(odd && even); above *= 10) {
      s.lambda = above * bound;
      Positions D = P0;
      try {
        smooth_positions(t, D, {}, s);
        ADD_FAILURE() << lapmesh::to_string(lap) << ": no divergence at " << above << " x the bound";
      } catch(const lapmesh::Numerical_error& e) {
        const std::string what = e.what(), key = "diverged at iteration ";
        ASSERT_NE(what.find(key), std::string::npos) << what;
        const int step = std::stoi(what.substr(what.find(key) + key.size()));
        (step % 2 ? odd : even) = true;
        EXPECT_FALSE(D.allFinite()) << lapmesh::to_string(lap) << ", step " << step;
      }
    }
    EXPECT_TRUE(odd && even) << lapmesh::to_string(lap);
  }
}

TEST(Smoothing, StabilityBoundMatchesDenseEigenvalue)
{
  for(lapmesh::Laplacian lap : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform}) {
    const Mesh m = jittered(lapmesh::icosphere(2), 0.05, 3);
    const auto pencil = lapmesh::laplacian_pencil(m, LP::laplacian(lap));
    const Eigen::MatrixXd S = Eigen::MatrixXd(pencil.stiffness);
    const Eigen::VectorXd ism = pencil.mass.cwiseSqrt().cwiseInverse();
    const Eigen::MatrixXd Ssym = -(ism.asDiagonal() * S * ism.asDiagonal());
    const double mu_max = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Ssym).eigenvalues().maxCoeff();
    const double bound = lapmesh::explicit_stability_bound(m, LP::laplacian(lap));
    EXPECT_NEAR(bound, 2.0 / mu_max, 1e-7 * bound) << lapmesh::to_string(lap);
    EXPECT_LE(bound, 2.0 / mu_max * (1 + 1e-12));  // on the safe side
  }
}

TEST(Smoothing, StabilityBoundStopsWhereTheUniformEstimateStalls)
{
  // The uniform Laplacian's top eigenvalues lie close together on a large sphere and on CGAL's
  // elephant: the estimate stalls before the residual bound meets the tolerance. The stalled
  // estimate must lie above the converged one (the bound on the safe side) and near it, after
  // fewer products than the cap. On the elephant the estimate pauses after 48 products and falls
  // again: two checks a window apart would stop there, 1.2e-3 above the converged value. The
  // cotangent estimates converge and are those of runs without the stall rule.
  using namespace lapmesh::internal;
  Mesh elephant;
  ASSERT_NO_THROW(lapmesh::io::read_triangle_mesh(cgal_mesh("elephant.off"), elephant));
  const std::pair<Mesh, double> cases[] = {{jittered(lapmesh::icosphere(5), 0.05, 3), 1e-3}, {elephant, 1e-5}};
  for(const auto& [m, tolerance] : cases)
    for(lapmesh::Laplacian lap : {lapmesh::Laplacian::uniform, lapmesh::Laplacian::cotangent}) {
      const std::string what = std::to_string(num_vertices(m)) + " vertices, " + lapmesh::to_string(lap);
      const auto pencil = lapmesh::laplacian_pencil(m, LP::laplacian(lap));
      const std::vector<char> free_mask(std::size_t(pencil.mass.size()), 1);
      Top_eigenvalue_stopping to_convergence;
      to_convergence.stall_tol = 0;
      to_convergence.max_steps = 4000;
      const Top_eigenvalue_estimate converged = top_eigenvalue_of_minus_laplacian(pencil, free_mask, false, to_convergence);
      ASSERT_TRUE(converged.converged) << what;
      const Top_eigenvalue_estimate stalled = top_eigenvalue_of_minus_laplacian(pencil, free_mask, false);
      if(lap == lapmesh::Laplacian::cotangent) {
        EXPECT_TRUE(stalled.converged) << what;
        EXPECT_EQ(stalled.value, converged.value) << what;
        EXPECT_EQ(stalled.products, converged.products) << what;
        continue;
      }
      EXPECT_FALSE(stalled.converged) << what;
      EXPECT_LT(stalled.products, Top_eigenvalue_stopping{}.max_steps) << what;
      EXPECT_LT(stalled.products, converged.products) << what;
      EXPECT_GE(stalled.value, converged.value) << what;
      EXPECT_LE(stalled.value, converged.value * (1 + tolerance)) << what;
      EXPECT_EQ(explicit_stability_bound(pencil, free_mask, false), stability_bound_of(stalled.value)) << what;
    }
}

TEST(Smoothing, TopEigenpairOfTridiagonalMatchesTheDenseSolver)
{
  // Random tridiagonal matrices of the sizes the Lanczos checks see, of small and large scale, and
  // one with a zero off-diagonal entry (two blocks): the largest eigenvalue and the last component
  // of its unit eigenvector as a dense eigen-solve gives them.
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for(int m : {1, 2, 8, 64, 200, 400})
    for(double scale : {1e-6, 1.0, 1e7}) {
      const std::size_t size = std::size_t(m);
      std::vector<double> a(size), b(size - 1);
      for(double& x : a) x = scale * u(rng);
      for(double& x : b) x = scale * u(rng);
      if(m > 8) b[std::size_t(m / 2)] = 0;
      Eigen::MatrixXd T = Eigen::MatrixXd::Zero(m, m);
      for(int i = 0; i < m; ++i) T(i, i) = a[std::size_t(i)];
      for(int i = 0; i + 1 < m; ++i) T(i, i + 1) = T(i + 1, i) = b[std::size_t(i)];
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(T);
      const lapmesh::internal::Tridiagonal_top top = lapmesh::internal::top_eigenpair_of_tridiagonal(a, b);
      EXPECT_NEAR(top.value, es.eigenvalues()[m - 1], 1e-12 * scale) << m << " " << scale;
      // The top eigenvalue of random matrices is well apart from the next: its vector is well defined.
      if(m > 1) {
        ASSERT_GT(es.eigenvalues()[m - 1] - es.eigenvalues()[m - 2], 1e-3 * scale) << m;
      }
      EXPECT_NEAR(std::abs(top.last_component), std::abs(es.eigenvectors()(m - 1, m - 1)), 1e-9) << m << " " << scale;
    }
}

TEST(Smoothing, StabilityBoundInParallelIsTheSerialOne)
{
  // The Lanczos products scale the vector and gather each row alike on any thread: with fixed
  // vertices, and several threads, the estimate is bitwise the serial one.
  const Mesh m = jittered(lapmesh::icosphere(6), 0.05, 3);
  const auto pencil = lapmesh::laplacian_pencil(m);
  std::vector<char> free_mask(num_vertices(m), 1);
  for(std::size_t i = 3; i < free_mask.size(); i += 7) free_mask[i] = 0;
  const double serial = lapmesh::internal::explicit_stability_bound(pencil, free_mask, false);
  EXPECT_GT(serial, 0.0);
  EXPECT_LT(serial, std::numeric_limits<double>::infinity());
#ifdef CGAL_LINKED_WITH_TBB
  for(int threads : {2, 5}) {
    tbb::global_control allowed(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    tbb::task_arena(threads).execute([&] {
      EXPECT_EQ(lapmesh::internal::explicit_stability_bound(pencil, free_mask, true), serial) << threads << " threads";
    });
  }
#else
  FAIL() << "lapmesh was built without TBB (libtbb-dev): its parallel path is not tested";
#endif
}

TEST(Smoothing, ExplicitStepsAreThoseOfThePencil)
{
  // The explicit scheme keeps its stiffness as values on the topology's pattern; each step must
  // still be P + lambda M^-1 S P on the free vertices with the pencil that laplacian_pencil()
  // assembles (of the input with a fixed operator, of the current positions otherwise). With a
  // fixed operator the steps alternate between two arrays: an odd number of them ends in the
  // engine's own array, an even one in the positions it was given.
  const Mesh input = jittered(bumpy_patch(12), 0.01, 5);
  auto constrained = get(CGAL::dynamic_vertex_property_t<bool>(), input);
  for(auto v : vertices(input)) put(constrained, v, v.idx() % 7 == 3);
  for(lapmesh::Laplacian lap : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform})
    for(bool fixed_operator : {true, false})
      for(int iterations : {3, 4}) {
        const auto np =
          LP::vertex_area(lapmesh::Vertex_area::mixed, LP::laplacian(lap)).vertex_is_constrained_map(constrained);
        const double lambda = 0.4 * lapmesh::explicit_stability_bound(input, np);
        Mesh m = input;
        const auto report = lapmesh::smooth_laplacian_explicit(
          m, lambda, LP::fixed_operator(fixed_operator, np).number_of_iterations(iterations));
        EXPECT_EQ(report.iterations, iterations);
        Mesh reference = input;
        auto pencil = lapmesh::laplacian_pencil(reference, np);
        for(int it = 0; it < iterations; ++it) {
          if(it > 0 && !fixed_operator) pencil = lapmesh::laplacian_pencil(reference, np);
          const Eigen::MatrixXd P = positions(reference);
          const Eigen::MatrixXd step = lambda * (pencil.mass.cwiseInverse().asDiagonal() * (pencil.stiffness * P));
          for(auto v : vertices(reference)) {
            if(get(constrained, v) || reference.is_border(v)) continue;
            const auto i = Eigen::Index(v.idx());
            reference.point(v) = Point(P(i, 0) + step(i, 0), P(i, 1) + step(i, 1), P(i, 2) + step(i, 2));
          }
        }
        double largest = 0, moved = 0;
        for(auto v : vertices(m)) {
          largest = std::max(largest, std::sqrt(CGAL::squared_distance(m.point(v), reference.point(v))));
          moved = std::max(moved, std::sqrt(CGAL::squared_distance(m.point(v), input.point(v))));
        }
        const std::string label = std::string(lapmesh::to_string(lap)) +
                                  (fixed_operator ? ", fixed operator, " : ", ") + std::to_string(iterations) +
                                  " steps";
        EXPECT_GT(moved, 1e-4) << label;
        EXPECT_LT(largest, 1e-13) << label;
        // The front end's progress callback sees the counts alone: the same steps, to the bit.
        Mesh with_progress = input;
        int calls = 0;
        const std::function<void(int, int)> count_calls = [&](int, int) { ++calls; };
        lapmesh::smooth_laplacian_explicit(
          with_progress, lambda,
          LP::progress_callback(count_calls, LP::fixed_operator(fixed_operator, np).number_of_iterations(iterations)));
        EXPECT_EQ(calls, iterations) << label;
        for(auto v : vertices(m)) ASSERT_EQ(m.point(v), with_progress.point(v)) << label;
      }
}

TEST(Smoothing, ExplicitBlowsUpAboveTheBoundAndNotBelow)
{
  for(lapmesh::Laplacian lap : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform}) {
    const Mesh input = jittered(lapmesh::icosphere(3), 0.02, 11);
    const double bound = lapmesh::explicit_stability_bound(input, LP::laplacian(lap));
    const double size0 = positions(input).cwiseAbs().maxCoeff();

    Mesh below = input;
    const auto rb = lapmesh::smooth_laplacian_explicit(
      below, 0.95 * bound,
      LP::compute_stability_bound(true, LP::fixed_operator(true, LP::laplacian(lap))).number_of_iterations(400));
    EXPECT_TRUE(rb.stability_bound_exact);
    EXPECT_FALSE(rb.above_stability_bound);
    EXPECT_NEAR(rb.stability_bound, bound, 1e-12 * bound);  // the bound reported is the one computed
    EXPECT_LE(positions(below).cwiseAbs().maxCoeff(), size0 * (1 + 1e-9));

    Mesh above = input;
    bool diverged = false;
    try {
      const auto ra = lapmesh::smooth_laplacian_explicit(
        above, 1.05 * bound, LP::fixed_operator(true, LP::laplacian(lap)).number_of_iterations(400));
      EXPECT_TRUE(ra.above_stability_bound);
      diverged = positions(above).cwiseAbs().maxCoeff() > 1e3 * size0;
    } catch(const lapmesh::Numerical_error&) {
      diverged = true;
    }
    EXPECT_TRUE(diverged) << lapmesh::to_string(lap);
  }
}

// Far above the bound the positions overflow: the error names the first step that wrote a
// coordinate that is not finite (one step fewer runs through with finite ones), serially and in
// parallel parts, and the mesh is left as it was.
TEST(Smoothing, ExplicitDivergenceNamesTheFirstNonFiniteStep)
{
  const Mesh input = jittered(lapmesh::icosphere(5), 0.002, 5);
  ASSERT_GT(num_vertices(input), 2u * 4096u);
  const double lambda = 100 * lapmesh::explicit_stability_bound(input);
  auto smooth = [&](Mesh& m, int iterations, bool parallel) {
    const auto np = LP::fixed_operator(true).number_of_iterations(iterations);
    if(parallel)
      lapmesh::smooth_laplacian_explicit<CGAL::Parallel_tag>(m, lambda, np);
    else
      lapmesh::smooth_laplacian_explicit(m, lambda, np);
  };
  int first_serial = 0;
  for(bool parallel : {false, true}) {
    Mesh m = input;
    int first = 0;
    try {
      smooth(m, 10000, parallel);
    } catch(const lapmesh::Numerical_error& e) {
      const std::string message = e.what(), prefix = "diverged at iteration ";
      const auto at = message.find(prefix);
      ASSERT_NE(at, std::string::npos) << message;
      first = std::atoi(message.c_str() + at + prefix.size());
    }
    ASSERT_GT(first, 1) << "no divergence reported, parallel " << parallel;
    EXPECT_EQ(positions(m), positions(input));
    if(!parallel) first_serial = first;
    EXPECT_EQ(first, first_serial);

    Mesh before = input;
    smooth(before, first - 1, parallel);
    const Eigen::MatrixXd P = positions(before);
    EXPECT_TRUE(P.allFinite());
    EXPECT_GT(P.cwiseAbs().maxCoeff(), 1e100);
  }
}

TEST(Smoothing, UniformImplicitEqualsDenseInverse)
{
  const Mesh input = jittered(lapmesh::icosphere(2), 0.05, 2);
  const auto pencil = lapmesh::laplacian_pencil(input, LP::laplacian(lapmesh::Laplacian::uniform));
  const int n = int(num_vertices(input));
  // Lu = D^-1 W, assembled independently from the adjacency.
  Eigen::MatrixXd Lu = Eigen::MatrixXd::Zero(n, n);
  for(auto v : vertices(input)) {
    const double deg = double(degree(v, input));
    for(auto w : vertices_around_target(halfedge(v, input), input)) Lu(v.idx(), w.idx()) += 1.0 / deg;
    Lu(v.idx(), v.idx()) = -1.0;
  }
  const double lambda = 0.7;
  Eigen::MatrixXd X = positions(input);
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  for(int k = 0; k < 3; ++k) X = (I - lambda * Lu).partialPivLu().solve(X);
  Mesh m = input;
  const auto report = lapmesh::smooth_laplacian_implicit(m, lambda, LP::laplacian(lapmesh::Laplacian::uniform).number_of_iterations(3));
  EXPECT_EQ(report.factorizations, 1);  // the uniform operator does not depend on positions
  EXPECT_LE((positions(m) - X).cwiseAbs().maxCoeff(), 1e-12);
  (void)pencil;
}

TEST(Smoothing, CotangentImplicitWithBoundaryAndConstraintsEqualsDenseDirichletSolve)
{
  for(bool fixed_operator : {false, true}) {
    const Mesh input = to_mesh(bumpy_patch(9));
    const int n = int(num_vertices(input));
    auto constrained = get(CGAL::dynamic_vertex_property_t<bool>(), input);
    std::vector<bool> fixed(n);
    for(auto v : vertices(input)) {
      const bool c = v.idx() % 7 == 3;
      put(constrained, v, c);
      fixed[v.idx()] = c || input.is_border(v);
    }
    const double lambda = 0.004;
    Eigen::MatrixXd X = positions(input);
    Mesh state = input;
    for(int k = 0; k < 3; ++k) {
      const auto pencil = lapmesh::laplacian_pencil(fixed_operator ? input : state);
      X = dense_implicit_step(Eigen::MatrixXd(pencil.stiffness), lapmesh::vertex_areas(state), X, lambda, fixed);
      for(auto v : vertices(state)) state.point(v) = Point(X(v.idx(), 0), X(v.idx(), 1), X(v.idx(), 2));
    }
    // (with a fixed operator the mass also stays that of the input)
    if(fixed_operator) {
      X = positions(input);
      const auto pencil = lapmesh::laplacian_pencil(input);
      for(int k = 0; k < 3; ++k)
        X = dense_implicit_step(Eigen::MatrixXd(pencil.stiffness), pencil.mass, X, lambda, fixed);
    }
    Mesh m = input;
    lapmesh::smooth_laplacian_implicit(
      m, lambda, LP::fixed_operator(fixed_operator).number_of_iterations(3).vertex_is_constrained_map(constrained));
    EXPECT_LE((positions(m) - X).cwiseAbs().maxCoeff(), 1e-12) << "fixed operator " << fixed_operator;
    EXPECT_GT((positions(m) - positions(input)).cwiseAbs().maxCoeff(), 1e-3);  // it did move
  }
}

TEST(Smoothing, FixedVerticesKeepTheirExactKernelCoordinates)
{
  // Over exact rationals that no double represents, the boundary (fixed) keeps its exact
  // points: only what moved is written back, and a fixed vertex's double does not count as moved.
  using Exact_kernel = CGAL::Simple_cartesian<CGAL::Exact_rational>;
  using Exact_mesh = CGAL::Surface_mesh<Exact_kernel::Point_3>;
  Exact_mesh input;
  ASSERT_TRUE(lapmesh::make_mesh(bumpy_patch(6), input));
  const Exact_kernel::Vector_3 third(CGAL::Exact_rational(1, 3072), CGAL::Exact_rational(1, 3072), CGAL::Exact_rational(-1, 3072));
  for(auto v : vertices(input)) input.point(v) = input.point(v) + third;
  for(bool explicit_scheme : {true, false}) {
    Exact_mesh m = input;
    const auto np = CGAL::parameters::number_of_iterations(3);
    if(explicit_scheme)
      lapmesh::smooth_laplacian_explicit(m, 0.5 * lapmesh::explicit_stability_bound(m), np);
    else
      lapmesh::smooth_laplacian_implicit(m, 0.004, np);
    int border = 0, moved = 0;
    for(auto v : vertices(m)) {
      const auto& before = input.point(v);
      if(m.is_border(v)) {
        ++border;
        EXPECT_TRUE(m.point(v) == before) << "border vertex " << v.idx() << (explicit_scheme ? " (explicit)" : " (implicit)");
        EXPECT_NE(CGAL::Exact_rational(CGAL::to_double(before.x())), before.x());  // no double equals it
      } else {
        moved += m.point(v) != before;
      }
    }
    EXPECT_GT(border, 0);
    EXPECT_EQ(moved, int(num_vertices(m)) - border) << (explicit_scheme ? "explicit" : "implicit");
  }
}

TEST(Smoothing, CholmodAndEigenSolversAgree)
{
  const Mesh input = to_mesh(lapmesh::bumpy_sphere(3));
  Mesh a = input, b = input;
  const double lambda = lapmesh::scale_free_time_step(input, 3.0);
  const auto ra = lapmesh::smooth_laplacian_implicit(a, lambda, LP::use_cholmod(true).number_of_iterations(5));
  const auto rb = lapmesh::smooth_laplacian_implicit(b, lambda, LP::use_cholmod(false).number_of_iterations(5));
#ifdef LAPMESH_HAS_CHOLMOD
  EXPECT_EQ(ra.solver, "cholmod-supernodal");
#else
  EXPECT_EQ(ra.solver, "eigen-ldlt");
#endif
  EXPECT_EQ(rb.solver, "eigen-ldlt");
  EXPECT_LE((positions(a) - positions(b)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT((positions(a) - positions(input)).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(Smoothing, TheFreeBlockInAGivenOrderIsThePermutedBlock)
{
  // Built in an order, the free block is P A_FF P^T, its right-hand side has the same rows,
  // and its solution scattered back gives the positions of the block in index order.
  using lapmesh::internal::Constrained_spd_system;
  using lapmesh::internal::Index;
  const Mesh input = to_mesh(bumpy_patch(7));
  const auto pencil = lapmesh::laplacian_pencil(input);
  std::vector<char> free_mask(num_vertices(input));
  for(auto v : vertices(input)) free_mask[v.idx()] = !(input.is_border(v) || v.idx() % 5 == 2);
  Constrained_spd_system natural(pencil.stiffness, free_mask);
  const Index nf = natural.size();
  std::vector<Index> order(static_cast<std::size_t>(nf));
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  Constrained_spd_system ordered(pencil.stiffness, free_mask, order);
  ASSERT_EQ(ordered.size(), nf);

  const double lambda = 0.003;
  natural.fill_matrix(pencil.stiffness, -lambda, pencil.mass, 1.0);
  ordered.fill_matrix(pencil.stiffness, -lambda, pencil.mass, 1.0);
  const auto& A = ordered.matrix();
  for(Index c = 0; c < nf; ++c) {  // each column starts at its diagonal, rows increasing
    ASSERT_EQ(A.innerIndexPtr()[A.outerIndexPtr()[c]], c);
    for(Index k = A.outerIndexPtr()[c] + 1; k < A.outerIndexPtr()[c + 1]; ++k)
      ASSERT_LT(A.innerIndexPtr()[k - 1], A.innerIndexPtr()[k]);
  }
  using SpMat = Eigen::SparseMatrix<double>;
  const Eigen::MatrixXd An = Eigen::MatrixXd(SpMat(natural.matrix().selfadjointView<Eigen::Lower>()));
  const Eigen::MatrixXd Ao = Eigen::MatrixXd(SpMat(ordered.matrix().selfadjointView<Eigen::Lower>()));
  for(Index a = 0; a < nf; ++a)
    for(Index b = 0; b < nf; ++b) ASSERT_EQ(Ao(a, b), An(order[a], order[b])) << a << ' ' << b;

  const Eigen::MatrixXd P = positions(input);
  Eigen::MatrixXd Bn(nf, 3), Bo(nf, 3);
  natural.fill_rhs(pencil.stiffness, -lambda, pencil.mass, 1.0, P, Bn, false);
  ordered.fill_rhs(pencil.stiffness, -lambda, pencil.mass, 1.0, P, Bo, false);
  for(Index a = 0; a < nf; ++a) ASSERT_EQ(Bo.row(a), Bn.row(order[a]));

  // Its map from the stiffness released (no fill follows), the matrix and the right-hand side
  // stay as they were, and a fill is refused instead of reading the freed map.
  const SpMat filled = ordered.matrix();
  ordered.release_fill_map();
  EXPECT_EQ(SpMat(ordered.matrix() - filled).norm(), 0.0);
  Eigen::MatrixXd released_rhs(nf, 3);
  ordered.fill_rhs(pencil.stiffness, -lambda, pencil.mass, 1.0, P, released_rhs, false);
  EXPECT_EQ(released_rhs, Bo);
  EXPECT_THROW(ordered.fill_matrix(pencil.stiffness, -lambda, pencil.mass, 1.0), std::logic_error);

  Eigen::MatrixXd Pn = P, Po = P;
  natural.scatter(Eigen::MatrixXd(An.ldlt().solve(Bn)), Pn);
  ordered.scatter(Eigen::MatrixXd(Ao.ldlt().solve(Bo)), Po);
  EXPECT_LE((Pn - Po).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_GT((Pn - P).cwiseAbs().maxCoeff(), 1e-4);  // the free rows moved
  for(auto v : vertices(input)) {
    if(!free_mask[v.idx()]) {
      EXPECT_EQ(Po.row(v.idx()), P.row(v.idx()));
    }
  }
}

#ifdef LAPMESH_HAS_CHOLMOD
TEST(Smoothing, TheFirstFactorisationOfAnAnalysisHandsBackTheCachedWorkingArrays)
{
  // A factor's values, most of an implicit step's peak, are not written beside the mappings that
  // the step's earlier stages freed into the caches: the first numeric factorisation of an
  // analysis hands them back. The later ones write into the factor they have and leave the
  // caches alone.
  using lapmesh::internal::Working_array;
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  const auto pencil = lapmesh::laplacian_pencil(to_mesh(lapmesh::icosphere(3, 1.0)));
  Eigen::SparseMatrix<double> K = -pencil.stiffness;
  K.diagonal() += pencil.mass;
  const std::size_t small_array = (std::size_t(1) << 20) / sizeof(double);  // the small arrays' cache
  lapmesh::release_working_memory();
  { Working_array<double> freed(small_array); }
  ASSERT_GT(lapmesh::cached_working_memory(), 0u);
  lapmesh::internal::Cholmod_supernodal_llt llt;
  llt.analyzePattern(K);
  ASSERT_EQ(llt.info(), Eigen::Success);
  EXPECT_GT(lapmesh::cached_working_memory(), 0u);  // the analysis leaves them
  llt.factorize(K);
  ASSERT_EQ(llt.info(), Eigen::Success);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  { Working_array<double> freed(small_array); }
  llt.factorize(K);
  ASSERT_EQ(llt.info(), Eigen::Success);
  EXPECT_GT(lapmesh::cached_working_memory(), 0u);
  lapmesh::release_working_memory();
}

// Between two factorisations of a rebuilt operator the factor's values are dead: the next step's
// assembly writes its stiffness and corner cotangents there, so that no array of its own lies
// beside the factor (the cotangents of this mesh would take a mapping of the small arrays' cache).
// Only after a factorisation, only where they fit, and only for the cotangent Laplacian.
TEST(Smoothing, ALaterStepAssemblesIntoTheDeadFactor)
{
  using namespace lapmesh::internal;
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  const Engine_arrays sphere = jittered_engine_arrays(lapmesh::icosphere(5), 0.002, 9);
  const Index n = sphere.n;
  const Positions& P0 = sphere.positions;
  ASSERT_GE(sphere.triangles.size() * sizeof(double), small_mapping_min_bytes);  // the cotangents, 3 per face
  const Mesh_topology t = build_topology(n, sphere.triangles);

  Smoothing_settings s;
  s.lambda = 1e-3;
  s.iterations = 4;
  std::vector<std::size_t> cached_after_step;
  s.progress = [&](int, int) { cached_after_step.push_back(lapmesh::cached_working_memory()); };
  Positions into_factor = P0;
  lapmesh::release_working_memory();
  smooth_positions(t, into_factor, std::vector<char>(std::size_t(n), 0), s);
  ASSERT_EQ(cached_after_step.size(), 4u);
  for(std::size_t it = 0; it < 4; ++it) EXPECT_EQ(cached_after_step[it], 0u) << "after step " << it + 1;

  // The same steps with Eigen's LDL^T, which lends no memory: the cotangents' mapping is cached
  // after each assembly; the positions agree.
  s.use_cholmod = false;
  cached_after_step.clear();
  Positions own_arrays = P0;
  lapmesh::release_working_memory();
  smooth_positions(t, own_arrays, std::vector<char>(std::size_t(n), 0), s);
  EXPECT_GT(cached_after_step.back(), 0u);
  EXPECT_LE((into_factor - own_arrays).cwiseAbs().maxCoeff(), 1e-13);
  EXPECT_GT((into_factor - P0).cwiseAbs().maxCoeff(), 1e-4);
  lapmesh::release_working_memory();

  // The solver lends its values only once they exist, and only as many as they are.
  const auto pencil = lapmesh::laplacian_pencil(to_mesh(lapmesh::icosphere(3, 1.0)));
  const std::vector<char> all_free(std::size_t(pencil.mass.size()), 1);
  const Constrained_spd_system natural(pencil.stiffness, all_free);
  Spd_direct_solver solver(true);
  const std::vector<Index> order = solver.analyze(natural.matrix(), 1);
  Constrained_spd_system ordered(pencil.stiffness, all_free, order);
  solver.analyze_in_order(ordered.matrix());
  EXPECT_EQ(solver.values_to_overwrite(1), nullptr);  // a symbolic factor
  ordered.fill_matrix(pencil.stiffness, -1e-3, pencil.mass, 1.0);
  ASSERT_TRUE(solver.factorize(ordered.matrix()));
  EXPECT_NE(solver.values_to_overwrite(solver.factor_values()), nullptr);
  EXPECT_EQ(solver.values_to_overwrite(solver.factor_values() + 1), nullptr);
}

TEST(Smoothing, CholmodFactorOfTheBlockInItsOwnOrderIsTheFactorOfThatOrder)
{
  // The block rebuilt in the order of CHOLMOD's analysis and factorised as given has the same
  // supernodes and values as the factor of the block in index order, and its in-place solve
  // gives Eigen's LDL^T solution.
  using lapmesh::internal::Cholmod_supernodal_llt;
  using lapmesh::internal::Constrained_spd_system;
  using lapmesh::internal::Index;
  const Mesh input = to_mesh(lapmesh::bumpy_sphere(3));
  const auto pencil = lapmesh::laplacian_pencil(input);
  const std::vector<char> free_mask(num_vertices(input), 1);
  const double lambda = lapmesh::scale_free_time_step(input, 3.0);

  Constrained_spd_system in_index_order(pencil.stiffness, free_mask);
  in_index_order.fill_matrix(pencil.stiffness, -lambda, pencil.mass, 1.0);
  Cholmod_supernodal_llt own(Cholmod_supernodal_llt::Ordering::amd);
  own.compute(in_index_order.matrix());
  ASSERT_EQ(own.info(), Eigen::Success);
  const Index nf = in_index_order.size();
  const std::vector<Index> order(own.permutation(), own.permutation() + nf);
  EXPECT_FALSE(own.in_given_order());

  Constrained_spd_system in_its_order(pencil.stiffness, free_mask, order);
  in_its_order.fill_matrix(pencil.stiffness, -lambda, pencil.mass, 1.0);
  Cholmod_supernodal_llt given(Cholmod_supernodal_llt::Ordering::given);
  given.compute(in_its_order.matrix());
  ASSERT_EQ(given.info(), Eigen::Success);
  EXPECT_TRUE(given.in_given_order());
  ASSERT_EQ(given.factor()->nsuper, own.factor()->nsuper);
  ASSERT_EQ(given.factor()->xsize, own.factor()->xsize);
  const auto* x_own = static_cast<const double*>(own.factor()->x);
  const auto* x_given = static_cast<const double*>(given.factor()->x);
  double largest = 0, difference = 0;
  for(std::size_t k = 0; k < given.factor()->xsize; ++k) {
    largest = std::max(largest, std::abs(x_own[k]));
    difference = std::max(difference, std::abs(x_own[k] - x_given[k]));
  }
  EXPECT_LE(difference, 1e-13 * largest);

  // lapmesh's numeric factorisation of the block as given (the smoothing solver's choice for
  // small supernodes) writes the same values into the same factor.
  Cholmod_supernodal_llt given_by_lapmesh(Cholmod_supernodal_llt::Ordering::given);
  given_by_lapmesh.set_numeric(Cholmod_supernodal_llt::Numeric::fastest);
  given_by_lapmesh.compute(in_its_order.matrix());
  ASSERT_EQ(given_by_lapmesh.info(), Eigen::Success);
  EXPECT_TRUE(given_by_lapmesh.factorised_by_lapmesh());
  ASSERT_EQ(given_by_lapmesh.factor()->xsize, given.factor()->xsize);
  const auto* x_lapmesh = static_cast<const double*>(given_by_lapmesh.factor()->x);
  double lapmesh_difference = 0;
  for(std::size_t k = 0; k < given.factor()->xsize; ++k)
    lapmesh_difference = std::max(lapmesh_difference, std::abs(x_lapmesh[k] - x_given[k]));
  EXPECT_LE(lapmesh_difference, 1e-12 * largest);

  // The in-place solve: lapmesh's supernodal kernels for 2 to 8 columns (3 is a smoothing step's
  // coordinates), CHOLMOD's solves otherwise; each column equals Eigen's LDL^T solution.
  const Eigen::SparseMatrix<double> full = in_its_order.matrix().selfadjointView<Eigen::Lower>();
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> reference_solver(full);
  for(const Index columns : {1, 3, 5, 9}) {
    const Eigen::MatrixXd B = Eigen::MatrixXd::Random(nf, columns);
    const Eigen::MatrixXd reference = reference_solver.solve(B);
    for(const Cholmod_supernodal_llt* factor : {&given, &given_by_lapmesh}) {
      Eigen::MatrixXd X = B, by_cholmod = B;
      ASSERT_TRUE(factor->solve_in_place(X.data(), nf, columns));
      ASSERT_TRUE(factor->cholmod_solve_in_place(by_cholmod.data(), nf, columns));
      EXPECT_LE((X - reference).cwiseAbs().maxCoeff(), 1e-10 * reference.cwiseAbs().maxCoeff()) << columns;
      EXPECT_LE((by_cholmod - reference).cwiseAbs().maxCoeff(), 1e-10 * reference.cwiseAbs().maxCoeff()) << columns;
    }
  }
}

namespace {
/// The graph Laplacian of a path (1 dimension) or of a cubic grid (3), negative semidefinite.
Eigen::SparseMatrix<double> grid_laplacian(int side, int dimensions)
{
  const int n = dimensions == 3 ? side * side * side : side;
  std::vector<Eigen::Triplet<double>> entries;
  const auto link = [&](int a, int b) {
    entries.emplace_back(a, b, 1.0);
    entries.emplace_back(b, a, 1.0);
    entries.emplace_back(a, a, -1.0);
    entries.emplace_back(b, b, -1.0);
  };
  for(int i = 0; i < n; ++i) {
    if(dimensions == 1) {
      if(i + 1 < n) link(i, i + 1);
      continue;
    }
    const int x = i % side, y = (i / side) % side, z = i / (side * side);
    if(x + 1 < side) link(i, i + 1);
    if(y + 1 < side) link(i, i + side);
    if(z + 1 < side) link(i, i + side * side);
  }
  Eigen::SparseMatrix<double> S(n, n);
  S.setFromTriplets(entries.begin(), entries.end());
  return S;
}

struct Ordering_outcome
{
  std::string ordering;
  double factor_entries = 0;
  std::size_t factor_values = 0, default_factor_values = 0;  // the latter: merged supernodes
  double flops_per_entry = 0;
  bool factorised_by_lapmesh = false;
  double error = std::numeric_limits<double>::infinity();  // until a solve is compared
};

/// The smoothing solver's analysis of M - S (M the identity) for `planned_factorizations`, its
/// factorisation and a solve compared with Eigen's LDL^T; large_factor_entries < 0: the default.
Ordering_outcome solve_in_chosen_order(const Eigen::SparseMatrix<double>& S, double large_factor_entries,
                                       int planned_factorizations)
{
  using lapmesh::internal::Constrained_spd_system;
  using lapmesh::internal::Index;
  using lapmesh::internal::Spd_direct_solver;
  const Index n = Index(S.rows());
  const std::vector<char> free_mask(std::size_t(n), 1);
  const Eigen::VectorXd mass = Eigen::VectorXd::Ones(n);
  Spd_direct_solver solver(true);
  if(large_factor_entries >= 0) solver.set_large_factor_entries(large_factor_entries);
  Constrained_spd_system natural(S, free_mask);
  const std::vector<Index> order = solver.analyze(natural.matrix(), planned_factorizations);
  Constrained_spd_system ordered(S, free_mask, order);
  solver.analyze_in_order(ordered.matrix());
  ordered.fill_matrix(S, -1.0, mass, 1.0);
  Ordering_outcome outcome;
  outcome.ordering = solver.ordering();
  outcome.factor_entries = solver.factor_entries();
  outcome.factor_values = solver.factor_values();
  lapmesh::internal::Cholmod_supernodal_llt merged(lapmesh::internal::Cholmod_supernodal_llt::Ordering::given);
  merged.analyzePattern(ordered.matrix());
  outcome.default_factor_values = merged.factor()->xsize;
  outcome.flops_per_entry = merged.cholmod().fl / merged.cholmod().lnz;
  if(!solver.factorize(ordered.matrix())) return outcome;
  outcome.factorised_by_lapmesh = solver.factorised_by_lapmesh();
  const Eigen::MatrixXd X = Eigen::MatrixXd::Random(n, 3);
  Eigen::MatrixXd B(n, 3), solution = X;
  ordered.gather(X, B);
  EXPECT_TRUE(solver.solve_in_place(B));
  ordered.scatter(B, solution);
  natural.fill_matrix(S, -1.0, mass, 1.0);
  const Eigen::SparseMatrix<double> full = natural.matrix().selfadjointView<Eigen::Lower>();
  const Eigen::MatrixXd expected = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>(full).solve(X);
  outcome.error = (solution - expected).cwiseAbs().maxCoeff() / expected.cwiseAbs().maxCoeff();
  return outcome;
}
} // namespace

TEST(Smoothing, OneFactorisationTriesMetisOnlyForALargeFactorThatNeedsManyFlopsPerEntry)
{
  // The graph Laplacian of a 3D grid: AMD's factor needs many flops per entry there, and
  // METIS's factor is smaller. A path's factor needs few: AMD stays however large it is taken to
  // be. Whatever the ordering, the solve equals Eigen's LDL^T solution of the same system. The
  // supernodes: merged (CHOLMOD's default) where CHOLMOD factorises, compact where lapmesh does,
  // so that the path's factor holds fewer values than CHOLMOD's default analysis would give it.
  const Eigen::SparseMatrix<double> grid = grid_laplacian(26, 3), path = grid_laplacian(20000, 1);
  const Ordering_outcome by_default = solve_in_chosen_order(grid, -1, 1), large = solve_in_chosen_order(grid, 0, 1),
                         path_large = solve_in_chosen_order(path, 0, 1);
  EXPECT_EQ(by_default.ordering, "amd");  // its factor is far below the default bar
  EXPECT_EQ(large.ordering, "metis");
  EXPECT_LT(large.factor_entries, 0.85 * by_default.factor_entries);
  EXPECT_EQ(path_large.ordering, "amd");
  // The numeric factorisation: CHOLMOD's for the grid's large supernodes (AMD's), lapmesh's for
  // the path's; each by the flops per factor entry, and on compact supernodes where lapmesh's.
  EXPECT_GT(by_default.flops_per_entry, 600);
  EXPECT_FALSE(by_default.factorised_by_lapmesh);
  EXPECT_TRUE(path_large.factorised_by_lapmesh);
  EXPECT_LT(double(path_large.factor_values), 0.9 * double(path_large.default_factor_values));
  for(const Ordering_outcome* o : {&by_default, &large, &path_large}) {
    EXPECT_EQ(o->factorised_by_lapmesh, o->flops_per_entry <= 600) << o->ordering;
    if(o->factorised_by_lapmesh)
      EXPECT_LT(o->factor_values, o->default_factor_values) << o->ordering;
    else
      EXPECT_EQ(o->factor_values, o->default_factor_values) << o->ordering;
    EXPECT_LE(o->error, 1e-12) << o->ordering;
  }
}

TEST(Smoothing, PlannedFactorisationsTryMetisOnceTheirFlopsOutweighItsAnalysis)
{
  // The time rule: METIS is tried from the number of factorisations whose flops in AMD's
  // ordering reach metis_min_planned_flops_per_entry per entry of the lower triangle, and kept
  // on the 3D grid, where its factor is smaller and needs fewer flops; one factorisation fewer
  // keeps AMD. A path's factorisations need few flops: AMD for a thousand of them.
  using Llt = lapmesh::internal::Cholmod_supernodal_llt;
  const Eigen::SparseMatrix<double> grid = grid_laplacian(26, 3), path = grid_laplacian(20000, 1);
  const lapmesh::internal::Constrained_spd_system natural(grid, std::vector<char>(std::size_t(grid.rows()), 1));
  Llt amd(Llt::Ordering::amd);
  amd.analyzePattern(natural.matrix());
  ASSERT_EQ(amd.info(), Eigen::Success);
  const double lower_entries = Llt::lower_entries(natural.matrix());
  ASSERT_EQ(lower_entries, double(grid.rows() + (grid.nonZeros() - grid.rows()) / 2));  // every link once
  const int planned = int(std::ceil(Llt::metis_min_planned_flops_per_entry * lower_entries / amd.cholmod().fl));
  ASSERT_GT(planned, 1);
  const Ordering_outcome fewer = solve_in_chosen_order(grid, -1, planned - 1),
                         enough = solve_in_chosen_order(grid, -1, planned),
                         path_many = solve_in_chosen_order(path, -1, 1000);
  EXPECT_EQ(fewer.ordering, "amd");
  EXPECT_EQ(enough.ordering, "metis");
  EXPECT_LT(enough.factor_entries, 0.85 * fewer.factor_entries);
  EXPECT_EQ(path_many.ordering, "amd");
  for(const Ordering_outcome* o : {&fewer, &enough, &path_many}) EXPECT_LE(o->error, 1e-12) << o->ordering;
}
#endif

TEST(Smoothing, CholmodAndEigenSolversAgreeWithConstraintsOverManySteps)
{
  // Several steps, with fixed and boundary vertices: the block in the solver's order, the
  // right-hand side with the fixed terms, the in-place solve and the stiffness released between
  // steps give Eigen's LDL^T result.
  const Mesh input = to_mesh(bumpy_patch(12));
  auto constrained = get(CGAL::dynamic_vertex_property_t<bool>(), input);
  for(auto v : vertices(input)) put(constrained, v, v.idx() % 11 == 4);
  const int steps = 8;
  Mesh a = input, b = input;
  const auto np = CGAL::parameters::number_of_iterations(steps).vertex_is_constrained_map(constrained);
  const auto ra = lapmesh::smooth_laplacian_implicit(a, 0.002, LP::use_cholmod(true, np));
  const auto rb = lapmesh::smooth_laplacian_implicit(b, 0.002, LP::use_cholmod(false, np));
  EXPECT_EQ(ra.factorizations, steps);
  EXPECT_EQ(rb.solver, "eigen-ldlt");
  EXPECT_LE((positions(a) - positions(b)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT((positions(a) - positions(input)).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(Smoothing, ReleaseFreesTheStorageOfASparseMatrix)
{
  Eigen::SparseMatrix<double> m = Eigen::MatrixXd::Identity(40, 40).sparseView();
  ASSERT_GT(m.data().allocatedSize(), 0);
  lapmesh::internal::release(m);
  EXPECT_EQ(m.data().allocatedSize(), 0);
  EXPECT_EQ(m.rows(), 0);
  EXPECT_EQ(m.nonZeros(), 0);
}

#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
TEST(Smoothing, FreedHeapBlocksBetweenLiveOnesAreHandedBack)
{
  // Blocks under glibc's mmap threshold, freed between blocks that stay, stay resident until
  // release_free_heap() hands their pages back.
  const auto resident_kib = [] {
    std::ifstream status("/proc/self/status");
    for(std::string line; std::getline(status, line);)
      if(line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    return -1L;
  };
  // Kept blocks of the same size: smaller ones could come from free chunks of earlier tests, and
  // the freed blocks would then join the top of the heap, which glibc trims by itself.
  constexpr std::size_t block = std::size_t(100) << 10, blocks = 320;  // 31.25 MiB freed
  std::vector<std::unique_ptr<char[]>> freed, kept;
  for(std::size_t i = 0; i < blocks; ++i) {
    freed.emplace_back(new char[block]);
    std::memset(freed.back().get(), 1, block);
    kept.emplace_back(new char[block]);
    std::memset(kept.back().get(), 1, block);
  }
  freed.clear();
  const long before = resident_kib();
  lapmesh::internal::release_free_heap(std::size_t(16) << 20);
  const long after = resident_kib();
  ASSERT_GT(before, 0);
  EXPECT_GE(before - after, long(blocks * block / 1024 / 2)) << before << " KiB -> " << after << " KiB";
}
#endif

TEST(Smoothing, ImplicitSmoothingIsScaleCovariantAtTheEndsOfTheRange)
{
  // Mean curvature flow commutes with scaling (lambda scales with the area): a mesh scaled by
  // s and smoothed equals the smoothed mesh scaled by s. At s = 1e+-140 the right-hand side
  // M P of the unscaled system is not representable (1e+-420).
  const lapmesh::Triangle_soup unit = lapmesh::bumpy_sphere(2);
  Mesh reference = to_mesh(unit);
  const double lambda = lapmesh::scale_free_time_step(reference, 1.0);
  lapmesh::smooth_laplacian_implicit(reference, lambda, CGAL::parameters::number_of_iterations(3));
  const auto expected = positions(reference);
  for(double scale : {1e-140, 1e-20, 1e20, 1e140}) {
    lapmesh::Triangle_soup scaled = unit;
    for(auto& p : scaled.points)
      for(double& c : p) c *= scale;
    Mesh m = to_mesh(scaled);
    lapmesh::smooth_laplacian_implicit(m, lambda * scale * scale, CGAL::parameters::number_of_iterations(3));
    const auto P = positions(m);
    ASSERT_TRUE(P.allFinite()) << scale;
    EXPECT_LE((P / scale - expected).cwiseAbs().maxCoeff(), 1e-12) << scale;
  }
}

TEST(Smoothing, ReusedFactorizationMatchesRefactorization)
{
  const Mesh input = to_mesh(lapmesh::bumpy_sphere(4));
  Mesh a = input, b = input;
  const double lambda = lapmesh::scale_free_time_step(input, 1.0);
  const auto ra = lapmesh::smooth_laplacian_implicit(a, lambda, CGAL::parameters::number_of_iterations(6));
  const auto rb = lapmesh::smooth_laplacian_implicit(b, lambda, LP::reuse_factorization(true).number_of_iterations(6));
  EXPECT_EQ(ra.factorizations, 6);
  EXPECT_LT(rb.factorizations, 6);
  EXPECT_EQ(rb.factorizations + rb.preconditioned_solves, 6);
  EXPECT_LE((positions(a) - positions(b)).cwiseAbs().maxCoeff(), 1e-10);
}

TEST(Smoothing, TimeStepUnitsAndAutomaticStep)
{
  // The rule shared by `lapmesh smooth --lambda auto`, the viewer and the study.
  const Mesh m = to_mesh(lapmesh::icosphere(3, 2.0));
  const double bound = lapmesh::explicit_stability_bound(m);
  const double h = lapmesh::mean_edge_length(m);
  EXPECT_DOUBLE_EQ(lapmesh::time_step(m, 0.5, lapmesh::Time_step_unit::stability_bound), 0.5 * bound);
  EXPECT_DOUBLE_EQ(lapmesh::time_step(m, 3.0, lapmesh::Time_step_unit::mean_edge_length_squared), 3.0 * h * h);
  EXPECT_DOUBLE_EQ(lapmesh::time_step(m, 3.0, lapmesh::Time_step_unit::absolute), 3.0);
  EXPECT_DOUBLE_EQ(lapmesh::automatic_time_step(m, lapmesh::Smoothing_scheme::explicit_euler), 0.9 * bound);
  EXPECT_DOUBLE_EQ(lapmesh::automatic_time_step(m, lapmesh::Smoothing_scheme::implicit_euler), h * h);
  // The uniform Laplacian's time step is dimensionless.
  EXPECT_DOUBLE_EQ(lapmesh::automatic_time_step(m, lapmesh::Smoothing_scheme::conformal,
                                                LP::laplacian(lapmesh::Laplacian::uniform)),
                   1.0);
  // The automatic explicit step is stable and follows mean curvature flow: after 5 steps of
  // lambda, r^2 = r0^2 - 4 t with t = 5 lambda (to a few percent at this resolution).
  Mesh s = m;
  const double lambda = lapmesh::automatic_time_step(s, lapmesh::Smoothing_scheme::explicit_euler);
  lapmesh::smooth_laplacian_explicit(s, lambda, CGAL::parameters::number_of_iterations(5));
  const double expected = std::sqrt(4.0 - 4 * 5 * lambda);
  for(auto v : vertices(s))
    EXPECT_NEAR(std::sqrt((s.point(v) - CGAL::ORIGIN).squared_length()), expected, 0.03 * expected);
}

namespace {
// A solver traits object whose factorisation always fails: the smoothing must report it.
struct Failing_solver
{
  using Matrix = CGAL::Eigen_sparse_matrix<double>;
  using Vector = CGAL::Eigen_vector<double>;
  using NT = double;
  bool factor(const Matrix&, NT&) { return false; }
  bool linear_solver(const Vector&, Vector&) { return false; }
};
} // namespace

TEST(Smoothing, UserSparseLinearSolverIsUsed)
{
  // CGAL's sparse_linear_solver: a direct LDL^T and CGAL's default iterative solver (BiCGSTAB
  // with incomplete LU) give the result of the built-in solver; a failing one is reported.
  const Mesh input = to_mesh(lapmesh::bumpy_sphere(3));
  const double lambda = lapmesh::scale_free_time_step(input, 1.0);
  const auto its = CGAL::parameters::number_of_iterations(3);
  Mesh ref = input, direct = input, iterative = input, conformal_ref = input, conformal = input;
  lapmesh::smooth_laplacian_implicit(ref, lambda, its);
  using Ldlt = CGAL::Eigen_solver_traits<Eigen::SimplicialLDLT<CGAL::Eigen_sparse_matrix<double>::EigenType>>;
  const auto rd = lapmesh::smooth_laplacian_implicit(direct, lambda, its.sparse_linear_solver(Ldlt()));
  lapmesh::smooth_laplacian_implicit(iterative, lambda, its.sparse_linear_solver(CGAL::Eigen_solver_traits<>()));
  lapmesh::smooth_conformal_flow(conformal_ref, lambda, its);
  lapmesh::smooth_conformal_flow(conformal, lambda, its.sparse_linear_solver(Ldlt()));
  EXPECT_EQ(rd.factorizations, 3);
  double d_direct = 0, d_iterative = 0, d_conformal = 0, moved = 0;
  for(auto v : vertices(input)) {
    d_direct = std::max(d_direct, std::sqrt(CGAL::squared_distance(ref.point(v), direct.point(v))));
    d_iterative = std::max(d_iterative, std::sqrt(CGAL::squared_distance(ref.point(v), iterative.point(v))));
    d_conformal = std::max(d_conformal, std::sqrt(CGAL::squared_distance(conformal_ref.point(v), conformal.point(v))));
    moved = std::max(moved, std::sqrt(CGAL::squared_distance(ref.point(v), input.point(v))));
  }
  EXPECT_GT(moved, 1e-3);
  EXPECT_LT(d_direct, 1e-12);
  EXPECT_LT(d_conformal, 1e-12);
  EXPECT_LT(d_iterative, 1e-8);
  EXPECT_GT(d_iterative, 0.0);  // a different solver really ran
  Mesh failing = input;
  EXPECT_THROW(lapmesh::smooth_laplacian_implicit(failing, lambda, its.sparse_linear_solver(Failing_solver())),
               lapmesh::Numerical_error);
}

TEST(Smoothing, ExplicitSkipsLanczosWhenGershgorinProvesStability)
{
  Mesh m = to_mesh(lapmesh::icosphere(3));
  const double bound = lapmesh::explicit_stability_bound(m);
  const auto r = lapmesh::smooth_laplacian_explicit(m, 0.2 * bound, CGAL::parameters::number_of_iterations(3));
  EXPECT_FALSE(r.stability_bound_exact);
  EXPECT_FALSE(r.above_stability_bound);
  EXPECT_LE(r.stability_bound, bound);      // Gershgorin is a safe (lower) bound
  EXPECT_GT(r.stability_bound, 0.3 * bound);
}

TEST(Smoothing, ExplicitReportsAKnownStabilityBoundAsGiven)
{
  // A caller that has the bound hands it over: the report holds it as given (here half the true
  // one, which no estimate would give) and judges lambda against it, below the Gershgorin bound
  // and above it, where the smoother would otherwise run Lanczos; the steps are the same.
  const Mesh m = to_mesh(lapmesh::icosphere(3));
  const double bound = lapmesh::explicit_stability_bound(m), given = 0.5 * bound;
  for(double fraction : {0.05, 0.9}) {
    const auto its = CGAL::parameters::number_of_iterations(2);
    Mesh computed = m, handed = m;
    const auto rc = lapmesh::smooth_laplacian_explicit(computed, fraction * bound, its);
    const auto rh = lapmesh::smooth_laplacian_explicit(handed, fraction * bound, LP::known_stability_bound(given, its));
    EXPECT_EQ(rc.stability_bound_exact, fraction > 0.5) << fraction;  // Lanczos above Gershgorin only
    EXPECT_TRUE(rh.stability_bound_exact) << fraction;
    EXPECT_EQ(rh.stability_bound, given) << fraction;
    EXPECT_EQ(rh.above_stability_bound, fraction * bound > given) << fraction;
    EXPECT_FALSE(rc.above_stability_bound) << fraction;
    for(auto v : vertices(m)) ASSERT_EQ(computed.point(v), handed.point(v)) << fraction;
  }
}

TEST(Smoothing, FixedVerticesNeverMoveBitwise)
{
  const Mesh input = to_mesh(bumpy_patch(15));
  auto constrained = get(CGAL::dynamic_vertex_property_t<bool>(), input);
  for(auto v : vertices(input)) put(constrained, v, v.idx() % 5 == 0);
  for(lapmesh::Smoothing_scheme scheme : {lapmesh::Smoothing_scheme::explicit_euler, lapmesh::Smoothing_scheme::implicit_euler,
                                          lapmesh::Smoothing_scheme::conformal})
    for(lapmesh::Laplacian lap : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform}) {
      Mesh m = input;
      const auto np = LP::laplacian(lap).number_of_iterations(5).vertex_is_constrained_map(constrained);
      const double lambda = scheme == lapmesh::Smoothing_scheme::explicit_euler
                              ? 0.5 * lapmesh::explicit_stability_bound(m, np)
                              : lapmesh::scale_free_time_step(m, 1.0, np);
      if(scheme == lapmesh::Smoothing_scheme::explicit_euler) lapmesh::smooth_laplacian_explicit(m, lambda, np);
      else if(scheme == lapmesh::Smoothing_scheme::implicit_euler) lapmesh::smooth_laplacian_implicit(m, lambda, np);
      else lapmesh::smooth_conformal_flow(m, lambda, np);
      int moved = 0;
      for(auto v : vertices(m)) {
        if(get(constrained, v) || m.is_border(v)) {
          ASSERT_TRUE(m.point(v) == input.point(v)) << "vertex " << v.idx();  // bitwise
        } else {
          moved += !(m.point(v) == input.point(v));
        }
      }
      EXPECT_GT(moved, 0);
    }
}

TEST(Smoothing, VolumeRestorationKeepsVolumeAndCentroid)
{
  const Mesh input = to_mesh(lapmesh::bumpy_sphere(3, 0.1, 5.0));
  const double V0 = CGAL::Polygon_mesh_processing::volume(input);
  for(lapmesh::Smoothing_scheme scheme : {lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Smoothing_scheme::conformal}) {
    Mesh plain = input, restored = input;
    const double lambda = lapmesh::scale_free_time_step(input, 2.0);
    if(scheme == lapmesh::Smoothing_scheme::implicit_euler) {
      lapmesh::smooth_laplacian_implicit(plain, lambda, LP::default_values().number_of_iterations(10));
      lapmesh::smooth_laplacian_implicit(restored, lambda, LP::restore_volume(true).number_of_iterations(10));
    } else {
      lapmesh::smooth_conformal_flow(plain, lambda, LP::default_values().number_of_iterations(10));
      lapmesh::smooth_conformal_flow(restored, lambda, LP::restore_volume(true).number_of_iterations(10));
    }
    EXPECT_GT(std::abs(CGAL::Polygon_mesh_processing::volume(plain) - V0) / V0, 1e-2);
    EXPECT_NEAR(CGAL::Polygon_mesh_processing::volume(restored), V0, 1e-9 * V0);
  }
}

// Area-weighted centroid of the faces, written here independently of the engine.
Eigen::RowVector3d area_centroid(const Mesh& m)
{
  Eigen::RowVector3d c = Eigen::RowVector3d::Zero();
  double total = 0;
  for(auto f : faces(m)) {
    const double a = CGAL::Polygon_mesh_processing::face_area(f, m);
    for(auto v : vertices_around_face(halfedge(f, m), m))
      c += a / 3.0 * Eigen::RowVector3d(m.point(v).x(), m.point(v).y(), m.point(v).z());
    total += a;
  }
  return c / total;
}

TEST(Smoothing, FreeBoundaryIsTheNeumannProblemAndAreaRestorationKeepsAreaAndCentroid)
{
  const Mesh input = to_mesh(bumpy_patch(12));
  const int n = int(num_vertices(input));
  const double lambda = lapmesh::scale_free_time_step(input, 0.2);
  // The free boundary is the unconstrained system: the dense reference with no fixed vertex.
  {
    Eigen::MatrixXd X = positions(input);
    Mesh state = input;
    for(int k = 0; k < 3; ++k) {
      const auto pencil = lapmesh::laplacian_pencil(state);
      X = dense_implicit_step(Eigen::MatrixXd(pencil.stiffness), pencil.mass, X, lambda, std::vector<bool>(n, false));
      for(auto v : vertices(state)) state.point(v) = Point(X(v.idx(), 0), X(v.idx(), 1), X(v.idx(), 2));
    }
    Mesh m = input;
    lapmesh::smooth_laplacian_implicit(m, lambda, LP::fix_boundary(false).number_of_iterations(3));
    EXPECT_LE((positions(m) - X).cwiseAbs().maxCoeff(), 1e-12);
    double boundary_move = 0;
    for(auto v : vertices(m))
      if(m.is_border(v)) boundary_move = std::max(boundary_move, (positions(m) - positions(input)).row(v.idx()).norm());
    EXPECT_GT(boundary_move, 1e-3);
  }
  const double A0 = CGAL::Polygon_mesh_processing::area(input);
  const Eigen::RowVector3d c0 = area_centroid(input);
  for(lapmesh::Smoothing_scheme scheme : {lapmesh::Smoothing_scheme::explicit_euler, lapmesh::Smoothing_scheme::implicit_euler,
                                          lapmesh::Smoothing_scheme::conformal}) {
    Mesh plain = input, restored = input;
    const double step = scheme == lapmesh::Smoothing_scheme::explicit_euler
                          ? 0.5 * lapmesh::explicit_stability_bound(input, LP::fix_boundary(false))
                          : lambda;
    auto smooth = [&](Mesh& m, bool restore) {
      // (a few steps: with a free boundary the flow collapses the corner triangles of the square
      // after about 7 implicit steps, and the rebuilt operator then stops with a clear error)
      const auto np = LP::restore_area(restore, LP::fix_boundary(false)).number_of_iterations(4);
      switch(scheme) {
        case lapmesh::Smoothing_scheme::explicit_euler: lapmesh::smooth_laplacian_explicit(m, step, np); break;
        case lapmesh::Smoothing_scheme::implicit_euler: lapmesh::smooth_laplacian_implicit(m, step, np); break;
        default: lapmesh::smooth_conformal_flow(m, step, np);
      }
    };
    smooth(plain, false);
    smooth(restored, true);
    const std::string name = lapmesh::to_string(scheme);
    EXPECT_LT(CGAL::Polygon_mesh_processing::area(plain), (1 - 1e-2) * A0) << name;  // the flow shrinks it
    EXPECT_NEAR(CGAL::Polygon_mesh_processing::area(restored), A0, 1e-12 * A0) << name;
    EXPECT_LE((area_centroid(restored) - c0).norm(), 1e-12) << name;
  }
}

TEST(Smoothing, ShapeRestorationRefusesWhatItCannotDo)
{
  const Mesh patch = to_mesh(bumpy_patch(6));
  const Mesh sphere = to_mesh(lapmesh::icosphere(2));
  auto refuses = [](Mesh m, const auto& np, const std::string& expected) {
    try {
      lapmesh::smooth_laplacian_implicit(m, 1e-3, np);
      ADD_FAILURE() << "no exception, expected: " << expected;
    } catch(const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  refuses(patch, LP::restore_area(true), "fix_boundary(false)");          // the boundary is fixed
  refuses(patch, LP::restore_volume(true, LP::fix_boundary(false)), "closed mesh");  // no volume
  refuses(sphere, LP::restore_volume(true, LP::restore_area(true)), "not both");
  auto constrained = get(CGAL::dynamic_vertex_property_t<bool>(), sphere);
  for(auto v : vertices(sphere)) put(constrained, v, v.idx() == 0);
  refuses(sphere, LP::restore_area(true).vertex_is_constrained_map(constrained), "constrained");
}

// CGAL 5.5.1's smooth_shape solves (M/2 - 2t C_0) P' = (M/2) P: its mass is area/6 per face
// corner (half the barycentric area) and its weights (Edge_cotangent_weight: cot a + cot b
// inside, a single cot on the border) are twice lapmesh's C, so CGAL's time t is lapmesh's
// lambda = 4t. On closed meshes with no constrained vertex it rescales about the volume centroid
// to the previous volume after each step, which is what restore_volume does. Constrained rows
// are identity rows. Its default solver is BiCGSTAB + ILUT; with a direct solver (SparseLU:
// the constrained rows make the matrix unsymmetric) both must agree to round-off.
TEST(Smoothing, ConformalFlowAgreesWithCgalSmoothShape)
{
  using Lu_solver = CGAL::Eigen_solver_traits<
    Eigen::SparseLU<CGAL::Eigen_sparse_matrix<double>::EigenType, Eigen::COLAMDOrdering<int>>>;
  auto max_difference = [](const Mesh& a, const Mesh& b) { return (positions(a) - positions(b)).cwiseAbs().maxCoeff(); };
  auto diagonal = [](const Mesh& m) {
    const Eigen::MatrixXd P = positions(m);
    return (P.colwise().maxCoeff() - P.colwise().minCoeff()).norm();
  };
  {
    // Open patch, border constrained in CGAL (lapmesh fixes the border anyway): no rescaling.
    const Mesh input = to_mesh(bumpy_patch(14));
    auto border = get(CGAL::dynamic_vertex_property_t<bool>(), input);
    for(auto v : vertices(input)) put(border, v, input.is_border(v));
    const double t = 0.003;
    Mesh cgal = input, cgal_default = input, ours = input;
    CGAL::Polygon_mesh_processing::smooth_shape(
      cgal, t, CGAL::parameters::number_of_iterations(5).vertex_is_constrained_map(border).sparse_linear_solver(Lu_solver()));
    CGAL::Polygon_mesh_processing::smooth_shape(
      cgal_default, t, CGAL::parameters::number_of_iterations(5).vertex_is_constrained_map(border));
    lapmesh::smooth_conformal_flow(ours, 4 * t, CGAL::parameters::number_of_iterations(5));
    const double diag = diagonal(input);
    std::cout << "open patch: moved " << max_difference(ours, input) / diag << ", |ours - CGAL LU| " << max_difference(ours, cgal) / diag
              << ", |ours - CGAL BiCGSTAB| " << max_difference(ours, cgal_default) / diag << " (/ bbox diagonal)\n";
    EXPECT_GT(max_difference(ours, input), 1e-2 * diag);  // it moved
    EXPECT_LE(max_difference(ours, cgal), 1e-12 * diag);
    EXPECT_LE(max_difference(ours, cgal_default), 1e-8 * diag);
    double border_moved = 0;
    for(auto v : vertices(input))
      if(input.is_border(v)) border_moved = std::max(border_moved, std::sqrt(CGAL::squared_distance(cgal_default.point(v), input.point(v))));
    std::cout << "open patch: CGAL (BiCGSTAB) moved constrained vertices by up to " << border_moved / diag << " / diagonal\n";
  }
  {
    // Closed mesh, no constraints: CGAL rescales to the previous volume about the volume centroid.
    const Mesh input = to_mesh(lapmesh::bumpy_sphere(3));
    const double t = 0.002;
    Mesh cgal = input, ours = input;
    CGAL::Polygon_mesh_processing::smooth_shape(cgal, t, CGAL::parameters::number_of_iterations(5).sparse_linear_solver(Lu_solver()));
    lapmesh::smooth_conformal_flow(ours, 4 * t, LP::restore_volume(true).number_of_iterations(5));
    const double diag = diagonal(input);
    std::cout << "closed bumpy sphere: moved " << max_difference(ours, input) / diag << ", |ours - CGAL LU| "
              << max_difference(ours, cgal) / diag << " (/ bbox diagonal)\n";
    EXPECT_GT(max_difference(ours, input), 1e-2 * diag);
    EXPECT_LE(max_difference(ours, cgal), 1e-12 * diag);
  }
  {
    // Closed mesh with two constrained vertices: CGAL does not rescale then (one constrained
    // vertex would be its scaling anchor); the constrained rows are identity rows, so with a
    // direct solver they stay bitwise, and the flow matches lapmesh's Dirichlet solve.
    const Mesh input = to_mesh(lapmesh::bumpy_sphere(3));
    auto constrained = get(CGAL::dynamic_vertex_property_t<bool>(), input);
    for(auto v : vertices(input)) put(constrained, v, v.idx() == 0 || v.idx() == 7);
    const double t = 0.002;
    Mesh cgal = input, ours = input;
    CGAL::Polygon_mesh_processing::smooth_shape(
      cgal, t, CGAL::parameters::number_of_iterations(5).vertex_is_constrained_map(constrained).sparse_linear_solver(Lu_solver()));
    lapmesh::smooth_conformal_flow(ours, 4 * t, CGAL::parameters::number_of_iterations(5).vertex_is_constrained_map(constrained));
    const double diag = diagonal(input);
    std::cout << "closed, 2 constrained: |ours - CGAL LU| " << max_difference(ours, cgal) / diag << " (/ bbox diagonal)\n";
    EXPECT_LE(max_difference(ours, cgal), 1e-12 * diag);
    for(auto v : vertices(input)) {
      if(get(constrained, v)) {
        EXPECT_TRUE(cgal.point(v) == input.point(v));
      }
    }
  }
}

TEST(Smoothing, SmoothingANoisySphereLowersTheError)
{
  const Mesh clean = to_mesh(lapmesh::icosphere(4));
  Mesh noisy = clean;
  lapmesh::add_noise(noisy, 0.3, CGAL::parameters::random_seed(1));
  auto error = [&](const Mesh& m) {  // RMS distance to the clean (unit) sphere
    return std::sqrt((positions(m).rowwise().norm().array() - 1.0).square().mean());
  };
  const double e0 = error(noisy);
  for(lapmesh::Laplacian lap : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform}) {
    Mesh m = noisy;
    lapmesh::smooth_laplacian_implicit(m, lapmesh::scale_free_time_step(m, 0.5, LP::laplacian(lap)),
                                       LP::restore_volume(true, LP::laplacian(lap)).number_of_iterations(2));
    std::cout << lapmesh::to_string(lap) << " " << e0 << " -> " << error(m) << "\n";
    EXPECT_LT(error(m), 0.6 * e0) << lapmesh::to_string(lap);
  }
  Mesh m = noisy;
  const double bound = lapmesh::explicit_stability_bound(m);
  lapmesh::smooth_laplacian_explicit(m, 0.5 * bound, LP::restore_volume(true).number_of_iterations(60));
  std::cout << "explicit " << e0 << " -> " << error(m) << "\n";
  EXPECT_LT(error(m), 0.6 * e0);
}

TEST(Smoothing, RejectsBadArguments)
{
  Mesh m = to_mesh(lapmesh::icosphere(1));
  const Mesh copy = m;
  for(double bad : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()})
    EXPECT_THROW(lapmesh::smooth_laplacian_implicit(m, bad), std::invalid_argument);
  EXPECT_THROW(lapmesh::smooth_laplacian_explicit(m, 0.1, CGAL::parameters::number_of_iterations(0)), std::invalid_argument);
  EXPECT_EQ((positions(m) - positions(copy)).cwiseAbs().maxCoeff(), 0.0);
}

// ---- command line -------------------------------------------------------------------

namespace {

std::string write_sphere()
{
  const std::string path = lapmesh_test::scratch_dir() + "/smooth_in.off";
  const Mesh m = to_mesh(lapmesh::icosphere(2));
  const auto [P, tris] = lapmesh::io::mesh_arrays(m);
  lapmesh::io::write_mesh(path, P, tris);
  return path;
}

} // namespace

TEST(SmoothingCli, BadLambdaOrIterationsFailCleanly)
{
  const std::string in = write_sphere();
  const std::string out = lapmesh_test::scratch_dir() + "/smooth_out.off";
  const std::vector<std::string> bad = {
    "--lambda 0 --iterations 3",      "--lambda -0.5 --iterations 3", "--lambda nan --iterations 3",
    "--lambda inf --iterations 3",    "--lambda abc --iterations 3",  "--lambda 0.01 --iterations 0",
    "--lambda 0.01 --iterations -2"};
  for(const std::string scheme : {"explicit", "implicit"})
    run_test_cases(bad, [&](const std::string& args) {
      std::filesystem::remove(out);
      const Cli_result r = run_lapmesh("smooth " + in + " -o " + out + " --scheme " + scheme + " " + args);
      EXPECT_NE(r.status, 0) << args;
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
      EXPECT_NE(r.err.find(in), std::string::npos) << r.err;
      EXPECT_FALSE(std::filesystem::exists(out)) << args;
    });
}

TEST(SmoothingCli, RestoreAreaNeedsAFreeBoundary)
{
  const std::string in = lapmesh_test::scratch_dir() + "/patch.off";
  {
    const lapmesh::Triangle_soup soup = bumpy_patch(6);
    Mesh m = to_mesh(soup);
    const auto [P, tris] = lapmesh::io::mesh_arrays(m);
    lapmesh::io::write_mesh(in, P, tris);
  }
  const std::string out = lapmesh_test::scratch_dir() + "/patch_out.off";
  std::filesystem::remove(out);
  Cli_result r = run_lapmesh("smooth " + in + " -o " + out + " --scheme implicit --lambda 1 --lambda-unit edge2 --iterations 2 --restore-area");
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("--free-boundary"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
  r = run_lapmesh("smooth " + in + " -o " + out +
              " --scheme implicit --lambda 1 --lambda-unit edge2 --iterations 2 --restore-area --free-boundary");
  EXPECT_EQ(r.status, 0) << r.err;
  Mesh original, got;
  lapmesh::io::read_triangle_mesh(in, original);
  lapmesh::io::read_triangle_mesh(out, got);
  EXPECT_NEAR(CGAL::Polygon_mesh_processing::area(got), CGAL::Polygon_mesh_processing::area(original),
              1e-12 * CGAL::Polygon_mesh_processing::area(original));
}

TEST(SmoothingCli, SmoothAndNoiseWriteMeshes)
{
  const std::string in = write_sphere();
  const std::string out = lapmesh_test::scratch_dir() + "/smooth_ok.off";
  std::filesystem::remove(out);
  Cli_result r = run_lapmesh("smooth " + in + " -o " + out + " --scheme implicit --lambda 0.001 --iterations 2");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(std::filesystem::exists(out));
  // The CLI output equals the library's result to the printed precision.
  Mesh expected = to_mesh(lapmesh::icosphere(2));
  lapmesh::smooth_laplacian_implicit(expected, 0.001, CGAL::parameters::number_of_iterations(2));
  Mesh got;
  lapmesh::io::read_triangle_mesh(out, got);
  EXPECT_LE((positions(got) - positions(expected)).cwiseAbs().maxCoeff(), 1e-15);

  const std::string n1 = lapmesh_test::scratch_dir() + "/noise1.off", n2 = lapmesh_test::scratch_dir() + "/noise2.off";
  EXPECT_EQ(run_lapmesh("noise " + in + " -o " + n1 + " --level 0.1 --seed 5").status, 0);
  EXPECT_EQ(run_lapmesh("noise " + in + " -o " + n2 + " --level 0.1 --seed 5").status, 0);
  std::ifstream a(n1), b(n2);
  std::stringstream sa, sb;
  sa << a.rdbuf();
  sb << b.rdbuf();
  EXPECT_EQ(sa.str(), sb.str());
  r = run_lapmesh("noise " + in + " -o " + n1 + " --level -1");
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

namespace {

// Runs the CLI and returns its stdout (empty on a non-zero status).
std::string cli_stdout(const std::string& args)
{
  const Cli_result r = run_lapmesh(args);
  return r.status == 0 ? r.out : std::string();
}

double printed_bound(const std::string& line)
{
  const std::string key = "stability bound ";
  const auto at = line.find(key);
  return at == std::string::npos ? std::nan("") : std::strtod(line.c_str() + at + key.size(), nullptr);
}

} // namespace

// `lapmesh smooth` printed the smoother's Gershgorin lower bound when lambda was small and the
// Lanczos bound with --lambda auto: one mesh, two "stability bounds". Every path now prints
// explicit_stability_bound() of the free vertices, which the dense eigen-solve above checks.
TEST(SmoothingCli, OneStabilityBoundWhateverTheLambda)
{
  const std::string closed = lapmesh_test::scratch_dir() + "/bound_closed.off";
  const std::string open = lapmesh_test::scratch_dir() + "/bound_open.off";
  for(const auto& [path, soup] : {std::pair{closed, lapmesh::icosphere(3)}, std::pair{open, bumpy_patch(12)}}) {
    const Mesh m = jittered(soup, 0.02, 7);
    const auto [P, tris] = lapmesh::io::mesh_arrays(m);
    lapmesh::io::write_mesh(path, P, tris);
  }
  const std::string out = lapmesh_test::scratch_dir() + "/bound_out.off";
  for(const std::string& in : {closed, open})
    for(const std::string lap : {"cotangent", "uniform"})
      for(const std::string boundary : {"", " --free-boundary"}) {
        Mesh m;
        lapmesh::io::read_triangle_mesh(in, m);
        const auto np = LP::fix_boundary(boundary.empty(), LP::laplacian(*lapmesh::parse_laplacian(lap)));
        const double bound = lapmesh::explicit_stability_bound(m, np);
        // The case that printed the other number: a lambda the Gershgorin bound already proves stable.
        Mesh copy = m;
        const auto r = lapmesh::smooth_laplacian_explicit(copy, 1e-3 * bound, np);
        EXPECT_FALSE(r.stability_bound_exact);
        EXPECT_LT(r.stability_bound, 0.99 * bound) << in << ' ' << lap;

        const std::string common = "smooth " + in + " -o " + out + " --scheme explicit --iterations 1 --laplacian " + lap + boundary;
        std::vector<double> printed;
        auto number = [](double x) {
          std::ostringstream os;
          os.precision(17);
          os << x;
          return os.str();
        };
        const std::vector<std::string> lambdas = {" --lambda " + number(1e-3 * bound), " --lambda auto",
                                                  " --lambda 0.5 --lambda-unit bound", " --lambda " + number(3 * bound)};
        for(const std::string& lambda : lambdas)
          printed.push_back(printed_bound(cli_stdout(common + lambda)));
        for(double b : printed) EXPECT_NEAR(b, bound, 1e-5 * bound) << in << ' ' << lap << boundary;  // 6 digits printed
      }
}

// lapmesh::bumpy_box(), the report's stand-in for the course's bumpy mesh: a closed, outward
// oriented, irregular triangulation of its surface, reproducible from its seed.
TEST(Shapes, BumpyBoxIsAnIrregularClosedSampleOfItsSurface)
{
  const lapmesh::Triangle_soup soup = lapmesh::bumpy_box(1);
  EXPECT_GE(soup.points.size(), 1100u);
  EXPECT_LE(soup.points.size(), 1350u);
  Mesh m;
  ASSERT_TRUE(lapmesh::make_mesh(soup, m));
  EXPECT_TRUE(CGAL::is_closed(m));
  EXPECT_EQ(long(num_vertices(m)) - long(num_edges(m)) + long(num_faces(m)), 2);  // a sphere's topology
  EXPECT_GT(CGAL::Polygon_mesh_processing::volume(m), 0.0);                          // outward normals

  double lo = 1e9, hi = -1e9, min_angle = 180, min_edge = 1e9;
  for(const auto& p : soup.points) {
    const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    const auto q = lapmesh::bumpy_box_surface_point({p[0] / r, p[1] / r, p[2] / r});
    EXPECT_NEAR(std::hypot(q[0] - p[0], q[1] - p[1], q[2] - p[2]), 0.0, 1e-12);  // on the surface
    for(double c : p) { lo = std::min(lo, c); hi = std::max(hi, c); }
  }
  EXPECT_NEAR(lo, -4.4, 1e-9);  // the bump tips are vertices
  EXPECT_NEAR(hi, 4.4, 1e-9);
  std::set<int> valences;
  for(auto v : vertices(m)) valences.insert(int(degree(v, m)));
  EXPECT_GE(valences.size(), 4u);  // irregular: not a subdivision's valence-6 lattice
  for(auto f : faces(m)) {
    std::array<Eigen::Vector3d, 3> c;
    int i = 0;
    for(auto v : vertices_around_face(halfedge(f, m), m)) c[i++] << m.point(v).x(), m.point(v).y(), m.point(v).z();
    for(int k = 0; k < 3; ++k) {
      const Eigen::Vector3d u = c[(k + 1) % 3] - c[k], w = c[(k + 2) % 3] - c[k];
      min_angle = std::min(min_angle, std::acos(u.dot(w) / (u.norm() * w.norm())) * 180 / M_PI);
      min_edge = std::min(min_edge, u.norm());
    }
  }
  EXPECT_GT(min_angle, 20.0);            // Delaunay on the surface: no needles
  EXPECT_GE(min_edge, 0.3 * (1 - 1e-12)); // the Poisson-disk spacing

  const auto again = lapmesh::bumpy_box(1), other = lapmesh::bumpy_box(2);
  EXPECT_EQ(again.points, soup.points);
  EXPECT_EQ(again.triangles, soup.triangles);
  EXPECT_NE(other.points, soup.points);
  EXPECT_THROW(lapmesh::bumpy_box(1, 0.01), std::invalid_argument);
  EXPECT_THROW(lapmesh::bumpy_box(1, std::nan("")), std::invalid_argument);
}
