// The command line's restart with transparent huge pages (src/huge_pages.h): when it is wanted,
// and that a restarted run writes exactly what an unrestarted one writes.
#include "huge_pages.h"
#include "test_helpers.h"

#include <lapmesh/io.h>
#include <lapmesh/shapes.h>

#include <cstdlib>
#include <filesystem>

using namespace lapmesh_test;
using lapmesh_cli::huge_pages_restart_wanted;

TEST(HugePages, RestartOnlyWhenTheKernelGivesThemOnRequestAndTheInputIsLarge)
{
  const auto large = lapmesh_cli::huge_pages_min_input_bytes, small = large - 1;
  const std::string madvise = "always [madvise] never\n";
  EXPECT_TRUE(huge_pages_restart_wanted(nullptr, nullptr, madvise, large));
  EXPECT_TRUE(huge_pages_restart_wanted("1", "glibc.malloc.arena_max=2", madvise, large));
  EXPECT_FALSE(huge_pages_restart_wanted(nullptr, nullptr, madvise, small));
  EXPECT_FALSE(huge_pages_restart_wanted(nullptr, nullptr, "[always] madvise never\n", large));  // already used
  EXPECT_FALSE(huge_pages_restart_wanted(nullptr, nullptr, "always madvise [never]\n", large));
  EXPECT_FALSE(huge_pages_restart_wanted(nullptr, nullptr, "", large));  // no transparent huge pages
  EXPECT_FALSE(huge_pages_restart_wanted("0", nullptr, madvise, large));  // switched off
  // The tunable is set: by the user, or this is the restarted run (no second restart).
  EXPECT_FALSE(huge_pages_restart_wanted(nullptr, "glibc.malloc.hugetlb=0", madvise, large));
  EXPECT_FALSE(huge_pages_restart_wanted(nullptr, "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=1", madvise, large));
}

TEST(HugePages, ALargeInputGivesTheSameOutputWithAndWithoutTheRestart)
{
  const std::string dir = scratch_dir(), in = dir + "/large_torus.off";
  const Mesh m = to_mesh(lapmesh::torus(330, 330, 1.0, 0.4));
  const auto [P, tris] = lapmesh::io::mesh_arrays(m);
  lapmesh::io::write_mesh(in, P, tris);
  ASSERT_GE(std::filesystem::file_size(in), lapmesh_cli::huge_pages_min_input_bytes);
  const char* previous = std::getenv("LAPMESH_HUGE_PAGES");
  const std::string saved = previous ? previous : "";

  unsetenv("LAPMESH_HUGE_PAGES");
  const Cli_result restarted = run_lapmesh("curvature " + in + " -o " + dir + "/restarted.csv -q");
  setenv("LAPMESH_HUGE_PAGES", "0", 1);
  const Cli_result plain = run_lapmesh("curvature " + in + " -o " + dir + "/plain.csv -q");
  if(previous)
    setenv("LAPMESH_HUGE_PAGES", saved.c_str(), 1);
  else
    unsetenv("LAPMESH_HUGE_PAGES");

  EXPECT_EQ(restarted.status, 0) << restarted.err;
  EXPECT_EQ(plain.status, 0) << plain.err;
  EXPECT_EQ(restarted.err, plain.err);
  const std::string a = read_file(dir + "/restarted.csv"), b = read_file(dir + "/plain.csv");
  EXPECT_GT(a.size(), 1000000u);
  EXPECT_TRUE(a == b) << "the outputs differ";
}
