// The slow-BLAS warning (lapmesh/blas.h): `lapmesh spectrum` and `smooth --scheme implicit` print it
// once on stderr when OpenBLAS is forced to its Prescott kernels on a CPU with AVX2, and not otherwise.
// When OpenBLAS picked those kernels itself, the CLI restarts with fitting ones (src/restart.h).
#include "restart.h"
#include "test_helpers.h"

#include <lapmesh/blas.h>
#include <lapmesh/io.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace lapmesh_test;

namespace {

const std::string warning = "lapmesh: warning: OpenBLAS uses its Prescott kernels on a CPU with AVX";

std::size_t occurrences(const std::string& text, const std::string& what)
{
  std::size_t n = 0;
  for(auto at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

// The CLI runs on OpenBLAS (a DYNAMIC_ARCH build reads OPENBLAS_CORETYPE): Debian's libopenblas0.
bool cli_loads_openblas()
{
  return std::system(("ldd " + std::string(LAPMESH_CLI) + " | grep -q libopenblas").c_str()) == 0;
}

std::string sphere_file()
{
  const Mesh m = to_mesh(lapmesh::icosphere(2, 1.0));
  const auto [P, tris] = lapmesh::io::mesh_arrays(m);
  const std::string path = scratch_dir() + "/blas_sphere.off";
  lapmesh::io::write_mesh(path, P, tris);
  return path;
}

} // namespace

TEST(Blas, NoBlasCheckWithoutABlasInTheBuild)
{
  // This test executable links neither CHOLMOD nor a BLAS: the check is not built in.
  EXPECT_FALSE(lapmesh::openblas_core_name().has_value());
  EXPECT_FALSE(lapmesh::blas_core_warning().has_value());
}

TEST(Blas, SpectrumWarnsOnceWhenOpenBlasRunsPrescottKernelsOnAnAvx2Cpu)
{
  if(!cpu_has_avx2() || !cli_loads_openblas()) GTEST_SKIP() << "needs an AVX2 CPU and a CLI linked with OpenBLAS";
  const std::string in = sphere_file(), out = scratch_dir() + "/blas_spectrum.csv";
  const char* previous = std::getenv("OPENBLAS_CORETYPE");
  const std::string saved = previous ? previous : "";

  // Kernels that fit the CPU (OpenBLAS's own detection may pick Prescott on an AVX-512 CPU,
  // where the warning is then right): no warning.
  setenv("OPENBLAS_CORETYPE", "Haswell", 1);
  Cli_result r = run_lapmesh("spectrum " + in + " -o " + out + " -k 6 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err.find("OpenBLAS"), std::string::npos) << r.err;

  setenv("OPENBLAS_CORETYPE", "Prescott", 1);
  r = run_lapmesh("spectrum " + in + " -o " + out + " -k 6 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(occurrences(r.err, warning), 1u) << r.err;
  EXPECT_EQ(occurrences(r.err, "OPENBLAS_CORETYPE="), 1u) << r.err;
  EXPECT_EQ(read_file(out).rfind("index,eigenvalue\n", 0), 0u);
  // The implicit smoothing warns too, the explicit one (no factorisation) does not.
  r = run_lapmesh("smooth " + in + " -o " + scratch_dir() + "/blas_smooth.off --scheme implicit --lambda auto --iterations 2 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(occurrences(r.err, warning), 1u) << r.err;
  r = run_lapmesh("smooth " + in + " -o " + scratch_dir() + "/blas_smooth.off --scheme explicit --lambda auto --iterations 2 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err.find("OpenBLAS"), std::string::npos) << r.err;

  if(previous) setenv("OPENBLAS_CORETYPE", saved.c_str(), 1);
  else unsetenv("OPENBLAS_CORETYPE");
}

TEST(Blas, TheCliRestartsWithFittingKernelsWhenOpenBlasPicksSlowOnes)
{
  __builtin_cpu_init();
  if(!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma") || !cli_loads_openblas())
    GTEST_SKIP() << "needs a CPU with AVX2 and FMA and a CLI linked with OpenBLAS";
  const std::string in = sphere_file(), out = scratch_dir() + "/blas_restart.csv";
  const std::string dir = scratch_dir(), err_file = dir + "/blas_restart_stderr.txt";
  // The stand-in answers "Prescott" unless OPENBLAS_CORETYPE names a core: as an OpenBLAS that
  // detected Prescott. (A sanitizer's runtime must otherwise come first among the libraries.)
  const auto run = [&](const std::string& coretype, const std::string& args) {
    const std::string env = (coretype.empty() ? "env -u OPENBLAS_CORETYPE " : "env OPENBLAS_CORETYPE=" + coretype + " ") +
                            "LD_PRELOAD=" LAPMESH_FAKE_OPENBLAS_CORE
                            " ASAN_OPTIONS=\"${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0\" ";
    const int rc = std::system((env + LAPMESH_CLI + " " + args + " >/dev/null 2>" + err_file).c_str());
    return Cli_result{WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, "", read_file(err_file)};
  };
  // Unset: the CLI restarts with OPENBLAS_CORETYPE=SkylakeX or Haswell (as the CPU has AVX-512 or
  // not), which the stand-in then reports, so the run does not warn; without the restart it would.
  std::remove(out.c_str());
  Cli_result r = run("", "spectrum " + in + " -o " + out + " -k 6 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err.find("OpenBLAS"), std::string::npos) << r.err;
  EXPECT_EQ(read_file(out).rfind("index,eigenvalue\n", 0), 0u);
  r = run("", "smooth " + in + " -o " + dir + "/blas_restart.off --scheme implicit --lambda auto --iterations 2 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err.find("OpenBLAS"), std::string::npos) << r.err;
  // A value the user set is kept, and warned about.
  r = run("Prescott", "spectrum " + in + " -o " + out + " -k 6 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(occurrences(r.err, warning), 1u) << r.err;
}

TEST(Blas, OnlyTheSubcommandsThatFactoriseRestartForTheBlas)
{
  const auto uses = [](std::vector<std::string> words) {
    std::vector<char*> argv;
    for(std::string& w : words) argv.push_back(w.data());
    return lapmesh_cli::subcommand_uses_the_blas(int(argv.size()), argv.data());
  };
  for(const char* name : {"spectrum", "reconstruct", "smooth", "denoise-study", "view"})
    EXPECT_TRUE(uses({"lapmesh", name, "in.off"})) << name;
  EXPECT_FALSE(uses({"lapmesh", "curvature", "in.off"}));
  EXPECT_FALSE(uses({"lapmesh", "noise", "spectrum"}));  // a file named like a subcommand
  EXPECT_FALSE(uses({"lapmesh", "--version"}));
  EXPECT_FALSE(uses({"lapmesh"}));
}
