// The intrinsic Delaunay Laplacian: flips make every weight >= 0 and every interior edge
// Delaunay, on a Delaunay mesh it is the cotangent Laplacian, the flips keep the surface
// (area, Gauss–Bonnet), and its heat flow obeys the maximum principle where the cotangent
// Laplacian's does not.
#include "test_helpers.h"

#include <lapmesh/curvature.h>
#include <lapmesh/internal/intrinsic_triangulation.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include <Eigen/SparseCholesky>

#include <fstream>
#include <random>

using namespace lapmesh_test;
namespace LP = lapmesh::parameters;
using lapmesh::Laplacian;

namespace {

// The soup with every vertex moved by a seeded Gaussian of `sigma` (tangentially and normally):
// obtuse triangles and negative cotangent weights appear from sigma ~ 0.2 edge lengths.
lapmesh::Triangle_soup jittered(lapmesh::Triangle_soup s, double sigma, unsigned seed)
{
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sigma);
  for(auto& p : s.points)
    for(double& c : p) c += g(rng);
  return s;
}

// A sphere whose triangles include slivers: every other vertex pulled towards a neighbour.
lapmesh::Triangle_soup sliver_sphere(int level)
{
  lapmesh::Triangle_soup s = lapmesh::icosphere(level);
  for(const auto& t : s.triangles) {
    auto& p = s.points[std::size_t(t[0])];
    const auto& q = s.points[std::size_t(t[1])];
    if(t[0] % 5 == 0)
      for(int c = 0; c < 3; ++c) p[c] = 0.1 * p[c] + 0.9 * q[c];
  }
  return s;
}

double min_off_diagonal(const Eigen::SparseMatrix<double>& S)
{
  double lowest = std::numeric_limits<double>::infinity();
  for(int k = 0; k < S.outerSize(); ++k)
    for(Eigen::SparseMatrix<double>::InnerIterator it(S, k); it; ++it)
      if(it.row() != it.col()) lowest = std::min(lowest, it.value());
  return lowest;
}

lapmesh::Laplacian_pencil pencil(const Mesh& m, Laplacian kind)
{
  return lapmesh::laplacian_pencil(m, LP::laplacian(kind));
}

// One backward Euler step of heat diffusion (M - t S) u = M u0, by an independent solver.
Eigen::VectorXd heat_step(const lapmesh::Laplacian_pencil& p, const Eigen::VectorXd& u0, double t)
{
  Eigen::SparseMatrix<double> A = -t * p.stiffness;
  for(int i = 0; i < A.rows(); ++i) A.coeffRef(i, i) += p.mass[i];
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
  return solver.solve(p.mass.cwiseProduct(u0));
}

} // namespace

TEST(IntrinsicDelaunay, WeightsBecomeNonNegativeAndEdgesDelaunay)
{
  struct Case
  {
    std::string name;
    lapmesh::Triangle_soup soup;
  };
  const std::vector<Case> cases = {{"jittered sphere", jittered(lapmesh::icosphere(3), 0.02, 7)},
                                   {"jittered patch", lapmesh::plane_patch(12, 0.45, 3)},
                                   {"sliver sphere", sliver_sphere(3)}};
  run_test_cases(cases, [](const Case& c) { return c.name; }, [](const Case& c) {
    const Mesh m = to_mesh(c.soup);
    const auto plain = pencil(m, Laplacian::cotangent);
    const auto intrinsic = pencil(m, Laplacian::intrinsic_delaunay);
    EXPECT_LT(min_off_diagonal(plain.stiffness), -1e-3) << "the case must have negative cotangent weights";
    EXPECT_GE(min_off_diagonal(intrinsic.stiffness), -1e-12);

    const auto mesh = lapmesh::internal::extract_mesh(m, CGAL::parameters::default_values());
    lapmesh::internal::Intrinsic_triangulation it(mesh.topology, mesh.positions);
    double area_before = 0, area_after = 0;
    for(int f = 0; f < it.num_faces(); ++f) area_before += it.face_area(f);
    EXPECT_FALSE(it.is_delaunay());
    const auto stats = it.flip_to_delaunay();
    EXPECT_GT(stats.flips, 0);
    EXPECT_TRUE(it.is_delaunay());
    for(int f = 0; f < it.num_faces(); ++f) area_after += it.face_area(f);
    EXPECT_NEAR(area_after, area_before, 1e-12 * area_before);  // flips keep the surface

    // L 1 = 0, symmetry, and the barycentric mass sums to the surface area.
    const Eigen::VectorXd ones = Eigen::VectorXd::Ones(intrinsic.mass.size());
    EXPECT_LT((intrinsic.stiffness * ones).cwiseAbs().maxCoeff(), 1e-10 * intrinsic.stiffness.cwiseAbs().sum());
    const Eigen::SparseMatrix<double> St = intrinsic.stiffness.transpose();
    EXPECT_EQ((St - intrinsic.stiffness).norm(), 0.0);
    EXPECT_NEAR(intrinsic.mass.sum(), area_before, 1e-12 * area_before);
  });
}

