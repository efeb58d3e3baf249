// Curvature against closed forms (sphere, torus, ellipsoid, saddle), convergence orders,
// Gauss–Bonnet, sign conventions, scale covariance, the uniform-vs-cotangent flat patch, the
// property-map API and the degenerate-input policy.
#include "test_helpers.h"

#include <lapmesh/curvature.h>
#include <lapmesh/io.h>

#include <CGAL/Polygon_mesh_processing/orientation.h>

using namespace lapmesh_test;
namespace LP = lapmesh::parameters;
using lapmesh::Vertex_area;

namespace {

struct Relative_errors
{
  double mean, gaussian;
};

// Relative RMS errors ||computed - exact|| / ||exact|| of H and K for a soup with closed forms.
template <typename Exact>
Relative_errors errors_against(const lapmesh::Triangle_soup& soup, Exact exact, Vertex_area area = Vertex_area::mixed)
{
  const Mesh m = to_mesh(soup);
  const auto c = lapmesh::vertex_curvatures(m, LP::vertex_area(area));
  double eh = 0, ek = 0, h2 = 0, k2 = 0;
  for(std::size_t i = 0; i < soup.points.size(); ++i) {
    const std::array<double, 2> hk = exact(soup.points[i]);
    eh += std::pow(c.mean[Eigen::Index(i)] - hk[0], 2);
    ek += std::pow(c.gaussian[Eigen::Index(i)] - hk[1], 2);
    h2 += hk[0] * hk[0];
    k2 += hk[1] * hk[1];
  }
  return {std::sqrt(eh / h2), std::sqrt(ek / k2)};
}

std::array<double, 2> torus_exact(const std::array<double, 3>& p)
{
  const double R = 1.0, r = 0.4, v = lapmesh::torus_tube_angle(p, R);
  return {(R + 2 * r * std::cos(v)) / (2 * r * (R + r * std::cos(v))), std::cos(v) / (r * (R + r * std::cos(v)))};
}

double gauss_bonnet_sum(const lapmesh::Vertex_curvatures& c) { return c.gaussian.dot(c.area); }

} // namespace

TEST(Curvature, SphereWithinOnePercentRmsAndSignedOutward)
{
  const double r = 2.5;
  const auto e = errors_against(lapmesh::icosphere(5, r), [r](const auto&) { return std::array<double, 2>{1 / r, 1 / (r * r)}; });
  EXPECT_LT(e.mean, 1e-5);  // measured 6.3e-7 (10242 vertices)
  EXPECT_LT(e.gaussian, 1e-3);
  const Mesh m = to_mesh(lapmesh::icosphere(4, r));
  const auto c = lapmesh::vertex_curvatures(m, LP::vertex_area(Vertex_area::mixed));
  EXPECT_GT(c.mean.minCoeff(), 0.0);  // outward normals: H > 0 everywhere
  EXPECT_NEAR(c.k1.mean(), 1 / r, 1e-3);
  EXPECT_NEAR(c.k2.mean(), 1 / r, 1e-2);
  // M^-1 C x = -2 H n: the Laplacian points inward with length 2H
  for(Eigen::Index i = 0; i < c.mean.size(); ++i)
    EXPECT_LT((c.laplacian.row(i) + 2.0 * c.mean[i] * c.normal.row(i)).norm(), 1e-2 * c.mean[i]);  // measured 4e-3
}

TEST(Curvature, InvertedSphereHasNegativeMeanCurvature)
{
  Mesh m = to_mesh(lapmesh::icosphere(3, 1.0));
  CGAL::Polygon_mesh_processing::reverse_face_orientations(m);
  const auto c = lapmesh::vertex_curvatures(m, LP::vertex_area(Vertex_area::mixed));
  EXPECT_LT(c.mean.maxCoeff(), 0.0);
  EXPECT_NEAR(c.mean.mean(), -1.0, 1e-3);
  EXPECT_NEAR(c.gaussian.mean(), 1.0, 1e-2);  // K does not depend on orientation
}

