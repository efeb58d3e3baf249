// Shared fixtures of the test suite and the benchmarks: mesh types and analytic meshes; for the
// tests (LAPMESH_TEST_TMP defined) also per-test scratch directories, table-driven cases and
// (LAPMESH_CLI defined) the runner of the command-line tool.
#ifndef LAPMESH_TEST_HELPERS_H
#define LAPMESH_TEST_HELPERS_H

#include <lapmesh/errors.h>
#include <lapmesh/shapes.h>

#include <CGAL/Polyhedron_3.h>
#include <CGAL/Polyhedron_items_with_id_3.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/graph_traits_Polyhedron_3.h>

#include <Eigen/Core>

#ifdef LAPMESH_TEST_TMP  // the test suite (the benchmarks share the meshes, not GoogleTest)
#include <gtest/gtest.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <sys/wait.h>
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

/// Icospheres of the given radii (the first of level 3, the others of level 2), centred on the x
/// axis 3 apart, as one soup of several components.
inline lapmesh::Triangle_soup spheres(const std::vector<double>& radii)
{
  lapmesh::Triangle_soup all;
  for(std::size_t k = 0; k < radii.size(); ++k) {
    const lapmesh::Triangle_soup one = lapmesh::icosphere(k == 0 ? 3 : 2, radii[k]);
    const int offset = int(all.points.size());
    for(auto p : one.points) {
      p[0] += 3.0 * double(k);
      all.points.push_back(p);
    }
    for(auto t : one.triangles) all.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  }
  return all;
}

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

/// The message of the Mesh_error that `run` throws, or "no error".
template <typename Run>
std::string mesh_error_message(const Run& run)
{
  try {
    run();
  } catch(const lapmesh::Mesh_error& e) {
    return e.what();
  }
  return "no error";
}

/// The whole content of a file (empty when it cannot be read).
inline std::string read_file(const std::string& path)
{
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// The name of a case in failure messages: the string itself, the first member of a pair, or
/// what GoogleTest prints.
template <typename Case>
std::string case_name(const Case& c)
{
  if constexpr(std::is_convertible_v<const Case&, std::string>)
    return std::string(c);
  else
    return ::testing::PrintToString(c);
}
template <typename Name, typename Value>
std::string case_name(const std::pair<Name, Value>& c)
{
  return case_name(c.first);
}

/// Runs `test_case` on every case of a table (mesh files, argument lists...), every failure
/// message naming its case, in the manner of libigl's test_common::run_test_cases. A fatal
/// assertion ends that case only.
template <typename Cases, typename Function>
void run_test_cases(const Cases& cases, Function test_case)
{
  for(const auto& c : cases) {
    SCOPED_TRACE("case: " + case_name(c));
    test_case(c);
  }
}
template <typename Case, typename Function>
void run_test_cases(std::initializer_list<Case> cases, Function test_case)
{
  run_test_cases<std::initializer_list<Case>, Function>(cases, test_case);
}
/// The same with the cases' names given by `name_of(case)` (cases that are structs).
template <typename Cases, typename Name_of, typename Function>
void run_test_cases(const Cases& cases, Name_of name_of, Function test_case)
{
  for(const auto& c : cases) {
    SCOPED_TRACE("case: " + std::string(name_of(c)));
    test_case(c);
  }
}
#endif

#if defined(LAPMESH_TEST_TMP) && defined(LAPMESH_CLI)
/// What a run of the lapmesh executable gave: its exit status (-1 when it did not exit), stdout
/// and stderr.
struct Cli_result
{
  int status;
  std::string out, err;
};

/// Whether the CPU has AVX2 or AVX-512, asked as lapmesh::blas_core_warning() asks it.
inline bool cpu_has_avx2()
{
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") || __builtin_cpu_supports("avx512f");
}

/// Runs the lapmesh executable with `args` (shell words, as typed after `lapmesh`), capturing
/// both streams in files of the running test's scratch directory. OpenBLAS misdetects some
/// AVX-512 CPUs as Prescott, and the CLI then warns on stderr: unless a test chose a core
/// itself, the CLI runs with OpenBLAS's Haswell kernels on an AVX2 CPU, so that what it prints
/// does not depend on that detection (blas_test.cpp tests the warning).
inline Cli_result run_lapmesh(const std::string& args)
{
  const std::string dir = scratch_dir();
  const std::string out = dir + "/lapmesh_stdout.txt", err = dir + "/lapmesh_stderr.txt";
  static const bool avx2 = cpu_has_avx2();
  const std::string blas_core = !std::getenv("OPENBLAS_CORETYPE") && avx2 ? "OPENBLAS_CORETYPE=Haswell " : "";
  const int rc =
    std::system((blas_core + std::string(LAPMESH_CLI) + " " + args + " >" + out + " 2>" + err).c_str());
  return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, read_file(out), read_file(err)};
}
#endif

/// The vertex positions of a Surface_mesh, one row per vertex (in index order).
inline Eigen::MatrixXd positions(const Mesh& m)
{
  Eigen::MatrixXd P(num_vertices(m), 3);
  for(auto v : vertices(m)) P.row(v.idx()) << m.point(v).x(), m.point(v).y(), m.point(v).z();
  return P;
}

/// Root-mean-square of a vector.
template <typename Vector>
double rms(const Vector& v)
{
  return std::sqrt(v.squaredNorm() / double(v.size()));
}

} // namespace lapmesh_test

#endif