TEST(IntrinsicDelaunay, OnADelaunayMeshItIsTheCotangentLaplacian)
{
  const Mesh m = to_mesh(lapmesh::icosphere(3));
  const auto mesh = lapmesh::internal::extract_mesh(m, CGAL::parameters::default_values());
  lapmesh::internal::Intrinsic_triangulation it(mesh.topology, mesh.positions);
  EXPECT_TRUE(it.is_delaunay());
  EXPECT_EQ(it.flip_to_delaunay().flips, 0);
  for(auto area : {lapmesh::Vertex_area::barycentric, lapmesh::Vertex_area::voronoi, lapmesh::Vertex_area::mixed}) {
    const auto plain = lapmesh::laplacian_pencil(m, LP::vertex_area(area, LP::laplacian(Laplacian::cotangent)));
    const auto intrinsic =
      lapmesh::laplacian_pencil(m, LP::vertex_area(area, LP::laplacian(Laplacian::intrinsic_delaunay)));
    const Eigen::MatrixXd difference = Eigen::MatrixXd(plain.stiffness) - Eigen::MatrixXd(intrinsic.stiffness);
    EXPECT_LT(difference.cwiseAbs().maxCoeff(), 1e-12) << lapmesh::to_string(area);
    EXPECT_LT((plain.mass - intrinsic.mass).cwiseAbs().maxCoeff(), 1e-14) << lapmesh::to_string(area);
  }
}

TEST(IntrinsicDelaunay, HeatFlowKeepsTheMaximumPrincipleWhereCotangentDoesNot)
{
  // A unit spike at one vertex diffused by one implicit step: (M - t S)^-1 M is entrywise
  // non-negative when every off-diagonal weight is >= 0, so u stays in [0, 1]. A short step
  // shows a negative weight: u_i ~ t S_iv / M_i next to the spike.
  const Mesh m = to_mesh(lapmesh::plane_patch(12, 0.45, 3));
  const auto plain = pencil(m, Laplacian::cotangent);
  const auto intrinsic = pencil(m, Laplacian::intrinsic_delaunay);
  const double t = 0.1 * plain.mass.mean();
  double plain_lowest = 0, intrinsic_lowest = 0, intrinsic_highest = 0;
  for(int v = 0; v < int(plain.mass.size()); ++v) {
    Eigen::VectorXd u0 = Eigen::VectorXd::Zero(plain.mass.size());
    u0[v] = 1;
    plain_lowest = std::min(plain_lowest, heat_step(plain, u0, t).minCoeff());
    const Eigen::VectorXd u = heat_step(intrinsic, u0, t);
    intrinsic_lowest = std::min(intrinsic_lowest, u.minCoeff());
    intrinsic_highest = std::max(intrinsic_highest, u.maxCoeff());
  }
  EXPECT_LT(plain_lowest, -1e-6) << "the cotangent Laplacian must leave the range on this mesh";
  EXPECT_GE(intrinsic_lowest, -1e-13);
  EXPECT_LE(intrinsic_highest, 1 + 1e-13);
}

