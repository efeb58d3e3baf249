// A stand-in for OpenBLAS's two query functions, preloaded into the CLI (LD_PRELOAD) by
// blas_test.cpp: it answers as a DYNAMIC_ARCH OpenBLAS that detected the Prescott core would,
// whatever this CPU is, and names the core in OPENBLAS_CORETYPE when that is set.
#include <cstdlib>

extern "C" {

__attribute__((visibility("default"))) char* openblas_get_corename()
{
  static char prescott[] = "Prescott";
  char* chosen = std::getenv("OPENBLAS_CORETYPE");
  return chosen ? chosen : prescott;
}

__attribute__((visibility("default"))) char* openblas_get_config()
{
  static char config[] = "OpenBLAS stand-in DYNAMIC_ARCH";
  return config;
}

} // extern "C"