TEST(Curvature, TorusWithinOnePercentRmsWithSecondOrderConvergence)
{
  const auto coarse = errors_against(lapmesh::torus(80, 32), torus_exact);
  const auto fine = errors_against(lapmesh::torus(160, 64), torus_exact);  // 10240 vertices
  EXPECT_LT(fine.mean, 0.01);
  EXPECT_LT(fine.gaussian, 0.01);
  // measured orders 1.99 (H) and 2.0 (K) on this ladder
  EXPECT_GT(std::log2(coarse.mean / fine.mean), 1.8);
  EXPECT_GT(std::log2(coarse.gaussian / fine.gaussian), 1.8);
}

TEST(Curvature, SphereConvergenceOrderMixedVersusBarycentric)
{
  const auto exact = [](const auto&) { return std::array<double, 2>{1.0, 1.0}; };
  std::vector<double> mixed_h, bary_max;
  for(int level = 3; level <= 5; ++level) {
    mixed_h.push_back(errors_against(lapmesh::icosphere(level), exact).mean);
    const Mesh m = to_mesh(lapmesh::icosphere(level));
    const auto c = lapmesh::vertex_curvatures(m);  // barycentric default
    bary_max.push_back((c.mean.array() - 1.0).abs().maxCoeff());
  }
  // mixed: measured order ~2.4 per halving of the edge length
  EXPECT_GT(std::log2(mixed_h[0] / mixed_h[1]), 2.0);
  EXPECT_GT(std::log2(mixed_h[1] / mixed_h[2]), 2.0);
  // barycentric: ~14.6% error at the valence-5 vertices at every level, no convergence
  for(double e : bary_max) EXPECT_NEAR(e, 0.146, 0.01);
}

TEST(Curvature, EllipsoidConvergesToClosedForm)
{
  const double a = 1.5, b = 1.0, c = 0.7;
  auto exact = [&](const std::array<double, 3>& p) { return lapmesh::ellipsoid_curvatures(p, a, b, c); };
  const auto coarse = errors_against(lapmesh::ellipsoid(4, a, b, c), exact);
  const auto fine = errors_against(lapmesh::ellipsoid(5, a, b, c), exact);
  EXPECT_LT(fine.mean, 0.005);  // measured 1.8e-3
  EXPECT_LT(fine.gaussian, 0.005);
  EXPECT_LT(fine.mean, coarse.mean);
  EXPECT_LT(fine.gaussian, coarse.gaussian);
}

TEST(Curvature, SaddleSignsAtItsCentre)
{
  // z = x^2 - y^2/2 with normals towards +z: k = -2 along x, +1 along y at the origin.
  const int n = 81;
  const Mesh m = to_mesh(lapmesh::height_field(n, [](double x, double y) { return x * x - 0.5 * y * y; }));
  const auto c = lapmesh::vertex_curvatures(m, LP::vertex_area(Vertex_area::mixed));
  const Eigen::Index centre = (n / 2) * n + n / 2;
  EXPECT_NEAR(c.mean[centre], -0.5, 2e-3);
  EXPECT_NEAR(c.gaussian[centre], -2.0, 5e-3);
  EXPECT_NEAR(c.k1[centre], 1.0, 2e-3);
  EXPECT_NEAR(c.k2[centre], -2.0, 5e-3);
}

TEST(Curvature, GaussBonnetToRoundOff)
{
  struct Case
  {
    const char* name;
    Mesh mesh;
    double chi;
  };
  std::vector<Case> cases;
  cases.push_back({"sphere", to_mesh(lapmesh::icosphere(4)), 2});
  cases.push_back({"torus", to_mesh(lapmesh::torus(60, 25)), 0});
  cases.push_back({"disk (boundary rule)", to_mesh(lapmesh::plane_patch(20, 0.3)), 1});
  cases.push_back({"bumpy saddle patch", to_mesh(lapmesh::height_field(15, [](double x, double y) { return std::sin(3 * x) * y; }, 0.2)), 1});
  for(const auto& cs : cases)
    for(auto area : {Vertex_area::barycentric, Vertex_area::mixed}) {
      const auto c = lapmesh::vertex_curvatures(cs.mesh, LP::vertex_area(area));
      EXPECT_NEAR(gauss_bonnet_sum(c), 2 * M_PI * cs.chi, 1e-10 * 2 * M_PI) << cs.name << ' ' << lapmesh::to_string(area);
    }
}

