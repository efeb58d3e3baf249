// The slow-BLAS warning (lapmesh/blas.h): `lapmesh spectrum` and `smooth --scheme implicit` print it
// once on stderr when OpenBLAS is forced to its Prescott kernels on a CPU with AVX2, and not otherwise.
#include "test_helpers.h"

#include <lapmesh/blas.h>
#include <lapmesh/io.h>

#include <cstdlib>

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
