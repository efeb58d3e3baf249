// The intrinsic Delaunay Laplacian: flips make every weight >= 0 and every interior edge
// Delaunay, on a Delaunay mesh it is the cotangent Laplacian, the flips keep the surface
// (area, Gauss–Bonnet), and its heat flow obeys the maximum principle where the cotangent
// Laplacian's does not.
#include "test_helpers.h"

#include <lapmesh/curvature.h>
#include <lapmesh/internal/intrinsic_triangulation.h>
#include <lapmesh/internal/laplacian_assembly.h>
#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include <Eigen/SparseCholesky>

#include <fstream>
#include <functional>
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

// Two cones of `n` faces each over a ring of `n` vertices whose radii vary at random: apexes of
// n corners, and flips at the ring where two neighbours' radii differ enough.
lapmesh::Triangle_soup jittered_bipyramid(int n, unsigned seed)
{
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> radius(0.7, 1.3);
  lapmesh::Triangle_soup s;
  for(int k = 0; k < n; ++k) {
    const double angle = 2 * M_PI * k / n, r = radius(rng);
    s.points.push_back({r * std::cos(angle), r * std::sin(angle), 0});
  }
  s.points.push_back({0, 0, 0.3});
  s.points.push_back({0, 0, -0.3});
  for(int k = 0; k < n; ++k) {
    s.triangles.push_back({k, (k + 1) % n, n});
    s.triangles.push_back({(k + 1) % n, k, n + 1});
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
    EXPECT_NEAR(intrinsic.mass.sum(), area_before / it.sheets(), 1e-12 * area_before);  // per sheet
    EXPECT_EQ(it.sheets(), c.name == "jittered patch" ? 2 : 1);  // open: the tufted cover
  });
}

