// Operators: stiffness matrices and vertex areas against an independent halfedge-based
// reference, invariants (symmetry, zero row sums, total area, linear precision, scale),
// generic-mesh support (Polyhedron_3, removed elements, index maps, boundaries, components),
// the uniform operator read off the graph's edges equal to the general path.
#include "test_helpers.h"

#include <lapmesh/internal/row_sort.h>
#include <lapmesh/curvature.h>
#include <lapmesh/laplacian.h>

#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/boost/graph/Euler_operations.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#endif

using namespace lapmesh_test;
namespace LP = lapmesh::parameters;
using lapmesh::internal::Working_array;

namespace {

// Reference cotangent weights by walking halfedges with CGAL (a different code path from
// lapmesh's corner arrays): C_ij = 1/2 sum over the faces of ij of cot(opposite angle).
Eigen::MatrixXd reference_cotangent_matrix(const Mesh& m)
{
  const int n = int(num_vertices(m));
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n, n);
  for(auto h : halfedges(m)) {
    if(is_border(h, m)) continue;
    const auto i = source(h, m), j = target(h, m), k = target(next(h, m), m);
    const Eigen::Vector3d pi(m.point(i).x(), m.point(i).y(), m.point(i).z());
    const Eigen::Vector3d pj(m.point(j).x(), m.point(j).y(), m.point(j).z());
    const Eigen::Vector3d pk(m.point(k).x(), m.point(k).y(), m.point(k).z());
    const Eigen::Vector3d u = pi - pk, v = pj - pk;
    const double cot = u.dot(v) / u.cross(v).norm();
    C(i.idx(), j.idx()) += 0.5 * cot;
    C(j.idx(), i.idx()) += 0.5 * cot;
  }
  for(int i = 0; i < n; ++i) C(i, i) = -(C.row(i).sum() - C(i, i));
  return C;
}

// Reference Voronoi areas from the edge formula of doc/conventions.md: 1/8 sum (cot a + cot b) |xi - xj|^2.
Eigen::VectorXd reference_voronoi_areas(const Mesh& m, const Eigen::MatrixXd& C)
{
  Eigen::VectorXd A = Eigen::VectorXd::Zero(num_vertices(m));
  for(auto v : vertices(m))
    for(auto w : vertices_around_target(v, m)) {
      const double d2 = CGAL::squared_distance(m.point(v), m.point(w));
      A[v.idx()] += 0.25 * C(v.idx(), w.idx()) * d2;  // C holds half the cotangent sum
    }
  return A;
}

Mesh jittered_sphere()
{
  auto soup = lapmesh::icosphere(3, 1.3);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  for(auto& p : soup.points)
    for(double& c : p) c += u(rng);
  return to_mesh(soup);
}

} // namespace

TEST(Operators, CotangentStiffnessMatchesHalfedgeReference)
{
  const Mesh m = jittered_sphere();
  const Eigen::MatrixXd C = Eigen::MatrixXd(lapmesh::cotangent_stiffness_matrix(m));
  const Eigen::MatrixXd R = reference_cotangent_matrix(m);
  EXPECT_LT((C - R).cwiseAbs().maxCoeff(), 1e-12 * R.cwiseAbs().maxCoeff());
}

TEST(Operators, StiffnessIsSymmetricWithZeroRowSums)
{
  const Mesh m = jittered_sphere();
  for(auto kind : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform}) {
    const auto pencil = lapmesh::laplacian_pencil(m, LP::laplacian(kind));
    const Eigen::SparseMatrix<double>& S = pencil.stiffness;
    const Eigen::SparseMatrix<double> St = S.transpose();
    EXPECT_EQ((S - St).norm(), 0.0) << lapmesh::to_string(kind);
    const Eigen::VectorXd ones = Eigen::VectorXd::Ones(S.rows());
    EXPECT_LT((S * ones).cwiseAbs().maxCoeff(), 1e-12 * S.diagonal().cwiseAbs().maxCoeff()) << lapmesh::to_string(kind);
    // negative semidefinite: x^T S x <= 0 for a few random x
    for(int trial = 0; trial < 5; ++trial) {
      const Eigen::VectorXd x = Eigen::VectorXd::Random(S.rows());
      EXPECT_LE(x.dot(S * x), 1e-12);
    }
  }
}

TEST(Operators, UniformIsAdjacencyMinusDegree)
{
  const Mesh m = to_mesh(lapmesh::plane_patch(6, 0.2));
  const auto pencil = lapmesh::laplacian_pencil(m, LP::laplacian(lapmesh::Laplacian::uniform));
  for(auto v : vertices(m)) {
    const int degree = int(CGAL::degree(v, m));
    EXPECT_EQ(pencil.mass[v.idx()], degree);
    EXPECT_EQ(pencil.stiffness.coeff(v.idx(), v.idx()), -degree);
    for(auto w : vertices_around_target(v, m)) EXPECT_EQ(pencil.stiffness.coeff(v.idx(), w.idx()), 1.0);
  }
  EXPECT_EQ(pencil.stiffness.nonZeros(), Eigen::Index(num_vertices(m) + 2 * num_edges(m)));
}