TEST(Curvature, GaussBonnetOnRealMeshes)
{
  // CGAL's data set: a genus-0 cow, a genus-2 double torus (chi = -2).
  using Case = std::pair<std::string, double>;  // a mesh file and its Euler characteristic
  run_test_cases(std::vector<Case>{{"cow.off", 2}, {"double-torus-example.off", -2}}, [](const Case& mesh_case) {
    const auto& [name, chi] = mesh_case;
    Mesh m;
    lapmesh::io::read_triangle_mesh(cgal_mesh(name), m);  // the double torus has quads: triangulated
    const double euler = double(num_vertices(m)) - double(num_edges(m)) + double(num_faces(m));
    ASSERT_EQ(euler, chi) << name;
    const auto c = lapmesh::vertex_curvatures(m, LP::vertex_area(Vertex_area::mixed));
    EXPECT_NEAR(gauss_bonnet_sum(c), 2 * M_PI * chi, 1e-10 * 2 * M_PI) << name;
  });
}

TEST(Curvature, UniformIsNonZeroOnIrregularFlatPatchWhereCotangentVanishes)
{
  // The seed's observation: the graph Laplacian sees the irregular sampling of a plane.
  const Mesh m = to_mesh(lapmesh::plane_patch(20, 0.35, 5));
  const auto cot = lapmesh::vertex_curvatures(m, LP::vertex_area(Vertex_area::mixed));
  const auto uni = lapmesh::vertex_curvatures(m, LP::laplacian(lapmesh::Laplacian::uniform));
  double cot_max = 0, uni_rms = 0;
  int interior = 0;
  for(auto v : vertices(m))
    if(!CGAL::is_border(v, m)) {
      cot_max = std::max(cot_max, std::abs(cot.mean[v.idx()]));
      uni_rms += uni.mean[v.idx()] * uni.mean[v.idx()];
      ++interior;
    }
  uni_rms = std::sqrt(uni_rms / interior);
  EXPECT_LT(cot_max, 1e-11);
  EXPECT_GT(uni_rms, 1e-3);  // spacing is 2/19: a jitter of 0.35 spacing displaces by ~0.03
}

TEST(Curvature, ScaleCovariance)
{
  const auto soup = lapmesh::torus(40, 16);
  const Mesh m = to_mesh(soup);
  const auto base = lapmesh::vertex_curvatures(m, LP::vertex_area(Vertex_area::mixed));
  const auto base_uniform = lapmesh::vertex_curvatures(m, LP::laplacian(lapmesh::Laplacian::uniform));
  for(double s : {1e-4, 1e4}) {
    auto scaled = soup;
    for(auto& p : scaled.points)
      for(double& x : p) x *= s;
    const Mesh ms = to_mesh(scaled);
    const auto c = lapmesh::vertex_curvatures(ms, LP::vertex_area(Vertex_area::mixed));
    EXPECT_LT((c.mean * s - base.mean).norm(), 1e-10 * base.mean.norm()) << s;            // H ~ 1/length
    EXPECT_LT((c.gaussian * s * s - base.gaussian).norm(), 1e-10 * base.gaussian.norm()) << s;  // K ~ 1/length^2
    EXPECT_LT((c.k2 * s - base.k2).norm(), 1e-10 * base.k2.norm()) << s;
    // the uniform "mean curvature" is not scale-correct: it scales like a length
    const auto u = lapmesh::vertex_curvatures(ms, LP::laplacian(lapmesh::Laplacian::uniform));
    EXPECT_LT((u.mean / s - base_uniform.mean).norm(), 1e-10 * base_uniform.mean.norm()) << s;
  }
}