// The stiffness is written column by column from the halfedges; here it is summed corner by
// corner from triplets instead, on flipped triangulations with repeated edges and loops, and
// with columns of a few hundred rows (the apexes of two cones).
TEST(IntrinsicDelaunay, ColumnAssemblyEqualsTheCornerByCornerSum)
{
  const std::vector<std::pair<std::string, lapmesh::Triangle_soup>> cases = {
    {"jittered sphere", jittered(lapmesh::icosphere(3), 0.02, 7)},
    {"jittered patch", lapmesh::plane_patch(12, 0.45, 3)},
    {"sliver sphere", sliver_sphere(3)},
    {"two cones of 300 faces over a jittered ring", jittered_bipyramid(300, 3)}};
  for(const auto& [name, soup] : cases) {
    const Mesh m = to_mesh(soup);
    const auto mesh = lapmesh::internal::extract_mesh(m, CGAL::parameters::default_values());
    lapmesh::internal::Intrinsic_triangulation it(mesh.topology, mesh.positions);
    ASSERT_GT(it.flip_to_delaunay().flips, 0) << name;
    Eigen::SparseMatrix<double> S;
    Eigen::VectorXd mass;
    lapmesh::internal::assemble_intrinsic_pencil(it, lapmesh::Vertex_area::barycentric, S, mass);

    using T = lapmesh::internal::Intrinsic_triangulation;
    const int n = it.num_vertices();
    std::vector<Eigen::Triplet<double>> entries;
    Eigen::VectorXd expected_mass = Eigen::VectorXd::Zero(n);
    for(int c = 0; c < 3 * it.num_faces(); ++c) {
      expected_mass[it.triangles()[c]] += it.face_area(c / 3) / 3 / it.sheets();
      const int h = T::halfedge_opposite(c);
      const int i = it.triangles()[h], j = it.triangles()[T::next_of(h)];
      const double w = 0.5 * it.corner_cotangent(c) / it.sheets();
      entries.emplace_back(i, j, w);
      entries.emplace_back(j, i, w);
      entries.emplace_back(i, i, -w);
      entries.emplace_back(j, j, -w);
    }
    Eigen::SparseMatrix<double> expected(n, n);
    expected.setFromTriplets(entries.begin(), entries.end());
    const double scale = expected.cwiseAbs().sum() / n;
    EXPECT_LT((S - expected).cwiseAbs().sum(), 1e-13 * scale * n) << name;
    EXPECT_LT((mass - expected_mass).cwiseAbs().maxCoeff(), 1e-15 * expected_mass.maxCoeff() * 10) << name;
    EXPECT_TRUE(S.isCompressed()) << name;
    for(int col = 0; col < n; ++col)  // rows strictly increasing within each column
      for(int k = S.outerIndexPtr()[col] + 1; k < S.outerIndexPtr()[col + 1]; ++k)
        EXPECT_LT(S.innerIndexPtr()[k - 1], S.innerIndexPtr()[k]) << name << " column " << col;
  }
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

// ---- meshes a Surface_mesh cannot hold, and vertices in no face ----------------------------

namespace {

using lapmesh::internal::Index;
using lapmesh::internal::Working_array;

// (S, M) of the intrinsic Delaunay Laplacian straight from arrays (no Surface_mesh).
lapmesh::Laplacian_pencil array_pencil(const std::vector<std::array<double, 3>>& points, Working_array<Index> tris,
                                       Laplacian kind = Laplacian::intrinsic_delaunay)
{
  const auto t = lapmesh::internal::build_topology(Index(points.size()), std::move(tris));
  lapmesh::internal::Positions P(points.size(), 3);
  for(std::size_t i = 0; i < points.size(); ++i) P.row(Eigen::Index(i)) << points[i][0], points[i][1], points[i][2];
  lapmesh::Laplacian_pencil out;
  lapmesh::internal::assemble_pencil(t, P, kind, lapmesh::Vertex_area::barycentric, false, out);
  return out;
}

double total_area(const std::vector<std::array<double, 3>>& points, const Working_array<Index>& tris)
{
  double area = 0;
  for(std::size_t f = 0; f < tris.size() / 3; ++f) {
    const Eigen::Vector3d a(points[tris[3 * f]].data()), b(points[tris[3 * f + 1]].data()),
      c(points[tris[3 * f + 2]].data());
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  return area;
}

struct Soup_case
{
  std::string name;
  std::vector<std::array<double, 3>> points;
  Working_array<Index> triangles;
};

std::vector<Soup_case> non_manifold_cases()
{
  // Three pages of a book on the edge 0-1, one of them very obtuse.
  Soup_case book{"three faces on an edge", {{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -0.7, 0.7}, {0.5, 0.05, -0.02}},
                 {0, 1, 2, 1, 0, 3, 0, 1, 4}};
  // Two fans touching at vertex 0 (a bowtie), each a pair of triangles.
  Soup_case bowtie{"bowtie vertex",
                   {{0, 0, 0}, {1, 0.2, 0}, {1, -0.2, 0.1}, {-1, 0.3, 0}, {-1, -0.3, 0}, {1.2, 0, 0.4}},
                   {0, 1, 2, 0, 3, 4, 1, 5, 2}};
  // A quad whose two triangles are both present twice, once with each orientation.
  Soup_case duplicated{"duplicated faces", {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                       {0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 3, 2}};
  // A fan around vertex 0 with a zero-area face (vertices 0, 1, 2 on a line).
  Soup_case flat{"zero-area face", {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {1, 1, 0}, {1, -1, 0}},
                 {0, 1, 3, 1, 2, 3, 1, 0, 4, 2, 1, 4, 0, 2, 1}};
  // An open, jittered patch: some boundary edges face obtuse angles.
  const lapmesh::Triangle_soup patch = lapmesh::plane_patch(8, 0.45, 11);
  Soup_case open{"open jittered patch", patch.points, {}};
  for(const auto& t : patch.triangles)
    for(auto v : t) open.triangles.push_back(Index(v));
  // One obtuse triangle: its cover is a pillow whose long edge flips into a loop, the flip
  // of a quad whose outer edges are glued to each other.
  Soup_case ear{"one obtuse triangle", {{0, 0, 0}, {1, 0, 0}, {0.5, 0.1, 0}}, {0, 1, 2}};
  return {book, bowtie, duplicated, flat, open, ear};
}

} // namespace

TEST(IntrinsicDelaunay, TuftedCoverTakesNonManifoldAndDegenerateInput)
{
  run_test_cases(non_manifold_cases(), [](const Soup_case& c) { return c.name; }, [](const Soup_case& c) {
    const auto p = array_pencil(c.points, c.triangles);
    ASSERT_TRUE(p.stiffness.toDense().allFinite());
    ASSERT_TRUE(p.mass.allFinite());
    EXPECT_GE(min_off_diagonal(p.stiffness), -1e-12);
    const Eigen::SparseMatrix<double> St = p.stiffness.transpose();
    EXPECT_EQ((St - p.stiffness).norm(), 0.0);
    EXPECT_LT((p.stiffness * Eigen::VectorXd::Ones(p.mass.size())).cwiseAbs().maxCoeff(),
              1e-12 * p.stiffness.cwiseAbs().sum());
    // Each face counted once: the cover's mass is halved. Mollification gives a zero-area face
    // an area of about sqrt(delta x its length), hence the loose bound.
    const double area = total_area(c.points, c.triangles);
    EXPECT_NEAR(p.mass.sum(), area, 1e-2 * area);
    EXPECT_GT(p.mass.minCoeff(), 0.0);

    const auto t = lapmesh::internal::build_topology(Index(c.points.size()), c.triangles);
    lapmesh::internal::Positions P(c.points.size(), 3);
    for(std::size_t i = 0; i < c.points.size(); ++i) P.row(Eigen::Index(i)) << c.points[i][0], c.points[i][1], c.points[i][2];
    const auto it = lapmesh::internal::intrinsic_delaunay_triangulation(t, P, 1e-5);
    EXPECT_EQ(it.sheets(), 2);
    EXPECT_TRUE(it.is_delaunay());
    for(Index h = 0; h < Index(it.twins().size()); ++h) EXPECT_GE(it.twins()[h], 0) << "the cover is closed";
  });
}

TEST(IntrinsicDelaunay, CotangentRefusesNonManifoldEdgesNamingTheIntrinsicLaplacian)
{
  const Soup_case book = non_manifold_cases()[0];
  for(Laplacian kind : {Laplacian::cotangent, Laplacian::uniform}) {
    try {
      array_pencil(book.points, book.triangles, kind);
      ADD_FAILURE() << lapmesh::to_string(kind) << " took a non-manifold edge";
    } catch(const lapmesh::Mesh_error& e) {
      EXPECT_NE(std::string(e.what()).find("edge (0, 1)"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("intrinsic-delaunay"), std::string::npos) << e.what();
    }
  }
}

TEST(IntrinsicDelaunay, FacesStoredApartAndWeldedGiveTheMeshsOperators)
{
  // The sliver sphere as a Surface_mesh, and as a face-by-face soup welded back through the
  // vertex index map: the same (S, M) for every Laplacian, the same curvatures.
  const lapmesh::Triangle_soup soup = sliver_sphere(2);
  const Mesh whole = to_mesh(soup);
  Mesh apart;
  auto weld = apart.add_property_map<Mesh::Vertex_index, int>("v:weld", -1).first;
  for(const auto& t : soup.triangles) {
    std::array<Mesh::Vertex_index, 3> face;
    for(int a = 0; a < 3; ++a) {
      const auto& p = soup.points[std::size_t(t[a])];
      face[a] = apart.add_vertex(Point(p[0], p[1], p[2]));
      weld[face[a]] = int(t[a]);
    }
    apart.add_face(face[0], face[1], face[2]);
  }
  ASSERT_EQ(num_vertices(apart), 3 * soup.triangles.size());
  for(Laplacian kind : {Laplacian::uniform, Laplacian::cotangent, Laplacian::intrinsic_delaunay}) {
    const auto a = lapmesh::laplacian_pencil(whole, LP::laplacian(kind));
    const auto b = lapmesh::laplacian_pencil(apart, LP::laplacian(kind).vertex_index_map(weld));
    EXPECT_LT((Eigen::MatrixXd(a.stiffness) - Eigen::MatrixXd(b.stiffness)).cwiseAbs().maxCoeff(), 1e-12)
      << lapmesh::to_string(kind);
    EXPECT_LT((a.mass - b.mass).cwiseAbs().maxCoeff(), 1e-15) << lapmesh::to_string(kind);
  }
  const auto ca = lapmesh::vertex_curvatures(whole, LP::laplacian(Laplacian::intrinsic_delaunay));
  const auto cb = lapmesh::vertex_curvatures(apart, LP::laplacian(Laplacian::intrinsic_delaunay).vertex_index_map(weld));
  EXPECT_LT((ca.mean - cb.mean).cwiseAbs().maxCoeff(), 1e-10 * ca.mean.cwiseAbs().maxCoeff());
  EXPECT_LT((ca.gaussian - cb.gaussian).cwiseAbs().maxCoeff(), 1e-10 * ca.gaussian.cwiseAbs().maxCoeff());

  // A constraint on one copy of a welded vertex holds the vertex: only the last copy of vertex 0
  // is marked, and every copy stays, as vertex 0 of the whole mesh does when it is marked.
  Mesh::Vertex_index last_copy_of_0;
  for(auto v : vertices(apart))
    if(weld[v] == 0) last_copy_of_0 = v;
  auto fixed_apart = apart.add_property_map<Mesh::Vertex_index, bool>("v:fixed", false).first;
  fixed_apart[last_copy_of_0] = true;
  Mesh whole_smoothed = whole;
  auto fixed_whole = whole_smoothed.add_property_map<Mesh::Vertex_index, bool>("v:fixed", false).first;
  fixed_whole[*vertices(whole_smoothed).begin()] = true;
  const double lambda = 0.01;
  lapmesh::smooth_laplacian_implicit(whole_smoothed, lambda,
                                     CGAL::parameters::vertex_is_constrained_map(fixed_whole).number_of_iterations(2));
  lapmesh::smooth_laplacian_implicit(
    apart, lambda,
    CGAL::parameters::vertex_is_constrained_map(fixed_apart).vertex_index_map(weld).number_of_iterations(2));
  const auto origin = whole.point(*vertices(whole).begin());
  for(auto v : vertices(apart)) {
    const auto expected = whole_smoothed.point(Mesh::Vertex_index(weld[v]));
    EXPECT_LT(CGAL::squared_distance(apart.point(v), expected), 1e-20) << "copy " << v << " of " << weld[v];
    if(weld[v] == 0) { EXPECT_EQ(apart.point(v), origin); }
  }
}

// An error that names a vertex names the input's vertex, not its place among the vertices in
// faces: here vertex 0 is in no face and vertex 1 has a negative Voronoi area (the angle at
// vertex 3 of its first face is near 180 degrees).
TEST(IntrinsicDelaunay, ErrorsNameTheInputVertexWhenAVertexIsInNoFace)
{
  Mesh m;
  m.add_vertex(Point(9, 9, 9));
  const auto a = m.add_vertex(Point(-1, 0, 0)), b = m.add_vertex(Point(1, 0, 0)), c = m.add_vertex(Point(0, 0.05, 0)),
             d = m.add_vertex(Point(0, -1, 0));
  m.add_face(a, b, c);
  m.add_face(b, a, d);
  const auto voronoi = LP::vertex_area(lapmesh::Vertex_area::voronoi);
  auto H = m.add_property_map<Mesh::Vertex_index, double>("v:H", 0).first;
  auto K = m.add_property_map<Mesh::Vertex_index, double>("v:K", 0).first;
  const auto expect_vertex_1 = [](const std::function<void()>& call, const char* what) {
    try {
      call();
      ADD_FAILURE() << what << ": no error";
    } catch(const lapmesh::Mesh_error& e) {
      EXPECT_EQ(e.element(), lapmesh::Mesh_error::Element::vertex) << what;
      EXPECT_EQ(e.index(), 1) << what;
      EXPECT_EQ(std::string(e.what()).rfind("vertex 1 ", 0), 0u) << what << ": " << e.what();
    }
  };
  expect_vertex_1([&] { lapmesh::compute_mean_curvature(m, H, voronoi); }, "mean curvature");
  expect_vertex_1([&] { lapmesh::compute_gaussian_curvature(m, K, voronoi); }, "Gaussian curvature");
  expect_vertex_1([&] { lapmesh::explicit_stability_bound(m, voronoi); }, "stability bound");
  expect_vertex_1([&] { Mesh w = m; lapmesh::smooth_laplacian_explicit(w, 1e-3, LP::fix_boundary(false, voronoi)); },
                  "smoothing");
  expect_vertex_1([&] { lapmesh::Spectral_basis::compute(m, 2, voronoi); }, "eigenpairs");
}

TEST(IntrinsicDelaunay, VerticesInNoFaceFollowThePolicy)
{
  // The icosphere with two vertices in no face (one first, one last): zero rows and mass in
  // the pencil, NaN curvature, the same values as without them elsewhere; spectral
  // reconstruction and smoothing leave them where they are.
  const lapmesh::Triangle_soup soup = lapmesh::icosphere(2);
  const Mesh plain = to_mesh(soup);
  Mesh with_extra;
  const auto first = with_extra.add_vertex(Point(5, 5, 5));
  std::vector<Mesh::Vertex_index> vs;
  for(const auto& p : soup.points) vs.push_back(with_extra.add_vertex(Point(p[0], p[1], p[2])));
  for(const auto& t : soup.triangles) with_extra.add_face(vs[t[0]], vs[t[1]], vs[t[2]]);
  const auto last = with_extra.add_vertex(Point(-5, 0, 0));
  const Eigen::Index n = Eigen::Index(soup.points.size());

  for(Laplacian kind : {Laplacian::cotangent, Laplacian::intrinsic_delaunay}) {
    const auto a = lapmesh::laplacian_pencil(plain, LP::laplacian(kind));
    const auto b = lapmesh::laplacian_pencil(with_extra, LP::laplacian(kind));
    ASSERT_EQ(b.mass.size(), n + 2);
    EXPECT_EQ(b.mass[0], 0.0);
    EXPECT_EQ(b.mass[n + 1], 0.0);
    EXPECT_EQ(b.mass.segment(1, n), a.mass);
    EXPECT_EQ(Eigen::MatrixXd(b.stiffness).block(1, 1, n, n), Eigen::MatrixXd(a.stiffness));
    EXPECT_EQ(Eigen::MatrixXd(b.stiffness).row(0).cwiseAbs().sum(), 0.0);

    const auto ca = lapmesh::vertex_curvatures(plain, LP::laplacian(kind));
    const auto cb = lapmesh::vertex_curvatures(with_extra, LP::laplacian(kind));
    EXPECT_TRUE(std::isnan(cb.mean[0]) && std::isnan(cb.gaussian[n + 1]) && std::isnan(cb.k1[0]));
    EXPECT_EQ(cb.mean.segment(1, n), ca.mean);
    EXPECT_EQ(cb.gaussian.segment(1, n), ca.gaussian);

    Mesh rebuilt = with_extra;
    lapmesh::spectral_reconstruction(rebuilt, 10, LP::laplacian(kind));
    EXPECT_EQ(rebuilt.point(first), Point(5, 5, 5));
    EXPECT_EQ(rebuilt.point(last), Point(-5, 0, 0));
    Mesh smoothed = with_extra;
    lapmesh::smooth_laplacian_implicit(smoothed, 0.01, LP::laplacian(kind));
    EXPECT_EQ(smoothed.point(first), Point(5, 5, 5));
    EXPECT_EQ(smoothed.point(last), Point(-5, 0, 0));
    EXPECT_NE(smoothed.point(vs[0]), with_extra.point(vs[0]));
  }
}

TEST(IntrinsicDelaunay, ReaderKeepsWhatRealMeshesHave)
{
  // A book of three faces (non-manifold edge), a bowtie vertex, a zero-area face, a face that
  // uses a vertex twice and a vertex in no face: read, counted, and stored apart for welding.
  const std::string path = scratch_dir() + "/dirty.off";
  {
    std::ofstream os(path);
    os << "OFF\n9 6 0\n0 0 0\n1 0 0\n0.5 1 0\n0.5 -0.7 0.7\n0.5 0.05 -0.3\n-1 0.3 0\n-1 -0.3 0\n2 0 0\n7 7 7\n"
          "3 0 1 2\n3 1 0 3\n3 0 1 4\n3 0 5 6\n3 1 7 7\n3 2 1 7\n";
  }
  Mesh m;
  const lapmesh::io::Soup_report r = lapmesh::io::read_triangle_mesh(path, m);
  EXPECT_EQ(r.dropped_faces, 1u);
  EXPECT_EQ(r.isolated_vertices, 1u);
  EXPECT_EQ(r.non_manifold_edges, 1u);
  EXPECT_EQ(r.zero_area_faces, 0u);
  ASSERT_EQ(r.input_vertex.size(), num_vertices(m));
  EXPECT_EQ(num_faces(m), 5u);
  auto weld = m.add_property_map<Mesh::Vertex_index, int>("v:weld", -1).first;
  for(auto v : m.vertices()) weld[v] = int(r.input_vertex[v.idx()]);
  const auto p = lapmesh::laplacian_pencil(m, LP::laplacian(Laplacian::intrinsic_delaunay).vertex_index_map(weld));
  ASSERT_EQ(p.mass.size(), 9);
  EXPECT_EQ(p.mass[8], 0.0);
  EXPECT_GT(p.mass.head(8).minCoeff(), 0.0);
  EXPECT_GE(min_off_diagonal(p.stiffness), -1e-12);
  EXPECT_THROW(lapmesh::laplacian_pencil(m, LP::laplacian(Laplacian::cotangent).vertex_index_map(weld)),
               lapmesh::Mesh_error);
}