TEST(Operators, AreasSumToSurfaceAreaAndVoronoiMatchesEdgeFormula)
{
  // An obtuse-rich mesh: a strongly jittered plane patch, and a jittered sphere.
  for(const Mesh& m : {jittered_sphere(), to_mesh(lapmesh::plane_patch(12, 0.45))}) {
    const double area = CGAL::Polygon_mesh_processing::area(m);
    const Eigen::VectorXd bary = lapmesh::vertex_areas(m);
    const Eigen::VectorXd mixed = lapmesh::vertex_areas(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
    const Eigen::VectorXd voronoi = lapmesh::vertex_areas(m, LP::vertex_area(lapmesh::Vertex_area::voronoi));
    EXPECT_NEAR(bary.sum(), area, 1e-12 * area);
    EXPECT_NEAR(mixed.sum(), area, 1e-12 * area);
    EXPECT_GT(mixed.minCoeff(), 0.0);
    const Eigen::VectorXd ref = reference_voronoi_areas(m, reference_cotangent_matrix(m));
    EXPECT_LT((voronoi - ref).cwiseAbs().maxCoeff(), 1e-12 * ref.cwiseAbs().maxCoeff());
  }
}

TEST(Operators, MixedEqualsVoronoiOnNonObtuseMesh)
{
  // An icosphere has only acute triangles.
  const Mesh m = to_mesh(lapmesh::icosphere(3));
  const Eigen::VectorXd mixed = lapmesh::vertex_areas(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const Eigen::VectorXd voronoi = lapmesh::vertex_areas(m, LP::vertex_area(lapmesh::Vertex_area::voronoi));
  EXPECT_LT((mixed - voronoi).cwiseAbs().maxCoeff(), 1e-14);
}

TEST(Operators, LinearPrecisionOnIrregularFlatPatch)
{
  // The cotangent Laplacian of any linear function vanishes at interior vertices of a flat mesh.
  const Mesh m = to_mesh(lapmesh::plane_patch(15, 0.35, 3));
  const auto C = lapmesh::cotangent_stiffness_matrix(m);
  Eigen::VectorXd f(num_vertices(m));
  for(auto v : vertices(m)) f[v.idx()] = 2.0 * m.point(v).x() - 3.0 * m.point(v).y() + 0.5;
  const Eigen::VectorXd Cf = C * f;
  int interior = 0;
  for(auto v : vertices(m))
    if(!CGAL::is_border(v, m)) {
      EXPECT_NEAR(Cf[v.idx()], 0.0, 1e-12);
      ++interior;
    }
  EXPECT_EQ(interior, 13 * 13);
}

TEST(Operators, ScaleCovariance)
{
  for(double s : {1e-4, 1e4}) {
    auto soup = lapmesh::torus(30, 15);
    const Mesh m = to_mesh(soup);
    for(auto& p : soup.points)
      for(double& c : p) c *= s;
    const Mesh ms = to_mesh(soup);
    const auto a = lapmesh::laplacian_pencil(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
    const auto b = lapmesh::laplacian_pencil(ms, LP::vertex_area(lapmesh::Vertex_area::mixed));
    EXPECT_LT((a.stiffness - b.stiffness).norm(), 1e-10 * a.stiffness.norm()) << s;  // cotangents are scale-free
    EXPECT_LT((a.mass * s * s - b.mass).norm(), 1e-12 * b.mass.norm()) << s;        // areas scale by s^2
  }
}

TEST(Operators, PolyhedronGivesTheSameMatricesAsSurfaceMesh)
{
  const auto soup = lapmesh::torus(20, 12);
  const Mesh sm = to_mesh(soup);
  const Polyhedron poly = to_mesh<Polyhedron>(soup);
  const auto a = lapmesh::laplacian_pencil(sm, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const auto b = lapmesh::laplacian_pencil(poly, LP::vertex_area(lapmesh::Vertex_area::mixed));
  EXPECT_EQ((a.stiffness - b.stiffness).norm(), 0.0);
  EXPECT_EQ((a.mass - b.mass).norm(), 0.0);
}

TEST(Operators, RemovedElementsAreSkippedAndRowsCompacted)
{
  // Remove a whole connected component (a small sphere) without collecting the garbage:
  // the result must equal the operator of the remaining mesh alone.
  Mesh both = to_mesh(lapmesh::icosphere(1, 0.5));
  const auto torus_soup = lapmesh::torus(16, 8);
  const Mesh torus_only = to_mesh(torus_soup);
  const std::size_t sphere_vertices = num_vertices(both);
  lapmesh::make_mesh(torus_soup, both);
  std::vector<Mesh::Face_index> sphere_faces;
  for(auto f : faces(both))
    if(std::size_t(target(halfedge(f, both), both).idx()) < sphere_vertices) sphere_faces.push_back(f);
  // mark the whole component removed (faces, edges, vertices), as a user's edit would
  for(auto f : sphere_faces) both.remove_face(f);
  std::vector<Mesh::Edge_index> sphere_edges;
  for(auto e : edges(both))
    if(std::size_t(source(halfedge(e, both), both).idx()) < sphere_vertices) sphere_edges.push_back(e);
  for(auto e : sphere_edges) both.remove_edge(e);
  for(std::size_t i = 0; i < sphere_vertices; ++i) both.remove_vertex(Mesh::Vertex_index(Mesh::size_type(i)));
  ASSERT_TRUE(both.has_garbage());
  ASSERT_EQ(both.number_of_vertices(), torus_only.number_of_vertices());  // num_vertices() counts removed ones too
  const auto a = lapmesh::laplacian_pencil(both);
  const auto b = lapmesh::laplacian_pencil(torus_only);
  EXPECT_EQ((a.stiffness - b.stiffness).norm(), 0.0);
  EXPECT_EQ((a.mass - b.mass).norm(), 0.0);
}

TEST(Operators, VertexIndexMapPermutesRows)
{
  Mesh m = to_mesh(lapmesh::icosphere(2));
  auto reversed = m.add_property_map<Mesh::Vertex_index, std::size_t>("v:reversed").first;
  const std::size_t n = num_vertices(m);
  for(auto v : vertices(m)) reversed[v] = n - 1 - v.idx();
  const Eigen::MatrixXd a = Eigen::MatrixXd(lapmesh::cotangent_stiffness_matrix(m));
  const Eigen::MatrixXd b = Eigen::MatrixXd(lapmesh::cotangent_stiffness_matrix(m, CGAL::parameters::vertex_index_map(reversed)));
  // equal up to the summation order of the diagonal
  EXPECT_LT((a.colwise().reverse().rowwise().reverse() - b).norm(), 1e-14 * a.norm());
}

TEST(Operators, BoundaryAndSeveralComponents)
{
  Mesh m = to_mesh(lapmesh::plane_patch(5));
  lapmesh::make_mesh(lapmesh::icosphere(1), m);
  const auto pencil = lapmesh::laplacian_pencil(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(pencil.stiffness.rows());
  EXPECT_LT((pencil.stiffness * ones).norm(), 1e-12);
  EXPECT_NEAR(pencil.mass.sum(), CGAL::Polygon_mesh_processing::area(m), 1e-12);
  // no coupling between the two components
  for(int k = 0; k < pencil.stiffness.outerSize(); ++k)
    for(Eigen::SparseMatrix<double>::InnerIterator it(pencil.stiffness, k); it; ++it)
      EXPECT_EQ(it.row() < 25, it.col() < 25);
}

TEST(Operators, ParallelEqualsSequentialBitwise)
{
  const Mesh m = to_mesh(lapmesh::torus(200, 100));
  const auto a = lapmesh::laplacian_pencil<CGAL::Sequential_tag>(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const auto b = lapmesh::laplacian_pencil<CGAL::Parallel_if_available_tag>(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  EXPECT_EQ((a.stiffness - b.stiffness).norm(), 0.0);
  EXPECT_EQ((a.mass - b.mass).norm(), 0.0);
}

TEST(Operators, InvalidMeshesAreReportedWithTheElement)
{
  // a zero-area face (three collinear vertices) inside an otherwise valid mesh
  lapmesh::Triangle_soup soup = lapmesh::plane_patch(3);
  soup.points[4] = {-1.0 + 1e-300, -1.0, 0.0};  // centre vertex onto the bottom edge: face (0, 1, 4) collapses
  const Mesh m = to_mesh(soup);
  try {
    lapmesh::laplacian_pencil(m);
    FAIL() << "expected a Mesh_error";
  } catch(const lapmesh::Mesh_error& e) {
    EXPECT_EQ(e.element(), lapmesh::Mesh_error::Element::face);
    EXPECT_NE(std::string(e.what()).find("zero area"), std::string::npos) << e.what();
  }
  // a vertex in no face: outside the operator (a zero row and mass), not an error
  Mesh isolated = to_mesh(lapmesh::icosphere(1));
  const auto extra = isolated.add_vertex(Point(5, 5, 5));
  const auto p = lapmesh::laplacian_pencil(isolated);
  EXPECT_EQ(p.mass[Eigen::Index(extra.idx())], 0.0);
  EXPECT_EQ(Eigen::MatrixXd(p.stiffness).row(Eigen::Index(extra.idx())).cwiseAbs().sum(), 0.0);
  // a non-finite coordinate
  Mesh nan_mesh = to_mesh(lapmesh::icosphere(1));
  nan_mesh.point(Mesh::Vertex_index(3)) = Point(std::nan(""), 0, 0);
  EXPECT_THROW(lapmesh::laplacian_pencil(nan_mesh), lapmesh::Mesh_error);
  // voronoi areas can be non-positive; the check used by the solvers names the vertex
  const Mesh obtuse = to_mesh(lapmesh::plane_patch(12, 0.49, 11));
  const Eigen::VectorXd voronoi = lapmesh::vertex_areas(obtuse, LP::vertex_area(lapmesh::Vertex_area::voronoi));
  ASSERT_LE(voronoi.minCoeff(), 0.0) << "test mesh no longer has a non-positive Voronoi area";
  EXPECT_THROW(lapmesh::internal::require_positive_mass(voronoi, lapmesh::Vertex_area::voronoi), lapmesh::Mesh_error);
  EXPECT_NO_THROW(lapmesh::internal::require_positive_mass(
    lapmesh::vertex_areas(obtuse, LP::vertex_area(lapmesh::Vertex_area::mixed)), lapmesh::Vertex_area::mixed));
  // The advice fits the kind of area: a Voronoi area is the one to replace, while a barycentric
  // or mixed one is non-positive only where the faces around the vertex have no area (a flow
  // can shrink them until they underflow, as on CGAL's u.off).
  auto message = [](auto&& check) {
    try {
      check();
    } catch(const lapmesh::Mesh_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const Eigen::VectorXd lost = (Eigen::VectorXd(3) << 0.5, 0.0, 0.25).finished();
  for(const lapmesh::Vertex_area area : {lapmesh::Vertex_area::barycentric, lapmesh::Vertex_area::mixed}) {
    const std::string kind = lapmesh::to_string(area);
    EXPECT_EQ(message([&] { lapmesh::internal::require_positive_mass(lost, area); }),
              "vertex 1 has a non-positive " + kind +
                " area (0); the mass matrix must be positive: the faces around it have no area");
    EXPECT_EQ(message([&] { lapmesh::internal::require_positive_vertex_areas(lost, area); }),
              "vertex 1 has a non-positive " + kind + " area, so its curvature is undefined: the faces around it have no area");
  }
  EXPECT_EQ(message([&] { lapmesh::internal::require_positive_mass(lost, lapmesh::Vertex_area::voronoi); }),
            "vertex 1 has a non-positive voronoi area (0); the mass matrix must be positive: use the mixed or barycentric area");
}

TEST(Operators, TopologyMarksNonManifoldEdgesAndMixedOrientation)
{
  using lapmesh::internal::build_topology;
  // three triangles around the edge (0, 1): all three in its fan
  const auto book = build_topology(5, {0, 1, 2, 1, 0, 3, 0, 1, 4});
  EXPECT_FALSE(book.manifold);
  ASSERT_EQ(book.fan_slot.size(), 1u);
  EXPECT_EQ(book.fan_begin[1] - book.fan_begin[0], 3);
  EXPECT_THROW(lapmesh::internal::require_manifold(book, "cotangent"), lapmesh::Mesh_error);
  // two triangles with opposite orientations on the edge (0, 1)
  EXPECT_FALSE(build_topology(4, {0, 1, 2, 0, 1, 3}).manifold);
  // consistent pair: one interior edge, four boundary edges, all vertices on the boundary
  const auto t = build_topology(4, {0, 1, 2, 1, 0, 3});
  EXPECT_EQ(t.num_edges, 5);
  EXPECT_EQ(t.num_boundary_edges, 4);
  EXPECT_EQ(lapmesh::internal::count_connected_components(t), 1);
}

namespace {

// `soup` with its vertices renumbered and its faces reordered at random: each vertex's
// neighbours then arrive in no particular order.
lapmesh::Triangle_soup shuffled(lapmesh::Triangle_soup soup, unsigned seed)
{
  std::vector<int> new_index(soup.points.size());
  std::iota(new_index.begin(), new_index.end(), 0);
  std::mt19937 random(seed);
  std::shuffle(new_index.begin(), new_index.end(), random);
  std::vector<std::array<double, 3>> points(soup.points.size());
  for(std::size_t i = 0; i < points.size(); ++i) points[std::size_t(new_index[i])] = soup.points[i];
  soup.points = std::move(points);
  for(auto& t : soup.triangles)
    for(auto& v : t) v = new_index[std::size_t(v)];
  std::shuffle(soup.triangles.begin(), soup.triangles.end(), random);
  return soup;
}

// The uniform pencil read off the graph's edges and through the general path (extraction and
// corner topology, which a vertex_index_map selects), compared entry for entry.
template <typename Graph>
void expect_uniform_paths_equal(const Graph& g, const std::string& what)
{
  Eigen::SparseMatrix<double> direct, sorted_in_place;
  const bool taken = lapmesh::internal::with_default_vertex_rows(g, [&](auto rows) {
    return lapmesh::internal::uniform_stiffness_from_edges(g, rows, get(CGAL::vertex_point, g), direct);
  });
  ASSERT_TRUE(taken) << what << ": the edge path declined";
  // The rows sorted where they lie, which the default takes on large meshes only.
  ASSERT_TRUE(lapmesh::internal::with_default_vertex_rows(g, [&](auto rows) {
    return lapmesh::internal::uniform_stiffness_from_edges(g, rows, get(CGAL::vertex_point, g), sorted_in_place, 0);
  })) << what << ": the edge path declined";
  auto rows = get(CGAL::dynamic_vertex_property_t<int>(), g);
  int i = 0;
  for(auto v : vertices(g)) put(rows, v, i++);
  const auto fast = lapmesh::laplacian_pencil(g, LP::laplacian(lapmesh::Laplacian::uniform));
  const Eigen::SparseMatrix<double> matrix = lapmesh::uniform_stiffness_matrix(g);  // without the pencil's mass
  const auto general = lapmesh::laplacian_pencil(g, LP::laplacian(lapmesh::Laplacian::uniform).vertex_index_map(rows));
  const Eigen::SparseMatrix<double>& edge_path = direct;
  const Eigen::SparseMatrix<double>& in_place = sorted_in_place;
  for(const Eigen::SparseMatrix<double>* W : {&edge_path, &in_place, &fast.stiffness, &matrix}) {
    ASSERT_EQ(W->rows(), general.stiffness.rows()) << what;
    ASSERT_EQ(W->nonZeros(), general.stiffness.nonZeros()) << what;
    ASSERT_TRUE(W->isCompressed() && general.stiffness.isCompressed()) << what;
    const Eigen::Index n = W->rows(), nnz = W->nonZeros();
    EXPECT_TRUE(std::equal(W->outerIndexPtr(), W->outerIndexPtr() + n + 1, general.stiffness.outerIndexPtr())) << what;
    EXPECT_TRUE(std::equal(W->innerIndexPtr(), W->innerIndexPtr() + nnz, general.stiffness.innerIndexPtr())) << what;
    EXPECT_TRUE(std::equal(W->valuePtr(), W->valuePtr() + nnz, general.stiffness.valuePtr())) << what;
  }
  EXPECT_EQ(fast.mass, general.mass) << what;
}

} // namespace

TEST(Operators, UniformFromEdgesEqualsTheGeneralPath)
{
  expect_uniform_paths_equal(to_mesh(lapmesh::icosphere(3)), "icosphere");
  expect_uniform_paths_equal(to_mesh(lapmesh::plane_patch(9, 0.3)), "plane patch (boundary)");
  expect_uniform_paths_equal(to_mesh<Polyhedron>(lapmesh::torus(20, 12)), "torus as a Polyhedron_3");
  lapmesh::Triangle_soup cone;  // an apex of 300 faces: a row past the insertion sort
  for(int k = 0; k < 300; ++k) cone.points.push_back({std::cos(2 * M_PI * k / 300), std::sin(2 * M_PI * k / 300), 0});
  cone.points.push_back({0, 0, 1});
  for(int k = 0; k < 300; ++k) cone.triangles.push_back({k, (k + 1) % 300, 300});
  expect_uniform_paths_equal(to_mesh(cone), "a cone of 300 faces");
  for(int faces : {7, 8}) {  // an apex row of 8 and of 9 entries: the network's and the insertion sort's
    lapmesh::Triangle_soup small_cone;
    for(int k = 0; k < faces; ++k)
      small_cone.points.push_back({std::cos(2 * M_PI * k / faces), std::sin(2 * M_PI * k / faces), 0});
    small_cone.points.push_back({0, 0, 1});
    for(int k = 0; k < faces; ++k) small_cone.triangles.push_back({k, (k + 1) % faces, faces});
    expect_uniform_paths_equal(to_mesh(shuffled(small_cone, unsigned(faces))),
                               "a shuffled cone of " + std::to_string(faces) + " faces");
  }
  expect_uniform_paths_equal(to_mesh(shuffled(lapmesh::icosphere(3), 11)), "a shuffled icosphere");

  // Two components, a vertex in no face, and an edge in no face between two corners of the
  // patch, linked into both corners' circulations through their border halfedges: it is no
  // edge of the triangles.
  Mesh m = to_mesh(lapmesh::plane_patch(5));
  lapmesh::make_mesh(lapmesh::icosphere(1), m);
  m.add_vertex(Point(5, 5, 5));
  const Mesh::Halfedge_index chord = m.add_edge(Mesh::Vertex_index(0), Mesh::Vertex_index(24));
  for(Mesh::Halfedge_index h : {chord, opposite(chord, m)}) {
    Mesh::Halfedge_index in = Mesh::null_halfedge();
    for(auto k : halfedges_around_target(target(h, m), m))
      if(is_border(k, m)) in = k;
    ASSERT_TRUE(in != Mesh::null_halfedge());
    const Mesh::Halfedge_index out = next(in, m);
    m.set_next(in, opposite(h, m));
    m.set_next(h, out);
  }
  ASSERT_TRUE(m.is_valid(false));
  expect_uniform_paths_equal(m, "components, a vertex in no face, an edge in no face");

  // Removed elements not yet collected: the faces around a vertex, which goes with them.
  Mesh holes = to_mesh(lapmesh::icosphere(2));
  std::vector<Mesh::Halfedge_index> around;
  for(auto h : halfedges_around_target(Mesh::Vertex_index(7), holes)) around.push_back(h);
  for(auto h : around) CGAL::Euler::remove_face(h, holes);
  ASSERT_TRUE(holes.has_garbage() && holes.is_removed(Mesh::Vertex_index(7)));
  expect_uniform_paths_equal(holes, "removed elements");
}

TEST(Operators, UniformStiffnessHandsBackOtherCallsCachedArraysBeforeItsMatrix)
{
  using lapmesh::internal::Mapping_cache;
  using lapmesh::internal::Working_array;
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  lapmesh::release_working_memory();
  const Mesh m = to_mesh(lapmesh::icosphere(4));
  const Eigen::SparseMatrix<double> reference =
    lapmesh::laplacian_pencil(m, LP::laplacian(lapmesh::Laplacian::uniform)).stiffness;
  // Another call's freed arrays, cached for a call that needs them: a large one (three huge
  // pages) and a small one (1 MiB, in small pages).
  const std::size_t large = std::size_t(6) << 20, small = std::size_t(1) << 20;
  const auto cache_other_calls_arrays = [&] {
    Working_array<double> large_array(large / sizeof(double)), small_array(small / sizeof(double));
  };
  lapmesh::release_working_memory();
  cache_other_calls_arrays();
  ASSERT_EQ(Mapping_cache::large_arrays().cached_bytes(), large);
  ASSERT_EQ(Mapping_cache::small_arrays().cached_bytes(), small);
  const Eigen::SparseMatrix<double> W = lapmesh::uniform_stiffness_matrix(m);
  EXPECT_EQ(Mapping_cache::large_arrays().cached_bytes(), 0u) << "it lay beside the matrix";
  EXPECT_EQ(Mapping_cache::small_arrays().cached_bytes(), 0u) << "it lay beside the matrix";
  ASSERT_EQ(W.nonZeros(), reference.nonZeros());
  EXPECT_EQ(Eigen::MatrixXd(W - reference).cwiseAbs().maxCoeff(), 0.0);
  // The control: with a vertex_index_map the general path assembles, which hands back its own
  // inputs only, and another call's cached mappings stay.
  cache_other_calls_arrays();
  auto rows = get(CGAL::dynamic_vertex_property_t<int>(), m);
  int i = 0;
  for(auto v : vertices(m)) put(rows, v, i++);
  const Eigen::SparseMatrix<double> welded = lapmesh::uniform_stiffness_matrix(m, CGAL::parameters::vertex_index_map(rows));
  EXPECT_EQ(Mapping_cache::large_arrays().cached_bytes(), large);
  EXPECT_EQ(Mapping_cache::small_arrays().cached_bytes(), small);
  EXPECT_EQ(Eigen::MatrixXd(welded - reference).cwiseAbs().maxCoeff(), 0.0);
  lapmesh::release_working_memory();
}

#if defined(__linux__)
// Populated by several threads, one huge page per call, a block has the same pages present as
// after one call for the whole block: the pieces' ends leave no page of it out and reach no page
// beyond it. The block starts and ends inside pages and huge pages.
TEST(Operators, PopulatingABlockInPiecesMakesItsPagesPresentAsOneCallDoes)
{
  const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
  const std::size_t mapped = std::size_t(48) << 20;
  const std::size_t offset = 3 * page + 123, bytes = (std::size_t(40) << 20) + 5000;  // over the 32 MiB populated
  const std::size_t first_page = offset / page, last_page = (offset + bytes - 1) / page;
  // Pages present in the block, and in the whole mapping: in small pages (a huge page at either
  // end of the block would make pages outside it present, and only where the kernel had one).
  const auto pages_present = [&](bool parallel) {
    void* base = mmap(nullptr, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if(base == MAP_FAILED) throw std::runtime_error("mmap failed");
#ifdef MADV_NOHUGEPAGE
    madvise(base, mapped, MADV_NOHUGEPAGE);
#endif
    lapmesh::internal::populate_for_writing(static_cast<char*>(base) + offset, bytes, parallel);
    std::vector<unsigned char> resident(mapped / page);
    const int status = mincore(base, mapped, resident.data());
    munmap(base, mapped);
    if(status != 0) throw std::runtime_error("mincore failed");
    std::pair<std::size_t, std::size_t> count{0, 0};
    for(std::size_t k = 0; k < resident.size(); ++k) {
      count.second += resident[k] & 1u;
      if(k >= first_page && k <= last_page) count.first += resident[k] & 1u;
    }
    return count;
  };
  const auto one_call = pages_present(false);
  // A kernel without MADV_POPULATE_WRITE (before Linux 5.14) makes none present either way.
  EXPECT_TRUE(one_call.first == last_page - first_page + 1 || one_call.second == 0)
    << one_call.first << " of " << last_page - first_page + 1;
  EXPECT_EQ(one_call.second, one_call.first) << "pages outside the block made present";
  const auto in_pieces = pages_present(true);
  EXPECT_EQ(in_pieces.first, one_call.first);
  EXPECT_EQ(in_pieces.second, one_call.second);
}
#endif

// The edges' ends and the counting sort's array wait in the matrix's own arrays: a call
// allocates no working array (which, freed, the cache would keep) beside its matrix, on either
// way of sorting the rows.
TEST(Operators, UniformStiffnessHoldsNoWorkingArrayBesideItsMatrix)
{
  using lapmesh::internal::Mapping_cache;
  const Mesh m = to_mesh(lapmesh::icosphere(6));  // 40962 vertices: each such array over 256 KiB
  const auto general =
    lapmesh::laplacian_pencil(m, LP::laplacian(lapmesh::Laplacian::uniform).vertex_index_map(get(boost::vertex_index, m)));
  for(const std::size_t sorted_in_place_from : {lapmesh::internal::uniform_rows_sorted_in_place_from, std::size_t(0)}) {
    lapmesh::release_working_memory();
    Eigen::SparseMatrix<double> W;
    ASSERT_TRUE(lapmesh::internal::with_default_vertex_rows(m, [&](auto rows) {
      return lapmesh::internal::uniform_stiffness_from_edges(m, rows, get(CGAL::vertex_point, m), W, sorted_in_place_from);
    }));
    EXPECT_EQ(Mapping_cache::total_cached_bytes(), 0u) << "sorted in place from " << sorted_in_place_from;
    ASSERT_EQ(W.nonZeros(), general.stiffness.nonZeros());
    EXPECT_EQ(Eigen::SparseMatrix<double>(W - general.stiffness).norm(), 0.0);
  }
  lapmesh::release_working_memory();
}

TEST(Operators, UniformFromEdgesReportsAsTheGeneralPath)
{
  const auto message = [](const Mesh& m, bool general) {
    try {
      if(general)
        lapmesh::uniform_stiffness_matrix(m, CGAL::parameters::vertex_index_map(get(boost::vertex_index, m)));
      else
        lapmesh::uniform_stiffness_matrix(m);
    } catch(const lapmesh::Mesh_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  Mesh nan_mesh = to_mesh(lapmesh::icosphere(1));
  nan_mesh.point(Mesh::Vertex_index(3)) = Point(std::nan(""), 0, 0);
  Mesh quad = to_mesh(lapmesh::plane_patch(3));
  for(auto h : halfedges(quad))
    if(!is_border_edge(h, quad)) {
      CGAL::Euler::join_face(h, quad);
      break;
    }
  Mesh no_faces;
  no_faces.add_vertex(Point(0, 0, 0));
  const std::vector<std::pair<const Mesh*, std::string>> cases = {
    {&nan_mesh, "vertex 3 has a non-finite coordinate"}, {&quad, "is not a triangle"}, {&no_faces, "the mesh has no faces"}};
  for(const auto& [m, expected] : cases) {
    const std::string fast = message(*m, false);
    EXPECT_NE(fast.find(expected), std::string::npos) << fast;
    EXPECT_EQ(fast, message(*m, true));
  }
}

namespace {

/// The vertex count and the flat triangle list of a soup: the input of build_topology().
std::pair<int, Working_array<int>> flat(const lapmesh::Triangle_soup& soup)
{
  Working_array<int> tri;
  for(const auto& f : soup.triangles) tri.insert(tri.end(), f.begin(), f.end());
  return {int(soup.points.size()), tri};
}

void expect_same_topology(const lapmesh::internal::Mesh_topology& a, const lapmesh::internal::Mesh_topology& b)
{
  EXPECT_EQ(a.num_vertices, b.num_vertices);
  EXPECT_EQ(a.num_faces, b.num_faces);
  EXPECT_EQ(a.num_edges, b.num_edges);
  EXPECT_EQ(a.num_boundary_edges, b.num_boundary_edges);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.corner_begin, b.corner_begin);
  EXPECT_EQ(a.vertex_corners, b.vertex_corners);
  EXPECT_EQ(a.outer, b.outer);
  EXPECT_EQ(a.inner, b.inner);
  EXPECT_EQ(a.diagonal_slot, b.diagonal_slot);
  EXPECT_EQ(a.slot_corners, b.slot_corners);
  EXPECT_EQ(a.on_boundary, b.on_boundary);
  EXPECT_EQ(a.manifold, b.manifold);
  EXPECT_EQ(a.fan_slot, b.fan_slot);
  EXPECT_EQ(a.fan_begin, b.fan_begin);
  EXPECT_EQ(a.fan_corners, b.fan_corners);
}

} // namespace

// The parallel topology is built in parts (rows) and vertex ranges (one per thread) that are
// joined afterwards: it must equal the serial one field by field, on meshes large enough for
// several of each, closed, with a boundary, with one hole, with non-manifold edges, with a
// face given twice and with its vertices numbered at random (each range's corners spread over
// all faces). It runs with 3 threads (each range reads every corner) and 8 (4 ranges, the
// corners sorted into them first) whatever the machine (one thread takes the serial path).
TEST(Operators, ParallelTopologyEqualsTheSerialOne)
{
  using lapmesh::internal::build_corner_topology;
  using lapmesh::internal::build_topology;
  auto torus = flat(lapmesh::torus(400, 200));
  auto fins = torus;  // a third face on two edges far apart: two fans, in different parts
  for(int f : {0, int(torus.second.size() / 3) - 1}) {
    fins.second.insert(fins.second.end(), {torus.second[3 * f], torus.second[3 * f + 1], fins.first});
    ++fins.first;
  }
  // Parts of a closed manifold mesh fill the slots reserved for them exactly; a part with a
  // boundary vertex overflows them, one with a face given twice leaves them short.
  auto hole = torus;
  const int middle = int(torus.second.size() / 6);
  hole.second.erase(hole.second.begin() + 3 * middle, hole.second.begin() + 3 * middle + 3);
  auto twice = torus;
  twice.second.insert(twice.second.end(), torus.second.begin() + 3 * middle, torus.second.begin() + 3 * middle + 3);
  auto shuffled = torus;
  std::vector<int> label(std::size_t(torus.first));
  std::iota(label.begin(), label.end(), 0);
  std::shuffle(label.begin(), label.end(), std::mt19937(5));
  for(int& v : shuffled.second) v = label[std::size_t(v)];
  const std::vector<std::pair<int, Working_array<int>>> cases = {torus, flat(lapmesh::plane_patch(300)), fins, hole, twice,
                                                               shuffled};
  auto check = [&] {
    for(const auto& [n, tri] : cases) {
      ASSERT_GT(n, 4 * 16384);
      const auto serial = build_topology(n, tri, false);
      expect_same_topology(serial, build_topology(n, tri, true));
      expect_same_topology(build_corner_topology(n, tri, false), build_corner_topology(n, tri, true));
    }
  };
#ifdef CGAL_LINKED_WITH_TBB
  for(int threads : {3, 8}) {
    tbb::global_control allowed(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    tbb::task_arena(threads).execute([&] {
      const int ranges = lapmesh::internal::vertex_range_count(torus.first, true);
      EXPECT_EQ(ranges, threads == 3 ? 3 : 4);
      EXPECT_EQ(ranges >= lapmesh::internal::min_ranges_sorted_into, threads == 8);
      check();
    });
  }
#else
  FAIL() << "lapmesh was built without TBB (libtbb-dev): its parallel path is not tested";
#endif
  EXPECT_GT(build_topology(cases[1].first, cases[1].second, true).num_boundary_edges, 0);
  const auto nonmanifold = build_topology(fins.first, fins.second, true);
  EXPECT_FALSE(nonmanifold.manifold);
  EXPECT_EQ(nonmanifold.fan_slot.size(), 2u);
  EXPECT_FALSE(build_corner_topology(fins.first, fins.second, true).manifold);
  EXPECT_EQ(build_topology(hole.first, hole.second, true).num_boundary_edges, 3);
  EXPECT_FALSE(build_topology(twice.first, twice.second, true).manifold);
}

// In parallel the faces are checked, and the vertices in no face found, by range or by chunk:
// the error must still name the first bad face or vertex, as the serial build does.
TEST(Operators, ParallelTopologyNamesTheFirstBadElement)
{
  using lapmesh::internal::build_topology;
  const auto [n, torus] = flat(lapmesh::torus(400, 200));
  auto message = [](int vertices, const Working_array<int>& tri, bool parallel) -> std::string {
    try {
      build_topology(vertices, tri, parallel);
    } catch(const lapmesh::Mesh_error& e) {
      return e.what();
    }
    return "no error";
  };
  auto out_of_range = torus, repeated = torus, unused = torus;
  out_of_range[3 * 50000 + 1] = n;
  out_of_range[3 * 100000 + 2] = -1;
  repeated[3 * 70000 + 2] = repeated[3 * 70000];
  repeated[3 * 90000] = n + 7;
  for(int& v : unused) v += (v >= 30000) + (v >= 60000);  // vertices 30000 and 60001 in no face
  const std::vector<std::tuple<int, Working_array<int>, std::string>> cases = {
    {n, out_of_range, "face 50000 has a vertex index out of range [0, " + std::to_string(n) + ")"},
    {n, repeated, "face 70000 uses the same vertex twice"},
    {n + 2, unused, "vertex 30000 is in no face"}};
#ifdef CGAL_LINKED_WITH_TBB
  for(const auto& bad : cases) {
    const int vertices = std::get<0>(bad);
    const Working_array<int>& tri = std::get<1>(bad);
    const std::string& expected = std::get<2>(bad);
    EXPECT_EQ(message(vertices, tri, false), expected);
    for(int threads : {3, 8}) {
      tbb::global_control allowed(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
      tbb::task_arena(threads).execute([&] { EXPECT_EQ(message(vertices, tri, true), expected) << threads; });
    }
  }
#else
  FAIL() << "lapmesh was built without TBB (libtbb-dev): its parallel path is not tested";
#endif
}

// An error from the topology's numbering names the input's vertex (its row): the whole number only.
TEST(Operators, ErrorsOfTheTopologyNameTheInputVertex)
{
  lapmesh::internal::Extracted_mesh<Mesh> mesh;
  mesh.num_rows = 200;
  mesh.row = {5, 3, 123, 7};
  using Element = lapmesh::Mesh_error::Element;
  const auto e = mesh.in_rows(lapmesh::Mesh_error("vertex 12 is far; vertex 1 has a negative area", Element::vertex, 1));
  EXPECT_STREQ(e.what(), "vertex 12 is far; vertex 3 has a negative area");
  EXPECT_EQ(e.index(), 3);
  const auto last = mesh.in_rows(lapmesh::Mesh_error("at vertex 2", Element::vertex, 2));
  EXPECT_STREQ(last.what(), "at vertex 123");
  const auto face = mesh.in_rows(lapmesh::Mesh_error("face 2 has zero area", Element::face, 2));
  EXPECT_STREQ(face.what(), "face 2 has zero area");
  EXPECT_EQ(face.index(), 2);
  // Faces reordered for locality name the face as read.
  mesh.face = {4, 0, 17, 9};
  const auto reordered = mesh.in_rows(lapmesh::Mesh_error("face 2 has zero area", Element::face, 2));
  EXPECT_STREQ(reordered.what(), "face 17 has zero area");
  EXPECT_EQ(reordered.index(), 17);
}

// A mesh in shuffled order is renumbered for locality by the curvatures' extraction (mean and
// principal curvatures, normals): what they return must not depend on it. The same torus in its
// own order and shuffled gives the same values vertex for vertex, up to the order of the sums,
// there and in the operations that keep the order (Gaussian curvature alone, vertex areas); the
// renumbering's face map names the faces as read.
TEST(Operators, ShuffledMeshIsRenumberedWithTheSameResults)
{
  const lapmesh::Triangle_soup soup = lapmesh::torus(320, 240);  // 76 800 vertices: beyond the caches' share
  const lapmesh::Triangle_soup mixed = shuffled(soup, 5);
  const Mesh ordered = to_mesh(soup);
  Mesh scattered = to_mesh(mixed);
  using lapmesh::internal::Topology_detail;
  constexpr auto local = lapmesh::internal::Vertex_order::local_if_scattered;
  const auto kept = lapmesh::internal::extract_mesh(ordered, CGAL::parameters::default_values(), Topology_detail::corners,
                                                    false, local);
  EXPECT_TRUE(kept.face.empty() && kept.rows_are_topology_vertices()) << "a torus in its own order was renumbered";
  const auto renumbered =
    lapmesh::internal::extract_mesh(scattered, CGAL::parameters::default_values(), Topology_detail::corners, false, local);
  ASSERT_EQ(renumbered.face.size(), mixed.triangles.size()) << "the shuffled torus was not renumbered";
  ASSERT_EQ(renumbered.row.size(), mixed.points.size());
  for(std::size_t f = 0; f < renumbered.face.size(); ++f)
    for(int c = 0; c < 3; ++c)
      ASSERT_EQ(renumbered.row[std::size_t(renumbered.topology.triangles[3 * f + std::size_t(c)])],
                mixed.triangles[std::size_t(renumbered.face[f])][std::size_t(c)])
        << "topology face " << f;
  const auto pattern =
    lapmesh::internal::extract_mesh(scattered, CGAL::parameters::default_values(), Topology_detail::pattern, false, local);
  EXPECT_TRUE(pattern.face.empty() && pattern.rows_are_topology_vertices()) << "a pattern's rows are its results'";

  // Row of each shuffled vertex in the ordered torus, by position (the torus's are distinct).
  std::map<std::array<double, 3>, int> ordered_row;
  for(std::size_t i = 0; i < soup.points.size(); ++i) ordered_row[soup.points[i]] = int(i);
  std::vector<int> same(mixed.points.size());
  for(std::size_t i = 0; i < mixed.points.size(); ++i) same[i] = ordered_row.at(mixed.points[i]);
  // The angle deficit is 2 pi less a vertex's angles, nearly as large: its rounding, relative to
  // K, is about 2 pi / (K A) times larger than the angles' (1e5 on this torus).
  const auto expect_same = [&](const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, const std::string& what,
                               double relative = 1e-12) {
    ASSERT_EQ(a.rows(), Eigen::Index(soup.points.size())) << what;
    ASSERT_EQ(b.rows(), a.rows()) << what;
    const double scale = a.cwiseAbs().maxCoeff();
    double worst = 0;
    for(Eigen::Index i = 0; i < b.rows(); ++i) worst = std::max(worst, (b.row(i) - a.row(same[std::size_t(i)])).cwiseAbs().maxCoeff());
    EXPECT_LE(worst, relative * scale) << what;
  };
  for(const bool parallel : {false, true}) {
    const std::string tag = parallel ? " (parallel)" : "";
    const auto a = parallel ? lapmesh::vertex_curvatures<CGAL::Parallel_tag>(ordered) : lapmesh::vertex_curvatures(ordered);
    const auto b = parallel ? lapmesh::vertex_curvatures<CGAL::Parallel_tag>(scattered) : lapmesh::vertex_curvatures(scattered);
    expect_same(a.mean, b.mean, "mean curvature" + tag);
    expect_same(a.gaussian, b.gaussian, "Gaussian curvature" + tag, 1e-10);
    expect_same(a.k1, b.k1, "k1" + tag, 1e-10);
    expect_same(a.k2, b.k2, "k2" + tag, 1e-10);
    expect_same(a.area, b.area, "areas" + tag);
    expect_same(a.normal, b.normal, "normals" + tag);
    expect_same(a.laplacian, b.laplacian, "Laplacian of the positions" + tag);
  }
  expect_same(lapmesh::vertex_areas(ordered, LP::vertex_area(lapmesh::Vertex_area::mixed)),
              lapmesh::vertex_areas(scattered, LP::vertex_area(lapmesh::Vertex_area::mixed)), "mixed areas");
  // A vertex in no face, last among the rows: NaN curvature and zero area there, the rest as before.
  Mesh with_isolated = scattered;
  with_isolated.add_vertex(Point(0.1, 0.2, 0.3));
  const auto lonely = lapmesh::vertex_curvatures(with_isolated);
  const Eigen::Index last = Eigen::Index(mixed.points.size());
  ASSERT_EQ(lonely.mean.size(), last + 1);
  EXPECT_TRUE(std::isnan(lonely.mean[last]) && std::isnan(lonely.gaussian[last]));
  EXPECT_EQ(lonely.area[last], 0.0);
  expect_same(lapmesh::vertex_curvatures(ordered).mean, lonely.mean.head(last), "mean curvature beside a vertex in no face");

  auto gaussian = scattered.add_property_map<Mesh::Vertex_index, double>("v:K", 0.0).first;
  lapmesh::compute_gaussian_curvature(scattered, gaussian);
  Eigen::VectorXd from_map(scattered.number_of_vertices());
  for(auto v : scattered.vertices()) from_map[Eigen::Index(std::size_t(v))] = gaussian[v];
  expect_same(lapmesh::vertex_curvatures(ordered).gaussian, from_map, "Gaussian curvature into a property map", 1e-10);
}

// A Surface_mesh without removed elements is read by index (in parallel where asked): the
// same arrays and the same errors as the general reader of any FaceGraph.
TEST(Operators, SurfaceMeshIsReadAsAnyFaceGraph)
{
  using namespace lapmesh::internal;
  auto general = [](const Mesh& m) {
    return with_default_vertex_rows(m, [&](auto rows) { return read_with_index_map(m, rows, get(CGAL::vertex_point, m)); });
  };
  const Mesh m = to_mesh(lapmesh::torus(400, 200));
  const auto reference = general(m);
  for(bool parallel : {false, true}) {
    const auto read = extract_arrays(m, CGAL::parameters::default_values(), parallel);
    EXPECT_EQ(read.positions, reference.positions);
    EXPECT_EQ(read.triangles, reference.triangles);
    EXPECT_EQ(read.vertices, reference.vertices);
    EXPECT_EQ(read.vertex_rows, reference.vertex_rows);
  }
  auto message = [](const auto& read) -> std::string {
    try {
      read();
    } catch(const lapmesh::Mesh_error& e) {
      return e.what();
    }
    return "no error";
  };
  Mesh bad = to_mesh(lapmesh::torus(400, 200));
  bad.point(Mesh::Vertex_index(40000)) = Point(0, std::nan(""), 0);
  bad.point(Mesh::Vertex_index(70000)) = Point(0, 0, HUGE_VAL);
  for(bool parallel : {false, true})
    EXPECT_EQ(message([&] { extract_arrays(bad, CGAL::parameters::default_values(), parallel); }),
              "vertex 40000 has a non-finite coordinate");
  EXPECT_EQ(message([&] { general(bad); }), "vertex 40000 has a non-finite coordinate");
  // Two triangles joined into a quad: face 60000 (or the face that takes its place) is not a triangle.
  Mesh quad = to_mesh(lapmesh::torus(400, 200));
  CGAL::Euler::join_face(halfedge(Mesh::Face_index(60000), quad), quad);
  ASSERT_TRUE(quad.has_garbage());
  quad.collect_garbage();
  std::string expected = message([&] { general(quad); });
  EXPECT_NE(expected.find("is not a triangle"), std::string::npos) << expected;
  for(bool parallel : {false, true})
    EXPECT_EQ(message([&] { extract_arrays(quad, CGAL::parameters::default_values(), parallel); }), expected);
}

namespace {

/// Two cones on an n-gon: the apexes have n corners, the equator vertices 4.
std::pair<int, Working_array<int>> bipyramid(int n)
{
  Working_array<int> tri;
  for(int k = 0; k < n; ++k) tri.insert(tri.end(), {k, (k + 1) % n, n, (k + 1) % n, k, n + 1});
  return {n + 2, tri};
}

/// The faces of `b` appended to those of `a`, b's vertices renumbered after a's, and b's vertex
/// `glued` replaced by a's vertex `onto` (one vertex shared, every edge manifold).
std::pair<int, Working_array<int>> glued_at_a_vertex(const std::pair<int, Working_array<int>>& a,
                                                   const std::pair<int, Working_array<int>>& b, int glued, int onto)
{
  auto out = a;
  for(int v : b.second) out.second.push_back(v == glued ? onto : a.first + v - (v > glued));
  out.first += b.first - 1;
  return out;
}

/// The vertices of a triangle list renumbered by a fixed random permutation, so that a vertex's
/// neighbours come in no particular order.
std::pair<int, Working_array<int>> shuffled(std::pair<int, Working_array<int>> mesh, unsigned seed)
{
  std::vector<int> label(std::size_t(mesh.first));
  std::iota(label.begin(), label.end(), 0);
  std::shuffle(label.begin(), label.end(), std::mt19937(seed));
  for(int& v : mesh.second) v = label[std::size_t(v)];
  return mesh;
}

} // namespace

// The pattern rows against a reference built from a map of halfedges: for the slot (i, j), the
// corner opposite i->j and the corner opposite j->i. The meshes cover interior vertices of up to
// 8 corners, of 9 to 16 and of more (an apex of 7, 8, 9, 16, 17, 24, 33 and 300 corners, the last
// two past the insertion sort; two apexes glued into one), boundary vertices, and shuffled
// vertex numbers.
TEST(Operators, PatternRowsEqualAHalfedgeMapReference)
{
  std::vector<std::pair<std::string, std::pair<int, Working_array<int>>>> cases = {
    {"icosphere", shuffled(flat(lapmesh::icosphere(2)), 1)},
    {"plane patch", shuffled(flat(lapmesh::plane_patch(7, 0.3)), 2)},
    {"torus", flat(lapmesh::torus(9, 7))},
    {"two bipyramids glued at an apex (10 corners there)", glued_at_a_vertex(bipyramid(5), bipyramid(5), 5, 5)},
    {"two bipyramids glued at an apex (18 corners there)", shuffled(glued_at_a_vertex(bipyramid(9), bipyramid(9), 9, 9), 3)}};
  for(int n : {7, 8, 9, 16, 17, 24, 33, 300}) cases.push_back({"bipyramid " + std::to_string(n), shuffled(bipyramid(n), unsigned(n))});
  for(const auto& [what, mesh] : cases) {
    const auto& [n, tri] = mesh;
    std::map<std::pair<int, int>, std::array<int, 2>> slots;
    for(int c = 0; c < int(tri.size()); ++c) {
      const int f = c / 3, from = tri[std::size_t(c)], to = tri[std::size_t(3 * f + (c + 1) % 3)];
      const int opposite = 3 * f + (c + 2) % 3;
      slots.try_emplace({from, to}, std::array<int, 2>{-1, -1}).first->second[0] = opposite;
      slots.try_emplace({to, from}, std::array<int, 2>{-1, -1}).first->second[1] = opposite;
    }
    for(int i = 0; i < n; ++i) slots[{i, i}] = {-1, -1};
    std::vector<int> outer{0}, inner, diagonal(static_cast<std::size_t>(n), -1);
    std::vector<std::array<int, 2>> slot_corners;
    std::vector<char> on_boundary(std::size_t(n), 0);
    int edges = 0, boundary_edges = 0;
    for(const auto& [ij, corners] : slots) {  // ordered by row, then column
      const auto [i, j] = ij;
      if(i == j) diagonal[std::size_t(i)] = int(inner.size());
      inner.push_back(j);
      slot_corners.push_back(corners);
      if(int(outer.size()) == i + 1) outer.push_back(0);
      outer[std::size_t(i) + 1] = int(inner.size());
      if(i == j) continue;
      const bool boundary = corners[0] < 0 || corners[1] < 0;
      if(boundary) on_boundary[std::size_t(i)] = 1;
      edges += i < j;
      boundary_edges += i < j && boundary;
    }
    const auto t = lapmesh::internal::build_topology(n, tri);
    EXPECT_TRUE(t.manifold) << what;
    EXPECT_EQ(std::vector<int>(t.outer.begin(), t.outer.end()), outer) << what;
    EXPECT_EQ(std::vector<int>(t.inner.begin(), t.inner.end()), inner) << what;
    EXPECT_EQ(std::vector<int>(t.diagonal_slot.begin(), t.diagonal_slot.end()), diagonal) << what;
    EXPECT_TRUE(std::equal(t.slot_corners.begin(), t.slot_corners.end(), slot_corners.begin(), slot_corners.end()))
      << what;
    EXPECT_EQ(t.on_boundary, on_boundary) << what;
    EXPECT_EQ(t.num_edges, edges) << what;
    EXPECT_EQ(t.num_boundary_edges, boundary_edges) << what;
  }
}

// Rows are sorted by insertion up to max_insertion_sorted_row entries and by std::stable_sort
// beyond: both against std::stable_sort of (key, value) pairs, keys with many repeats.
TEST(Operators, RowSortIsStableOnShortAndLongRows)
{
  std::mt19937 random(11);
  for(std::size_t count : {std::size_t(0), std::size_t(1), std::size_t(7), lapmesh::internal::max_insertion_sorted_row,
                           lapmesh::internal::max_insertion_sorted_row + 1, std::size_t(2000)}) {
    std::vector<int> keys(count);
    std::vector<double> values(count);
    for(std::size_t k = 0; k < count; ++k) {
      keys[k] = int(random() % (count / 4 + 1));
      values[k] = double(k);
    }
    std::vector<std::pair<int, double>> expected(count);
    for(std::size_t k = 0; k < count; ++k) expected[k] = {keys[k], values[k]};
    std::stable_sort(expected.begin(), expected.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<int> keys_alone = keys;
    lapmesh::internal::sort_row(keys.data(), count, values.data());
    lapmesh::internal::sort_row(keys_alone.data(), count);
    for(std::size_t k = 0; k < count; ++k) {
      EXPECT_EQ(keys[k], expected[k].first) << count << " entries, entry " << k;
      EXPECT_EQ(values[k], expected[k].second) << count << " entries, entry " << k;
      EXPECT_EQ(keys_alone[k], expected[k].first) << count << " entries, entry " << k;
    }
  }
}

// The network of eight: every row of zeros and ones (which suffices for a network of
// compare-exchanges to sort every input), then rows of indices with repeats, padded, against
// std::sort.
TEST(Operators, ShortRowsAreSortedByTheNetwork)
{
  for(int bits = 0; bits < 256; ++bits) {
    std::array<int, 8> keys;
    for(int k = 0; k < 8; ++k) keys[std::size_t(k)] = (bits >> k) & 1;
    const int ones = int(std::count(keys.begin(), keys.end(), 1));
    lapmesh::internal::sort_short_row(keys.data());
    for(int k = 0; k < 8; ++k) EXPECT_EQ(keys[std::size_t(k)], k >= 8 - ones ? 1 : 0) << "bits " << bits;
  }
  std::mt19937 random(5);
  for(int trial = 0; trial < 2000; ++trial) {
    std::array<int, 8> keys;
    const int used = 1 + trial % 8;
    for(int k = 0; k < 8; ++k)
      keys[std::size_t(k)] = k < used ? int(random() % 12) * 100000 : std::numeric_limits<int>::max();
    std::array<int, 8> expected = keys;
    std::sort(expected.begin(), expected.end());
    lapmesh::internal::sort_short_row(keys.data());
    EXPECT_EQ(keys, expected) << "trial " << trial;
  }
}

// A row of W from its neighbours in any order, on both sides of the network's eight entries:
// sorted with the diagonal among them, values 1 and -degree; a neighbour given twice is
// declined.
TEST(Operators, UniformRowsAreSortedWithTheirDiagonal)
{
  std::mt19937 random(7);
  for(int degree = 1; degree <= 20; ++degree)
    for(int trial = 0; trial < 50; ++trial) {
      const int r = int(random() % 1000);
      std::vector<int> pool(1000);
      std::iota(pool.begin(), pool.end(), 0);
      pool.erase(pool.begin() + r);
      std::shuffle(pool.begin(), pool.end(), random);
      std::vector<int> row(pool.begin(), pool.begin() + degree);
      row.push_back(-1);  // the diagonal's slot, not yet written
      std::vector<int> expected(pool.begin(), pool.begin() + degree);
      expected.push_back(r);
      std::sort(expected.begin(), expected.end());
      std::vector<double> value(std::size_t(degree) + 1, 0.0);
      ASSERT_TRUE(lapmesh::internal::finish_uniform_row(row.data(), value.data(), degree, r)) << degree;
      EXPECT_EQ(row, expected) << "degree " << degree;
      for(int a = 0; a <= degree; ++a)
        EXPECT_EQ(value[std::size_t(a)], row[std::size_t(a)] == r ? -double(degree) : 1.0) << "degree " << degree;

      if(degree < 2) continue;
      // Neighbour `from` given again at `to`, another place.
      std::vector<int> twice(pool.begin(), pool.begin() + degree);
      const std::size_t from = random() % std::size_t(degree);
      const std::size_t to = (from + 1 + random() % std::size_t(degree - 1)) % std::size_t(degree);
      twice[to] = twice[from];
      twice.push_back(-1);
      EXPECT_FALSE(lapmesh::internal::finish_uniform_row(twice.data(), value.data(), degree, r)) << "degree " << degree;
    }
}

// Vertices in no face first, in the middle and last: the stiffness is the one of the mesh
// without them, each entry moved to the rows of its vertices, their columns empty.
TEST(Operators, RowsInNoFaceAreEmptyColumnsOfTheSameMatrix)
{
  const lapmesh::Triangle_soup soup = lapmesh::icosphere(2);
  Mesh spread;
  std::vector<Mesh::Vertex_index> vs;
  spread.add_vertex(Point(5, 5, 5));
  for(std::size_t i = 0; i < soup.points.size(); ++i) {
    if(i == soup.points.size() / 2) spread.add_vertex(Point(6, 5, 5));
    vs.push_back(spread.add_vertex(Point(soup.points[i][0], soup.points[i][1], soup.points[i][2])));
  }
  spread.add_vertex(Point(7, 5, 5));
  for(const auto& t : soup.triangles) spread.add_face(vs[std::size_t(t[0])], vs[std::size_t(t[1])], vs[std::size_t(t[2])]);
  for(lapmesh::Laplacian kind : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform}) {
    const auto a = lapmesh::laplacian_pencil(to_mesh(soup), LP::laplacian(kind));
    const auto b = lapmesh::laplacian_pencil(spread, LP::laplacian(kind));
    std::vector<Eigen::Triplet<double>> entries;
    for(int j = 0; j < a.stiffness.outerSize(); ++j)
      for(Eigen::SparseMatrix<double>::InnerIterator it(a.stiffness, j); it; ++it)
        entries.emplace_back(int(vs[std::size_t(it.row())].idx()), int(vs[std::size_t(it.col())].idx()), it.value());
    Eigen::SparseMatrix<double> expected(b.stiffness.rows(), b.stiffness.cols());
    expected.setFromTriplets(entries.begin(), entries.end());
    ASSERT_EQ(b.stiffness.rows(), Eigen::Index(soup.points.size() + 3));
    EXPECT_TRUE(b.stiffness.isCompressed());
    EXPECT_EQ(b.stiffness.nonZeros(), a.stiffness.nonZeros());
    EXPECT_EQ((b.stiffness - expected).norm(), 0.0);
    for(int j = 0; j < b.stiffness.outerSize(); ++j)  // rows strictly increasing in each column
      for(int k = b.stiffness.outerIndexPtr()[j] + 1; k < b.stiffness.outerIndexPtr()[j + 1]; ++k)
        EXPECT_LT(b.stiffness.innerIndexPtr()[k - 1], b.stiffness.innerIndexPtr()[k]);
  }
}

TEST(Operators, CornerTopologyEqualsTheFullOne)
{
  using lapmesh::internal::build_corner_topology;
  using lapmesh::internal::build_topology;
  lapmesh::Triangle_soup two = lapmesh::plane_patch(7, 0.3);
  const auto sphere = lapmesh::icosphere(1);
  const int offset = int(two.points.size());
  for(const auto& f : sphere.triangles) two.triangles.push_back({f[0] + offset, f[1] + offset, f[2] + offset});
  two.points.insert(two.points.end(), sphere.points.begin(), sphere.points.end());
  // Hubs of many corners: a closed double cone (hubs 0 and 41 around the ring 1..40) and an open
  // fan (a boundary hub), whose neighbour lists are longer than a short sort's.
  Working_array<int> double_cone, open_fan;
  for(int i = 0; i < 40; ++i) {
    const int j = 1 + i, k = 1 + (i + 1) % 40;
    double_cone.insert(double_cone.end(), {0, j, k, 41, k, j});
    if(i < 39) open_fan.insert(open_fan.end(), {0, j, j + 1});
  }
  std::vector<std::pair<int, Working_array<int>>> cases = {flat(lapmesh::icosphere(2)), flat(lapmesh::torus(12, 8)),
                                                         flat(lapmesh::plane_patch(6)), flat(two),
                                                         flat(shuffled(lapmesh::torus(12, 8), 5)),
                                                         flat(shuffled(lapmesh::plane_patch(6), 7)),
                                                         // two triangles that share a vertex only
                                                         {5, {0, 1, 2, 0, 3, 4}},
                                                         {42, double_cone},
                                                         {41, open_fan}};
  for(const auto& [n, tri] : cases) {
    const auto full = build_topology(n, tri), corners = build_corner_topology(n, tri);
    EXPECT_TRUE(full.has_pattern());
    EXPECT_FALSE(corners.has_pattern());
    EXPECT_TRUE(corners.manifold);
    EXPECT_EQ(corners.triangles, full.triangles);
    EXPECT_EQ(corners.corner_begin, full.corner_begin);
    EXPECT_EQ(corners.vertex_corners, full.vertex_corners);
    EXPECT_EQ(corners.on_boundary, full.on_boundary);
    EXPECT_EQ(corners.num_edges, full.num_edges);
    EXPECT_EQ(corners.num_boundary_edges, full.num_boundary_edges);
  }
  EXPECT_GT(build_corner_topology(cases[2].first, cases[2].second).num_boundary_edges, 0);
  const auto cone = build_corner_topology(42, double_cone), fan = build_corner_topology(41, open_fan);
  EXPECT_EQ(cone.num_edges, 120);
  EXPECT_EQ(cone.num_boundary_edges, 0);
  EXPECT_EQ(fan.num_edges, 79);
  EXPECT_EQ(fan.num_boundary_edges, 41);
  EXPECT_TRUE(fan.on_boundary[0]);
  auto cone_and_fin = double_cone;  // a third face on the hub's edge 0-1
  cone_and_fin.insert(cone_and_fin.end(), {0, 1, 42});
  // Non-manifold (three faces on an edge; opposite orientations): the full topology, with the fan.
  for(const auto& [n, tri] : {std::make_pair(5, Working_array<int>{0, 1, 2, 1, 0, 3, 0, 1, 4}),
                              std::make_pair(4, Working_array<int>{0, 1, 2, 0, 1, 3}),
                              std::make_pair(43, cone_and_fin)}) {
    const auto t = build_corner_topology(n, tri);
    EXPECT_TRUE(t.has_pattern());
    EXPECT_FALSE(t.manifold);
    EXPECT_EQ(t.fan_slot, build_topology(n, tri).fan_slot);
  }
}

namespace {

/// Positions for the synthetic triangle lists of CotangentRowsEqualTheFilledPattern: `ring`
/// vertices on a circle after `hubs` at (0, 0, +-1).
lapmesh::internal::Positions circle_with_hubs(int hubs, int ring)
{
  lapmesh::internal::Positions P(hubs + ring, 3);
  for(int h = 0; h < hubs; ++h) P.row(h) << 0.1 * h, 0.0, h == 0 ? 1.0 : -1.0;
  for(int k = 0; k < ring; ++k) {
    const double a = 2 * M_PI * k / (ring + 1);  // an open fan's last face is not flat
    P.row(hubs + k) << std::cos(a), std::sin(a), 0.05 * (k % 3);
  }
  return P;
}

lapmesh::internal::Positions soup_positions(const lapmesh::Triangle_soup& soup)
{
  lapmesh::internal::Positions P(Eigen::Index(soup.points.size()), 3);
  for(std::size_t i = 0; i < soup.points.size(); ++i)
    P.row(Eigen::Index(i)) << soup.points[i][0], soup.points[i][1], soup.points[i][2];
  return P;
}

/// A triangle list over vertices 0..n-1 with its positions.
struct Triangles_case
{
  std::string name;
  int n;
  Working_array<int> tri;
  lapmesh::internal::Positions P;
};

Triangles_case triangles_case(const std::string& name, const lapmesh::Triangle_soup& soup)
{
  auto [n, tri] = flat(soup);
  return {name, n, std::move(tri), soup_positions(soup)};
}

/// Double cones of `ring` faces around each of two hubs (0 and 1), closed: rows longer than a
/// short sort's.
Working_array<int> double_cone(int ring)
{
  Working_array<int> tri;
  for(int i = 0; i < ring; ++i) {
    const int j = 2 + i, k = 2 + (i + 1) % ring;
    tri.insert(tri.end(), {0, j, k, 1, k, j});
  }
  return tri;
}

/// Expects `actual` to equal `expected` bit for bit: its compressed storage and its mass.
void expect_same_pencil_bits(const lapmesh::Laplacian_pencil& expected, const lapmesh::Laplacian_pencil& actual,
                             const std::string& what)
{
  const Eigen::Index n = expected.stiffness.rows();
  const std::size_t nnz = std::size_t(expected.stiffness.nonZeros());
  ASSERT_EQ(actual.stiffness.rows(), n) << what;
  ASSERT_EQ(std::size_t(actual.stiffness.nonZeros()), nnz) << what;
  EXPECT_TRUE(actual.stiffness.isCompressed()) << what;
  EXPECT_TRUE(std::equal(expected.stiffness.outerIndexPtr(), expected.stiffness.outerIndexPtr() + n + 1,
                         actual.stiffness.outerIndexPtr()))
    << what;
  EXPECT_TRUE(std::equal(expected.stiffness.innerIndexPtr(), expected.stiffness.innerIndexPtr() + nnz,
                         actual.stiffness.innerIndexPtr()))
    << what;
  EXPECT_TRUE(std::equal(expected.stiffness.valuePtr(), expected.stiffness.valuePtr() + nnz,
                         actual.stiffness.valuePtr()))
    << what;
  EXPECT_TRUE(actual.mass == expected.mass) << what;
}

} // namespace

// The serial cotangent pencil builds the pattern's rows with their values straight into the
// matrix, on the corner incidence alone. It must equal, entry for entry and bit for bit, the
// pattern's topology filled from its slots, whatever the bound on the entries the caller gives:
// exact, generous (the matrix then holds fewer than it has room for), unknown, or too small
// (the rows are counted, then written again).
TEST(Operators, CotangentRowsEqualTheFilledPattern)
{
  using lapmesh::internal::build_corner_incidence;
  using lapmesh::internal::build_topology;
  using lapmesh::internal::Positions;
  std::vector<Triangles_case> cases = {triangles_case("torus", lapmesh::torus(12, 8)),
                                       triangles_case("plane patch", lapmesh::plane_patch(7, 0.3)),
                                       triangles_case("icosphere", lapmesh::icosphere(2))};
  const Working_array<int> cone = double_cone(40);  // hubs of 40 corners
  Working_array<int> open_fan;
  for(int i = 0; i < 39; ++i) open_fan.insert(open_fan.end(), {0, 1 + i, 2 + i});
  cases.push_back({"double cone", 42, cone, circle_with_hubs(2, 40)});
  cases.push_back({"open fan", 41, open_fan, circle_with_hubs(1, 40)});
  cases.push_back({"two triangles sharing a vertex", 5, {0, 1, 2, 0, 3, 4}, circle_with_hubs(1, 4)});
  for(const auto& c : cases)
    for(const auto area :
        {lapmesh::Vertex_area::barycentric, lapmesh::Vertex_area::voronoi, lapmesh::Vertex_area::mixed}) {
      const std::string what = c.name + ", " + lapmesh::to_string(area);
      lapmesh::Laplacian_pencil filled;
      const auto t = build_topology(c.n, c.tri);
      lapmesh::internal::assemble_pencil(t, c.P, lapmesh::Laplacian::cotangent, area, false, filled);
      const std::size_t exact = std::size_t(filled.stiffness.nonZeros());
      for(const std::size_t bound : {exact, exact + 7, std::size_t(0), std::size_t(c.n)}) {
        lapmesh::Laplacian_pencil by_rows;
        lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(c.n, c.tri), c.P, area, bound,
                                                             false, by_rows);
        expect_same_pencil_bits(filled, by_rows, what + ", bound " + std::to_string(bound));
      }
    }
  // A non-manifold edge (a third face on the double cone's edge 0-2) is named as the pattern names it.
  auto fin = cone;
  fin.insert(fin.end(), {0, 2, 42});
  Positions P(43, 3);
  P << circle_with_hubs(2, 40), Eigen::RowVector3d(0.5, 0.5, 2.0);
  lapmesh::Laplacian_pencil out;
  const std::string by_pattern = mesh_error_message([&] {
    lapmesh::internal::assemble_pencil(build_topology(43, fin), P, lapmesh::Laplacian::cotangent,
                                       lapmesh::Vertex_area::mixed, false, out);
  });
  EXPECT_NE(by_pattern.find("is non-manifold"), std::string::npos) << by_pattern;
  EXPECT_EQ(mesh_error_message([&] {
              lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(43, fin), P,
                                                                   lapmesh::Vertex_area::mixed, 0, false, out);
            }),
            by_pattern);
  // With a zero-area face too (vertex 3 on vertex 2), the edge is still named first.
  P.row(3) = P.row(2);
  EXPECT_EQ(mesh_error_message([&] {
              lapmesh::internal::assemble_pencil(build_topology(43, fin), P, lapmesh::Laplacian::cotangent,
                                                 lapmesh::Vertex_area::mixed, false, out);
            }),
            by_pattern);
  EXPECT_EQ(mesh_error_message([&] {
              lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(43, fin), P,
                                                                   lapmesh::Vertex_area::mixed, 0, false, out);
            }),
            by_pattern);
  EXPECT_NE(mesh_error_message([&] {
              lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(42, cone),
                                                                   P.topRows(42), lapmesh::Vertex_area::mixed, 0,
                                                                   false, out);
            }).find("has zero area"),
            std::string::npos)
    << "the control: without the fin, the face is named";
}

// In parallel each part writes its rows into a slice of the matrix placed as if every vertex were
// interior: a closed manifold mesh fills them exactly; a boundary vertex, a face given twice or a
// row longer than its corners make a part overflow its slice, or leave it short, and the rows are
// written again. Either way the matrix is the serial one, bit for bit, and a non-manifold edge
// gets the same message. Parts of a few dozen rows stand in for the large meshes' parts.
TEST(Operators, ParallelCotangentRowsEqualTheSerialOnes)
{
  using lapmesh::internal::build_corner_incidence;
  using lapmesh::internal::Positions;
  const lapmesh::Triangle_soup torus = lapmesh::torus(40, 20);
  std::vector<Triangles_case> cases = {triangles_case("torus", torus),
                                       triangles_case("plane patch", lapmesh::plane_patch(30, 0.3)),
                                       triangles_case("shuffled torus", shuffled(torus, 11))};
  const Triangles_case closed = cases[0];
  const int middle = int(closed.tri.size() / 6);
  Working_array<int> hole = closed.tri, twice = closed.tri;
  hole.erase(hole.begin() + 3 * middle, hole.begin() + 3 * middle + 3);
  twice.insert(twice.end(), closed.tri.begin() + 3 * middle, closed.tri.begin() + 3 * middle + 3);
  cases.push_back({"torus with a hole", closed.n, hole, closed.P});
  const Working_array<int> cone = double_cone(40);  // hubs of 40 corners
  cases.push_back({"double cone", 42, cone, circle_with_hubs(2, 40)});
  Working_array<int> fin = cone;
  fin.insert(fin.end(), {0, 2, 41});
  Positions flattened = circle_with_hubs(2, 40);
  flattened.row(3) = flattened.row(2);  // faces of zero area beside the fin
  const std::vector<Triangles_case> refused = {{"a face given twice", closed.n, twice, closed.P},
                                               {"a fin on the double cone", 42, fin, circle_with_hubs(2, 40)},
                                               {"a fin and faces of zero area", 42, fin, flattened}};
#ifdef CGAL_LINKED_WITH_TBB
  for(int threads : {3, 8}) {
    tbb::global_control allowed(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    tbb::task_arena(threads).execute([&] {
      for(const auto& c : cases)
        for(const int rows_per_part : {7, 37, 1000}) {
          lapmesh::Laplacian_pencil serial, parallel;
          const std::size_t bound = std::size_t(c.n) + c.tri.size();
          lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(c.n, c.tri), c.P,
                                                               lapmesh::Vertex_area::mixed, bound, false, serial);
          lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(c.n, c.tri), c.P,
                                                               lapmesh::Vertex_area::mixed, bound, true, parallel,
                                                               [] {}, rows_per_part);
          expect_same_pencil_bits(serial, parallel,
                                  c.name + ", " + std::to_string(threads) + " threads, parts of " +
                                    std::to_string(rows_per_part));
        }
      for(const auto& c : refused) {
        lapmesh::Laplacian_pencil out;
        const std::string serial = mesh_error_message([&] {
          lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(c.n, c.tri), c.P,
                                                               lapmesh::Vertex_area::mixed, 0, false, out);
        });
        EXPECT_NE(serial.find("is non-manifold"), std::string::npos) << c.name << ": " << serial;
        EXPECT_EQ(mesh_error_message([&] {
                    lapmesh::internal::assemble_cotangent_pencil_by_rows(build_corner_incidence(c.n, c.tri), c.P,
                                                                         lapmesh::Vertex_area::mixed, 0, true, out,
                                                                         [] {}, 7);
                  }),
                  serial)
          << c.name;
      }
    });
  }
#else
  FAIL() << "lapmesh was built without TBB (libtbb-dev): its parallel path is not tested";
#endif
}

// The bound on the entries comes from the graph's edges, which may be more than its faces'
// (an edge of no face): the matrix is the same, its spare room unused.
TEST(Operators, ThePencilOfAGraphWithAnEdgeOfNoFaceIsThatOfItsFaces)
{
  const Mesh m = to_mesh(lapmesh::torus(10, 6));
  Mesh with_edge = m;
  const auto a = with_edge.add_vertex(Point(5, 5, 5)), b = with_edge.add_vertex(Point(6, 5, 5));
  CGAL::Euler::add_edge(a, b, with_edge);
  ASSERT_EQ(num_edges(with_edge), num_edges(m) + 1);
  const auto p = lapmesh::laplacian_pencil(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const auto q = lapmesh::laplacian_pencil(with_edge, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const Eigen::Index n = p.stiffness.rows();
  ASSERT_EQ(q.stiffness.rows(), n + 2);
  EXPECT_EQ(q.stiffness.nonZeros(), p.stiffness.nonZeros());
  EXPECT_TRUE(Eigen::MatrixXd(q.stiffness.topLeftCorner(n, n)) == Eigen::MatrixXd(p.stiffness));
  EXPECT_TRUE(q.mass.head(n) == p.mass);
  EXPECT_TRUE(q.mass.tail(2).isZero(0.0));
  // The uniform stiffness off the graph's edges, sized for all of them, likewise.
  const Eigen::SparseMatrix<double> W = lapmesh::uniform_stiffness_matrix(m), V = lapmesh::uniform_stiffness_matrix(with_edge);
  ASSERT_EQ(V.rows(), n + 2);
  EXPECT_EQ(V.nonZeros(), W.nonZeros());
  EXPECT_EQ(V.outerIndexPtr()[n + 2], W.nonZeros());
  EXPECT_TRUE(Eigen::MatrixXd(V.topLeftCorner(n, n)) == Eigen::MatrixXd(W));
}

TEST(Operators, PencilsMoveWithoutCopyingTheirStorage)
{
  // Eigen 3.4's sparse matrix copies where it is moved; a pencil must not.
  const Mesh m = jittered_sphere();
  lapmesh::Laplacian_pencil p = lapmesh::laplacian_pencil(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const Eigen::MatrixXd S = p.stiffness;
  const Eigen::VectorXd M = p.mass;
  const double* values = p.stiffness.valuePtr();
  const double* mass = p.mass.data();
  lapmesh::Laplacian_pencil q(std::move(p));
  EXPECT_EQ(q.stiffness.valuePtr(), values);
  EXPECT_EQ(q.mass.data(), mass);
  EXPECT_EQ(p.stiffness.nonZeros(), 0);
  EXPECT_EQ(p.mass.size(), 0);
  lapmesh::Laplacian_pencil r = lapmesh::laplacian_pencil(m);
  r = std::move(q);
  EXPECT_EQ(r.stiffness.valuePtr(), values);
  EXPECT_EQ(r.mass.data(), mass);
  EXPECT_EQ((Eigen::MatrixXd(r.stiffness) - S).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(r.mass, M);
  // A copy is a copy; a pencil built from (S, M) holds them.
  const lapmesh::Laplacian_pencil c = r;
  EXPECT_NE(c.stiffness.valuePtr(), values);
  EXPECT_EQ((Eigen::MatrixXd(c.stiffness) - S).cwiseAbs().maxCoeff(), 0.0);
  const lapmesh::Laplacian_pencil built(c.stiffness, c.mass);
  EXPECT_EQ((Eigen::MatrixXd(built.stiffness) - S).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(built.mass, M);
  // The stiffness matrices returned alone are the pencils' (swapped out of them).
  EXPECT_EQ((Eigen::MatrixXd(lapmesh::cotangent_stiffness_matrix(m)) -
             Eigen::MatrixXd(lapmesh::laplacian_pencil(m).stiffness)).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((Eigen::MatrixXd(lapmesh::uniform_stiffness_matrix(m)) -
             Eigen::MatrixXd(lapmesh::laplacian_pencil(m, LP::laplacian(lapmesh::Laplacian::uniform)).stiffness))
              .cwiseAbs().maxCoeff(), 0.0);
}

#ifdef __linux__
TEST(Operators, LargeWorkingArraysLieInMappingsOfTheirOwnInWholeHugePages)
{
  using lapmesh::internal::Working_array;
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  // The mapping that holds `address`, from /proc/self/smaps: its bounds and its VmFlags line.
  struct Mapping
  {
    std::uintptr_t begin = 0, end = 0;
    std::string flags;
  };
  const auto mapping_of = [](const void* address) {
    const auto a = reinterpret_cast<std::uintptr_t>(address);
    std::ifstream smaps("/proc/self/smaps");
    Mapping found;
    bool inside = false;
    for(std::string line; std::getline(smaps, line);) {
      std::uintptr_t begin = 0, end = 0;
      char dash = 0;
      std::istringstream header(line);
      if(header >> std::hex >> begin >> dash >> end && dash == '-' && line.find(':') > line.find(' ')) {
        inside = begin <= a && a < end;
        if(inside) found = {begin, end, ""};
      } else if(inside && line.rfind("VmFlags:", 0) == 0) {
        found.flags = line;
      }
    }
    return found;
  };
  constexpr std::uintptr_t huge = std::uintptr_t(1) << 21;

  // Grown by push_back, the array moves from operator new to mappings of its own and keeps its values.
  Working_array<int> grown;
  for(int i = 0; i < (3 << 20); ++i) grown.push_back(i);
  for(int i = 0; i < (3 << 20); ++i)
    if(grown[std::size_t(i)] != i) FAIL() << "value " << i << " lost in a reallocation";
  const std::size_t bytes = sizeof(int) * grown.capacity();
  ASSERT_GE(bytes, lapmesh::internal::huge_page_mapping_min_bytes);
  const auto address = reinterpret_cast<std::uintptr_t>(grown.data());
  EXPECT_EQ(address % huge, 0u);
  // Its own whole 2 MiB pages, advised huge. A reallocation's new mapping takes over the pages
  // of the cached one before it (they stay an area of the kernel's apart), so the array may lie
  // in several areas, one after the other; a neighbouring area with the same flags may merge.
  const Mapping m = mapping_of(grown.data());
  ASSERT_NE(m.end, 0u) << "no mapping holds the array";
  EXPECT_LE(m.begin, address);
  const bool advice_visible = std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled").good();
  const std::uintptr_t end = address + (bytes + huge - 1) / huge * huge;
  for(Mapping part = m;;) {
    if(advice_visible) {
      EXPECT_NE(part.flags.find(" hg"), std::string::npos) << "not advised huge pages: " << part.flags;
    }
    if(part.end >= end) break;
    const Mapping next = mapping_of(reinterpret_cast<const void*>(part.end));
    ASSERT_EQ(next.begin, part.end) << "a gap in the array's pages";
    part = next;
  }

  // Under 4 MiB: a mapping of its own in small pages, not advised huge.
  Working_array<int> small(std::size_t(1) << 18);
  std::iota(small.begin(), small.end(), 0);
  EXPECT_LT(sizeof(int) * small.capacity(), lapmesh::internal::huge_page_mapping_min_bytes);
  EXPECT_GE(sizeof(int) * small.capacity(), lapmesh::internal::small_mapping_min_bytes);
  EXPECT_EQ(small.back(), (1 << 18) - 1);
  // Its own pages: it starts on a page (operator new's blocks start past a header); the kernel
  // may merge its mapping with a neighbouring one of the same flags.
  const auto small_address = reinterpret_cast<std::uintptr_t>(small.data());
  EXPECT_EQ(small_address % 4096, 0u);
  const Mapping small_mapping = mapping_of(small.data());
  EXPECT_LE(small_mapping.begin, small_address);
  EXPECT_GE(small_mapping.end, small_address + sizeof(int) * small.capacity());
  EXPECT_EQ(small_mapping.flags.find(" hg"), std::string::npos);
  // Under 256 KiB: operator new, with no advice.
  Working_array<int> tiny(std::size_t(1) << 12);
  std::iota(tiny.begin(), tiny.end(), 0);
  EXPECT_LT(sizeof(int) * tiny.capacity(), lapmesh::internal::small_mapping_min_bytes);
  EXPECT_EQ(tiny.back(), (1 << 12) - 1);
  EXPECT_EQ(mapping_of(tiny.data()).flags.find(" hg"), std::string::npos);

  // Freed with the cache off: the mapping is gone (unless another one has taken the address since).
  const std::size_t limit = lapmesh::working_memory_cache_limit();
  lapmesh::set_working_memory_cache_limit(0);
  grown = Working_array<int>();
  lapmesh::set_working_memory_cache_limit(limit);
  const Mapping after = mapping_of(reinterpret_cast<const void*>(address));
  EXPECT_TRUE(after.end == 0 || after.flags.find(" hg") == std::string::npos ||
              after.begin != m.begin || after.end != m.end);
}

TEST(Operators, FreedWorkingArraysAreKeptForTheNextCallWithinTheLimitAndUsedBeforeFreshPages)
{
  using lapmesh::internal::Working_array;
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  const std::size_t limit = lapmesh::working_memory_cache_limit();
  ASSERT_GE(limit, std::size_t(64) << 20) << "the default limit holds the arrays of a large mesh";
  lapmesh::release_working_memory();
  ASSERT_EQ(lapmesh::cached_working_memory(), 0u);
  constexpr std::size_t huge = std::size_t(1) << 21;
  const std::size_t count = (std::size_t(6) << 20) / sizeof(double);  // 6 MiB: three huge pages

  // A freed array's mapping is cached and serves the next array of that size: same address,
  // values still there (nothing is zeroed), the cache empty again.
  auto* first = new Working_array<double>(count);
  std::fill(first->begin(), first->end(), 2.5);
  const double* address = first->data();
  delete first;
  EXPECT_EQ(lapmesh::cached_working_memory(), 3 * huge);
  Working_array<double> again(count);
  EXPECT_EQ(again.data(), address);
  EXPECT_EQ(again[count / 2], 2.5);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);

  // An array takes the head of the smallest cached mapping that holds it; the tail stays cached.
  const std::size_t mib = (std::size_t(1) << 20) / sizeof(double);
  Working_array<double> a(5 * mib), b(12 * mib);  // 3 and 6 huge pages
  const double *a_address = a.data(), *b_address = b.data();
  Working_array<double>().swap(a);
  Working_array<double>().swap(b);
  EXPECT_EQ(lapmesh::cached_working_memory(), 9 * huge);
  Working_array<double> c(9 * mib / 2);  // 3 huge pages: a's mapping
  EXPECT_EQ(c.data(), a_address);
  EXPECT_EQ(lapmesh::cached_working_memory(), 6 * huge);
  Working_array<double> d(9 * mib / 2);  // the head of b's mapping
  EXPECT_EQ(d.data(), b_address);
  EXPECT_EQ(lapmesh::cached_working_memory(), 3 * huge);
  Working_array<double> tail(6 * mib);  // b's tail
  EXPECT_EQ(tail.data(), b_address + 6 * mib);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);

  // One that no cached mapping holds: a new mapping takes over the cached pages, oldest first,
  // with what was written in them (fresh pages would read zero), and the cache is left empty.
  std::fill(tail.begin(), tail.end(), 1.5);
  std::fill(c.begin(), c.end(), 3.5);
  Working_array<double>().swap(tail);
  Working_array<double>().swap(c);
  EXPECT_EQ(lapmesh::cached_working_memory(), 6 * huge);
  Working_array<double> e(18 * mib);  // 9 huge pages
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  EXPECT_EQ(std::count(e.begin(), e.begin() + 6 * mib, 1.5), std::ptrdiff_t(6 * mib));
  EXPECT_EQ(std::count(e.begin() + 6 * mib, e.begin() + 6 * mib + 9 * mib / 2, 3.5), std::ptrdiff_t(9 * mib / 2));
  EXPECT_EQ(std::count(e.begin() + 12 * mib, e.end(), 0.0), std::ptrdiff_t(6 * mib));
  Working_array<double>().swap(d);
  Working_array<double>().swap(e);
  EXPECT_EQ(lapmesh::cached_working_memory(), 12 * huge);

  // The limit: over it, the oldest mappings are handed back; a mapping larger than the limit is
  // not kept; 0 keeps nothing; release_working_memory() hands back all and says how much.
  lapmesh::set_working_memory_cache_limit(10 * huge);
  EXPECT_EQ(lapmesh::working_memory_cache_limit(), 10 * huge);
  EXPECT_EQ(lapmesh::cached_working_memory(), 9 * huge);  // d's, the older, went first
  {
    // A new mapping that takes over e's, itself made of moved pieces, and is too large to keep.
    Working_array<double> big(24 * mib);
    EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
    EXPECT_EQ(std::count(big.begin(), big.begin() + 6 * mib, 1.5), std::ptrdiff_t(6 * mib));
    EXPECT_EQ(std::count(big.begin() + 6 * mib, big.begin() + 6 * mib + 9 * mib / 2, 3.5), std::ptrdiff_t(9 * mib / 2));
  }
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  { Working_array<double> kept(count); }
  EXPECT_EQ(lapmesh::release_working_memory(), 3 * huge);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  lapmesh::set_working_memory_cache_limit(0);
  { Working_array<double> off(count); }
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  lapmesh::set_working_memory_cache_limit(limit);

  // Below 256 KiB an array comes from operator new and is never cached.
  { Working_array<double> heap((std::size_t(128) << 10) / sizeof(double)); }
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);

  // release_to_system() empties an array and hands its mapping back instead of caching it; the
  // arrays freed after it are cached again.
  Working_array<double> handed_back(count), kept(count);
  lapmesh::internal::release_to_system(handed_back);
  EXPECT_TRUE(handed_back.empty());
  EXPECT_EQ(handed_back.capacity(), 0u);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  Working_array<double>().swap(kept);
  EXPECT_EQ(lapmesh::cached_working_memory(), 3 * huge);
  lapmesh::release_working_memory();
}

TEST(Operators, WorkingArraysUnder4MiBAreKeptForTheNextArrayOfTheirExactSize)
{
  using lapmesh::internal::Working_array;
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  const std::size_t limit = lapmesh::working_memory_cache_limit();
  lapmesh::release_working_memory();
  const std::size_t kib = 1024 / sizeof(double);

  // Freed, a 1 MiB array's mapping is kept in whole pages and serves the next array of its size,
  // values and all; an array of another size, larger or smaller, does not take it.
  auto* first = new Working_array<double>(1024 * kib);
  std::fill(first->begin(), first->end(), 4.5);
  const double* address = first->data();
  delete first;
  EXPECT_EQ(lapmesh::cached_working_memory(), std::size_t(1) << 20);
  {
    Working_array<double> smaller(512 * kib), larger(2048 * kib);
    EXPECT_NE(smaller.data(), address);
    EXPECT_NE(larger.data(), address);
    EXPECT_EQ(lapmesh::cached_working_memory(), std::size_t(1) << 20);
  }
  const std::size_t half_mib = std::size_t(1) << 19;
  EXPECT_EQ(lapmesh::cached_working_memory(), 7 * half_mib);  // oldest first: 1, 2 and 0.5 MiB
  Working_array<double> again(1024 * kib - 1);  // the same whole pages
  EXPECT_EQ(again.data(), address);
  EXPECT_EQ(again[100 * kib], 4.5);
  EXPECT_EQ(lapmesh::cached_working_memory(), 5 * half_mib);

  // release_to_system() keeps it all the same: handed back, it would be faulted in afresh at the
  // next call, for little memory.
  lapmesh::internal::release_to_system(again);
  EXPECT_EQ(lapmesh::cached_working_memory(), 7 * half_mib);  // 2, 0.5 and 1 MiB

  // The small arrays take a sixteenth of the limit: over it, the oldest go first.
  lapmesh::set_working_memory_cache_limit(std::size_t(32) << 20);  // 2 MiB for the small arrays
  EXPECT_EQ(lapmesh::working_memory_cache_limit(), std::size_t(32) << 20);
  EXPECT_EQ(lapmesh::cached_working_memory(), 3 * half_mib);  // the 2 MiB one went
  { Working_array<double> other(1536 * kib); }
  EXPECT_EQ(lapmesh::cached_working_memory(), 3 * half_mib);  // the new one alone
  Working_array<double> reuse(1536 * kib);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  { Working_array<double> too_large(3072 * kib); }
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  lapmesh::set_working_memory_cache_limit(0);
  Working_array<double>().swap(reuse);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
  lapmesh::set_working_memory_cache_limit(limit);
  EXPECT_EQ(lapmesh::working_memory_cache_limit(), limit);

  // release_working_memory() hands both caches back and says how much.
  { Working_array<double> small(1024 * kib), large(1024 * 1024 * kib / 128); }  // 1 MiB and 8 MiB
  EXPECT_EQ(lapmesh::release_working_memory(), std::size_t(9) << 20);
  EXPECT_EQ(lapmesh::cached_working_memory(), 0u);
}

// laplacian_pencil() hands the positions, the triangles and the corner lists back before it
// allocates the matrix: with the cache emptied first, what it leaves cached afterwards is the
// rest of the topology (the pattern and its corner slots) and the cotangents, not the arrays of
// one entry per corner or per face vertex. (Arrays under 4 MiB are kept all the same, apart.)
TEST(Operators, ThePencilKeepsNoPatternSlotsBesideItsMatrix)
{
  ASSERT_TRUE(lapmesh::huge_pages_enabled()) << "the test runs with huge pages on (LAPMESH_HUGE_PAGES unset)";
  const Mesh m = to_mesh(lapmesh::torus(800, 400));  // 320k vertices: every corner array over 4 MiB
  const std::size_t corners = 3 * num_faces(m), nonzeros = num_vertices(m) + 2 * num_edges(m);
  const auto whole_huge_pages = [](std::size_t bytes) { return ((bytes + (std::size_t(1) << 21) - 1) >> 21) << 21; };
  lapmesh::release_working_memory();
  const auto pencil = lapmesh::laplacian_pencil(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  ASSERT_EQ(std::size_t(pencil.stiffness.nonZeros()), nonzeros);
  // The large working arrays of the call, cached when it ends: the triangles and the corner lists
  // (one index per corner each) and the cotangents (one per corner). The pattern's slots (two
  // corners per entry) and a second copy of its indices would be among them.
  const std::size_t expected =
    2 * whole_huge_pages(corners * sizeof(int)) + whole_huge_pages(corners * sizeof(double));
  EXPECT_EQ(lapmesh::internal::Mapping_cache::large_arrays().cached_bytes(), expected);
  lapmesh::release_working_memory();
}
#endif