TEST(Curvature, PropertyMapApiWritesTheSameValuesOnSurfaceMeshAndPolyhedron)
{
  const auto soup = lapmesh::torus(24, 12);
  Mesh m = to_mesh(soup);
  const auto np = LP::vertex_area(Vertex_area::mixed);
  const auto arrays = lapmesh::vertex_curvatures(m, np);

  auto H = m.add_property_map<Mesh::Vertex_index, double>("v:H").first;
  auto K = m.add_property_map<Mesh::Vertex_index, double>("v:K").first;
  auto k1 = m.add_property_map<Mesh::Vertex_index, double>("v:k1").first;
  auto k2 = m.add_property_map<Mesh::Vertex_index, double>("v:k2").first;
  auto A = m.add_property_map<Mesh::Vertex_index, double>("v:A").first;
  auto N = m.add_property_map<Mesh::Vertex_index, Kernel::Vector_3>("v:N").first;
  lapmesh::compute_vertex_curvatures(
    m, LP::vertex_mean_curvature_map(H, LP::vertex_gaussian_curvature_map(K, LP::vertex_max_curvature_map(k1,
       LP::vertex_min_curvature_map(k2, LP::vertex_area_map(A, np.vertex_normal_map(N)))))));
  Mesh::Property_map<Mesh::Vertex_index, double> Honly = m.add_property_map<Mesh::Vertex_index, double>("v:H2").first;
  lapmesh::compute_mean_curvature(m, Honly, np);
  for(auto v : vertices(m)) {
    EXPECT_EQ(H[v], arrays.mean[v.idx()]);
    EXPECT_EQ(Honly[v], arrays.mean[v.idx()]);
    EXPECT_EQ(K[v], arrays.gaussian[v.idx()]);
    EXPECT_EQ(k1[v], arrays.k1[v.idx()]);
    EXPECT_EQ(k2[v], arrays.k2[v.idx()]);
    EXPECT_EQ(A[v], arrays.area[v.idx()]);
    EXPECT_EQ(N[v].z(), arrays.normal(v.idx(), 2));
  }

  // Polyhedron_3 with a std::map-backed property map
  Polyhedron poly = to_mesh<Polyhedron>(soup);
  std::map<Polyhedron::Vertex_handle, double> gauss;
  lapmesh::compute_gaussian_curvature(poly, boost::make_assoc_property_map(gauss), np);
  std::size_t i = 0;
  for(auto v : vertices(poly)) EXPECT_NEAR(gauss[v], arrays.gaussian[Eigen::Index(i++)], 1e-12 * arrays.gaussian.cwiseAbs().maxCoeff());
}

// compute_gaussian_curvature() skips the Laplacian, the normals and k1, k2, and
// compute_mean_curvature() the angles and the arrays of normals and Laplacians: they must still
// give vertex_curvatures()'s K and H bitwise, boundary and vertices in no face included.
TEST(Curvature, GaussianAndMeanAloneAreBitwiseTheFullComputations)
{
  lapmesh::Triangle_soup soup = lapmesh::plane_patch(9, 0.3, 5);
  for(auto& p : soup.points) p[2] = 0.3 * p[0] * p[0] - 0.2 * p[1] * p[1];  // a saddle with a boundary
  Mesh m = to_mesh(soup);
  m.add_vertex(Point(4, 4, 4));  // in no face: NaN
  for(lapmesh::Laplacian kind :
       {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform, lapmesh::Laplacian::intrinsic_delaunay})
    for(Vertex_area area : {Vertex_area::barycentric, Vertex_area::mixed}) {
      const auto np = LP::vertex_area(area, LP::laplacian(kind));
      const auto full = lapmesh::vertex_curvatures(m, np);
      // Writes one curvature alone into a fresh map and compares it with the full computation's.
      const auto expect_alone_equals = [&](const char* what, const Eigen::VectorXd& expected, const auto& compute) {
        auto map = m.add_property_map<Mesh::Vertex_index, double>("v:alone").first;
        compute(map);
        for(auto v : vertices(m)) {
          if(std::isnan(expected[v.idx()]))
            EXPECT_TRUE(std::isnan(map[v])) << what << " " << v;
          else
            EXPECT_EQ(map[v], expected[v.idx()])
              << what << " " << lapmesh::to_string(kind) << " " << lapmesh::to_string(area) << " " << v;
        }
        EXPECT_TRUE(std::isnan(map[Mesh::Vertex_index(num_vertices(m) - 1)])) << what;
        m.remove_property_map(map);
      };
      expect_alone_equals("K", full.gaussian, [&](auto map) { lapmesh::compute_gaussian_curvature(m, map, np); });
      expect_alone_equals("H", full.mean, [&](auto map) { lapmesh::compute_mean_curvature(m, map, np); });
    }
}

