// Compile-and-run check that lapmesh's own named parameters compose with CGAL's in 5.5:
// start a pack with ours, chain CGAL's members after it, append ours to a CGAL pack, and
// read every value and default back. A CGAL upgrade that breaks this fails to compile here.
#include "test_helpers.h"

#include <lapmesh/curvature.h>
#include <lapmesh/parameters.h>

using namespace lapmesh_test;
namespace LP = lapmesh::parameters;
using CGAL::parameters::choose_parameter;
using CGAL::parameters::get_parameter;
using CGAL::parameters::is_default_parameter;

TEST(Parameters, StartChainAppendAndDefaults)
{
  const auto np = LP::laplacian(lapmesh::Laplacian::uniform).number_of_iterations(3);
  EXPECT_EQ(get_parameter(np, lapmesh::internal_np::laplacian), lapmesh::Laplacian::uniform);
  EXPECT_EQ(get_parameter(np, CGAL::internal_np::number_of_iterations), 3);

  const auto appended = LP::vertex_area(lapmesh::Vertex_area::mixed, CGAL::parameters::number_of_iterations(7));
  EXPECT_EQ(get_parameter(appended, lapmesh::internal_np::vertex_area), lapmesh::Vertex_area::mixed);
  EXPECT_EQ(get_parameter(appended, CGAL::internal_np::number_of_iterations), 7);

  using Appended = std::decay_t<decltype(appended)>;
  static_assert(!is_default_parameter<Appended, lapmesh::internal_np::vertex_area_t>::value);
  static_assert(is_default_parameter<Appended, lapmesh::internal_np::laplacian_t>::value);
  EXPECT_EQ(choose_parameter(get_parameter(appended, lapmesh::internal_np::laplacian), lapmesh::Laplacian::cotangent),
            lapmesh::Laplacian::cotangent);
}

TEST(Parameters, CustomVertexPointMapIsUsed)
{
  // Curvature through a second point property (a sphere of radius 3) while the mesh's own
  // points describe the unit sphere.
  Mesh m = to_mesh(lapmesh::icosphere(3, 1.0));
  auto scaled = m.add_property_map<Mesh::Vertex_index, Point>("v:scaled").first;
  for(auto v : vertices(m)) scaled[v] = Point(3 * m.point(v).x(), 3 * m.point(v).y(), 3 * m.point(v).z());
  const auto unit = lapmesh::vertex_curvatures(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const auto three = lapmesh::vertex_curvatures(
    m, LP::vertex_area(lapmesh::Vertex_area::mixed, CGAL::parameters::vertex_point_map(scaled)));
  EXPECT_NEAR(unit.mean.mean(), 1.0, 1e-3);
  EXPECT_NEAR(three.mean.mean(), 1.0 / 3.0, 1e-3);
}

TEST(Parameters, StringConversionsRoundTrip)
{
  for(auto k : {lapmesh::Laplacian::uniform, lapmesh::Laplacian::cotangent})
    EXPECT_EQ(lapmesh::parse_laplacian(lapmesh::to_string(k)), k);
  for(auto a : {lapmesh::Vertex_area::barycentric, lapmesh::Vertex_area::voronoi, lapmesh::Vertex_area::mixed})
    EXPECT_EQ(lapmesh::parse_vertex_area(lapmesh::to_string(a)), a);
  EXPECT_FALSE(lapmesh::parse_laplacian("cotan").has_value());
  EXPECT_FALSE(lapmesh::parse_vertex_area("").has_value());
}
