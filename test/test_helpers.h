// Shared fixtures of the test suite and the benchmarks: mesh types and analytic meshes; for the
// tests (LAPMESH_TEST_TMP defined) also per-test scratch directories.
#ifndef LAPMESH_TEST_HELPERS_H
#define LAPMESH_TEST_HELPERS_H

#include <lapmesh/shapes.h>

#include <CGAL/Polyhedron_3.h>
#include <CGAL/Polyhedron_items_with_id_3.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/graph_traits_Polyhedron_3.h>

#ifdef LAPMESH_TEST_TMP  // the test suite (the benchmarks share the meshes, not GoogleTest)
#include <gtest/gtest.h>
#endif

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include <unistd.h>

namespace lapmesh_test {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
using Polyhedron = CGAL::Polyhedron_3<Kernel>;

template <typename Graph = Mesh>
Graph to_mesh(const lapmesh::Triangle_soup& soup)
{
  Graph g;
  if(!lapmesh::make_mesh(soup, g)) throw std::runtime_error("test mesh could not be built");
  return g;
}

/// Path of a mesh of CGAL's data set (libcgal-demo), unpacked at configure time.
inline std::string cgal_mesh(const std::string& name) { return std::string(LAPMESH_CGAL_MESHES) + "/" + name; }

#ifdef LAPMESH_TEST_TMP
/// A scratch directory of the running test, created on first use. ctest runs every TEST in a
/// process of its own, two at a time: fixed file names shared between tests would let
/// concurrent tests overwrite each other's inputs and captured output. Outside a test (in a
/// suite's SetUpTestSuite) the directory is the suite's, made unique by the process id, since
/// every process runs that set-up.
inline std::string scratch_dir()
{
  const ::testing::UnitTest* unit = ::testing::UnitTest::GetInstance();
  const ::testing::TestInfo* info = unit->current_test_info();
  const ::testing::TestSuite* suite = unit->current_test_suite();
  std::string name = info    ? std::string(info->test_suite_name()) + "." + info->name()
                     : suite ? std::string(suite->name()) + ".set_up." + std::to_string(::getpid())
                             : "outside_a_test." + std::to_string(::getpid());
  std::replace(name.begin(), name.end(), '/', '_');
  const std::string dir = std::string(LAPMESH_TEST_TMP) + "/" + name;
  std::filesystem::create_directories(dir);
  return dir;
}
#endif

/// Root-mean-square of a vector.
template <typename Vector>
double rms(const Vector& v)
{
  return std::sqrt(v.squaredNorm() / double(v.size()));
}

} // namespace lapmesh_test

#endif