// Serially the face pass adds each corner's area, angle and face normal to its vertex as it
// goes; in parallel they are stored per corner and gathered by vertex. Both add in the same
// order, so every per-vertex result is the same to the bit, for every kind of vertex area.
TEST(Curvature, ParallelEqualsSequentialBitwise)
{
  const Mesh m = to_mesh(lapmesh::bumpy_sphere(5));
  ASSERT_GT(num_vertices(m), 8192u);  // large enough for the parallel loops to split
  for(const Vertex_area area : {Vertex_area::mixed, Vertex_area::barycentric}) {
    const auto a = lapmesh::vertex_curvatures<CGAL::Sequential_tag>(m, LP::vertex_area(area));
    const auto b = lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(m, LP::vertex_area(area));
    EXPECT_EQ((a.mean - b.mean).norm(), 0.0);
    EXPECT_EQ((a.gaussian - b.gaussian).norm(), 0.0);
    EXPECT_EQ((a.k1 - b.k1).norm(), 0.0);
    EXPECT_EQ((a.area - b.area).norm(), 0.0);
    EXPECT_EQ((a.normal - b.normal).norm(), 0.0);
    EXPECT_EQ((lapmesh::vertex_areas<CGAL::Parallel_if_available_tag>(m, LP::vertex_area(area)) - a.area).norm(), 0.0);
    EXPECT_EQ((lapmesh::vertex_areas<CGAL::Sequential_tag>(m, LP::vertex_area(area)) - a.area).norm(), 0.0);

    Mesh copy = m;
    // The largest difference between a property map of `copy` and the sequential arrays' values.
    const auto largest_difference = [&](const auto& map, const Eigen::VectorXd& expected) {
      double largest = 0;
      for(const auto v : vertices(copy)) largest = std::max(largest, std::abs(map[v] - expected[Eigen::Index(v.idx())]));
      return largest;
    };
    auto K = copy.add_property_map<Mesh::Vertex_index, double>("v:K", 0.0).first;
    lapmesh::compute_gaussian_curvature<CGAL::Sequential_tag>(copy, K, LP::vertex_area(area));
    EXPECT_EQ(largest_difference(K, a.gaussian), 0.0);
    auto H = copy.add_property_map<Mesh::Vertex_index, double>("v:H", 0.0).first;
    lapmesh::compute_mean_curvature<CGAL::Parallel_if_available_tag>(copy, H, LP::vertex_area(area));
    EXPECT_EQ(largest_difference(H, a.mean), 0.0);
  }
}

TEST(Curvature, DegenerateInputIsReportedNotTurnedIntoNaN)
{
  auto collinear = lapmesh::plane_patch(5);
  // vertex 6 = (-0.5, -0.5); vertex 7 = (0, -0.5); vertex 12 = (0, 0) -> move 12 onto the
  // line through 6 and 7: face (6, 7, 12) collapses to zero area
  collinear.points[12] = {0.5, -0.5, 0};
  try {
    lapmesh::vertex_curvatures(to_mesh(collinear));
    FAIL() << "a zero-area face must be reported";
  } catch(const lapmesh::Mesh_error& e) {
    EXPECT_EQ(e.element(), lapmesh::Mesh_error::Element::face);
    EXPECT_NE(std::string(e.what()).find("zero area"), std::string::npos);
  }
  // The Voronoi area can vanish or turn negative: curvature refuses it with the vertex index.
  const Mesh obtuse = to_mesh(lapmesh::plane_patch(12, 0.49, 11));
  const Eigen::VectorXd voronoi = lapmesh::vertex_areas(obtuse, LP::vertex_area(Vertex_area::voronoi));
  ASSERT_LE(voronoi.minCoeff(), 0.0) << "test mesh no longer has a non-positive Voronoi area";
  EXPECT_THROW(lapmesh::vertex_curvatures(obtuse, LP::vertex_area(Vertex_area::voronoi)), lapmesh::Mesh_error);
}