TEST(IntrinsicDelaunay, GaussBonnetAndSpectrumOfJitteredSpheres)
{
  for(const auto& [name, soup] : std::vector<std::pair<std::string, lapmesh::Triangle_soup>>{
        {"jittered", jittered(lapmesh::icosphere(3), 0.02, 11)}, {"slivers", sliver_sphere(3)}}) {
    const Mesh m = to_mesh(soup);
    const auto c = lapmesh::vertex_curvatures(m, LP::laplacian(Laplacian::intrinsic_delaunay));
    EXPECT_NEAR(c.gaussian.dot(c.area), 4 * M_PI, 1e-10) << name;  // a sphere: chi = 2
    EXPECT_TRUE(c.mean.allFinite()) << name;
    // The first 16 eigenvalues against l (l + 1) on the unit sphere: measured for both
    // operators (the mass changes too, so no ordering between them is assumed).
    const auto plain = lapmesh::laplacian_eigenvalues(m, 16, LP::laplacian(Laplacian::cotangent));
    const auto intrinsic = lapmesh::laplacian_eigenvalues(m, 16, LP::laplacian(Laplacian::intrinsic_delaunay));
    double plain_error = 0, intrinsic_error = 0;
    for(int i = 1; i < 16; ++i) {
      const int l = i < 4 ? 1 : i < 9 ? 2 : 3;
      plain_error = std::max(plain_error, std::abs(plain[i] / (l * (l + 1)) - 1));
      intrinsic_error = std::max(intrinsic_error, std::abs(intrinsic[i] / (l * (l + 1)) - 1));
    }
    std::cout << name << ": largest relative error of lambda_1..15 against l(l+1): cotangent " << plain_error
              << ", intrinsic Delaunay " << intrinsic_error << '\n';
    EXPECT_LT(intrinsic_error, 0.2) << name;
    EXPECT_GE(intrinsic[0], -1e-9) << name;
  }
}

TEST(IntrinsicDelaunay, EverySubcommandTakesIt)
{
  // A sliver-heavy sphere written as OFF, then every subcommand with --laplacian
  // intrinsic-delaunay: exit 0 and finite numbers in every output.
  const lapmesh::Triangle_soup soup = sliver_sphere(2);
  const std::string dir = scratch_dir();
  const std::string in = dir + "/intrinsic_slivers.off";
  {
    std::ofstream os(in);
    os.precision(17);
    os << "OFF\n" << soup.points.size() << ' ' << soup.triangles.size() << " 0\n";
    for(const auto& p : soup.points) os << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
    for(const auto& t : soup.triangles) os << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  }
  const std::string L = " --laplacian intrinsic-delaunay";
  const std::vector<std::pair<std::string, std::string>> runs = {
    {"curvature " + in + " -o " + dir + "/i_curv.csv" + L, dir + "/i_curv.csv"},
    {"spectrum " + in + " -o " + dir + "/i_spec.csv -k 10" + L, dir + "/i_spec.csv"},
    {"reconstruct " + in + " -o " + dir + "/i_rec.off -k 10" + L, dir + "/i_rec.off"},
    {"smooth " + in + " -o " + dir + "/i_exp.off --scheme explicit --lambda auto --iterations 5" + L, dir + "/i_exp.off"},
    {"smooth " + in + " -o " + dir + "/i_imp.off --scheme implicit --lambda 1 --lambda-unit edge2 --iterations 5" + L,
     dir + "/i_imp.off"},
    {"smooth " + in + " -o " + dir + "/i_conf.off --scheme conformal --lambda auto --iterations 3" + L, dir + "/i_conf.off"},
    {"denoise-study " + in + " -o " + dir + "/i_study.csv --levels 0.1 --schemes implicit --laplacians intrinsic-delaunay "
                                             "--lambdas 1 --iterations 2 -q",
     dir + "/i_study.csv"},
  };
  run_test_cases(runs, [](const auto& r) { return r.first; }, [](const auto& r) {
    const Cli_result result = run_lapmesh(r.first);
    ASSERT_EQ(result.status, 0) << result.err;
    const std::string text = read_file(r.second);
    EXPECT_FALSE(text.empty());
    EXPECT_EQ(text.find("nan"), std::string::npos);
    EXPECT_EQ(text.find("inf"), std::string::npos);
  });
}
