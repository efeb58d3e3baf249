// lapmesh — a check of the BLAS the process runs on.
//
// CHOLMOD's supernodal Cholesky and the block Lanczos (the spectral solver and the implicit
// smoothing) spend much of their time in the BLAS. OpenBLAS built with DYNAMIC_ARCH picks its
// kernels from the CPU it detects at start-up; on some virtual machines it detects an old core
// ("Prescott", "Core2") or none ("Generic") on a CPU with AVX2 or AVX-512, and then runs kernels
// several times slower without any other sign. blas_core_warning() reports that case.
//
// OpenBLAS is looked up at run time (dlsym) in the process, not decided at configure time: on
// Debian the BLAS is chosen by the alternatives system when the program starts (libblas.so.3),
// and the development link libblas.so the build sees may name another BLAS than the one loaded.
// The check is active when lapmesh is built with a BLAS or with CHOLMOD (LAPMESH_HAS_BLAS or
// LAPMESH_HAS_CHOLMOD: their targets link libdl), on x86 with GCC or Clang; otherwise it always
// returns std::nullopt.
#ifndef LAPMESH_BLAS_H
#define LAPMESH_BLAS_H

#include <optional>
#include <string>

#if (defined(LAPMESH_HAS_BLAS) || defined(LAPMESH_HAS_CHOLMOD)) && (defined(__x86_64__) || defined(__i386__)) && \
  (defined(__GNUC__) || defined(__clang__)) && defined(__unix__)
#define LAPMESH_BLAS_CHECK 1
#include <dlfcn.h>

#include <algorithm>
#include <array>
#include <cctype>
#endif

namespace lapmesh {

/// The name of the core whose kernels the loaded OpenBLAS uses (openblas_get_corename(), e.g.
/// "Haswell", "Prescott"), std::nullopt when the process has no OpenBLAS loaded or the check is
/// not built in.
inline std::optional<std::string> openblas_core_name()
{
#ifdef LAPMESH_BLAS_CHECK
  using Name_function = char* (*)();
  const auto corename = reinterpret_cast<Name_function>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  if(!corename) return std::nullopt;
  const char* name = corename();
  if(!name) return std::nullopt;
  std::string s(name);
  while(!s.empty() && std::isspace((unsigned char)s.back())) s.pop_back();
  return s;
#else
  return std::nullopt;
#endif
}

namespace internal {

/// What blas_core_warning() and openblas_coretype_that_fits() judge: the loaded OpenBLAS runs
/// kernels without AVX2 (an old or generic core) on a CPU with AVX2 or AVX-512F.
struct Slow_openblas
{
  std::string core;      ///< openblas_get_corename()
  bool avx512 = false;   ///< the CPU has AVX-512F
  bool avx2_fma = false; ///< the CPU has AVX2 and FMA
  bool skylakex = false; ///< the CPU has what OpenBLAS's SkylakeX kernels use: AVX-512 F, CD, BW, DQ, VL
  bool dynamic = false;  ///< a DYNAMIC_ARCH build, which reads OPENBLAS_CORETYPE when it loads
};

inline std::optional<Slow_openblas> slow_openblas()
{
#ifdef LAPMESH_BLAS_CHECK
  const std::optional<std::string> core = openblas_core_name();
  if(!core) return std::nullopt;
  __builtin_cpu_init();
  Slow_openblas slow;
  slow.core = *core;
  const bool avx2 = __builtin_cpu_supports("avx2");
  slow.avx512 = __builtin_cpu_supports("avx512f");
  slow.avx2_fma = avx2 && __builtin_cpu_supports("fma");
  slow.skylakex = slow.avx2_fma && slow.avx512 && __builtin_cpu_supports("avx512cd") &&
                  __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
                  __builtin_cpu_supports("avx512vl");
  if(!avx2 && !slow.avx512) return std::nullopt;
  // OpenBLAS's x86 cores without AVX2 kernels (its DYNAMIC_ARCH names, compared in lower case).
  static constexpr std::array<const char*, 20> slow_cores = {
    "generic", "unknown", "katmai", "coppermine", "northwood", "prescott", "banias", "atom", "core2", "penryn",
    "dunnington", "nehalem", "sandybridge", "opteron", "opteron(sse3)", "barcelona", "bobcat", "bulldozer",
    "piledriver", "steamroller"};
  std::string lower = *core;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if(std::find_if(slow_cores.begin(), slow_cores.end(), [&](const char* s) { return lower == s; }) ==
     slow_cores.end())
    return std::nullopt;
  // OPENBLAS_CORETYPE is read only by a DYNAMIC_ARCH build (openblas_get_config() says which).
  using Config_function = char* (*)();
  const auto config = reinterpret_cast<Config_function>(dlsym(RTLD_DEFAULT, "openblas_get_config"));
  const char* config_text = config ? config() : nullptr;
  slow.dynamic = config_text && std::string(config_text).find("DYNAMIC_ARCH") != std::string::npos;
  return slow;
#else
  return std::nullopt;
#endif
}

} // namespace internal

/// A one-line warning when the loaded OpenBLAS uses kernels without AVX2 (an old or generic core)
/// on a CPU that has AVX2 or AVX-512F, e.g. "OpenBLAS uses its Prescott kernels on a CPU with
/// AVX2: set OPENBLAS_CORETYPE=Haswell (or SkylakeX) for full speed"; std::nullopt when the BLAS
/// is not OpenBLAS, its core is a current one, or the CPU has no AVX2. Cheap (no BLAS call):
/// meant to be called once at the start of a spectral or implicit run.
inline std::optional<std::string> blas_core_warning()
{
  const std::optional<internal::Slow_openblas> slow = internal::slow_openblas();
  if(!slow) return std::nullopt;
  std::string text =
    "OpenBLAS uses its " + slow->core + " kernels on a CPU with " + (slow->avx512 ? "AVX-512" : "AVX2") + ": ";
  if(slow->dynamic)
    text += slow->skylakex ? "set OPENBLAS_CORETYPE=SkylakeX (or Haswell) for full speed"
                           : "set OPENBLAS_CORETYPE=Haswell for full speed";
  else
    text += "use an OpenBLAS built for this CPU or with DYNAMIC_ARCH for full speed";
  return text;
}

/// The OPENBLAS_CORETYPE under which the loaded OpenBLAS would run kernels that fit this CPU, in
/// the case that blas_core_warning() reports, when the build reads the variable (DYNAMIC_ARCH):
/// "SkylakeX" on a CPU with the AVX-512 of those kernels (F, CD, BW, DQ, VL), where they ran
/// lapmesh's factorisations faster than Haswell's (doc/benchmarks.md); "Haswell" on one with
/// AVX2 and FMA; std::nullopt otherwise. OpenBLAS reads the variable when it is loaded, so only a
/// new process can use it (the command line restarts itself with it).
inline std::optional<std::string> openblas_coretype_that_fits()
{
  const std::optional<internal::Slow_openblas> slow = internal::slow_openblas();
  if(!slow || !slow->dynamic || !slow->avx2_fma) return std::nullopt;
  return std::string(slow->skylakex ? "SkylakeX" : "Haswell");
}

} // namespace lapmesh

#ifdef LAPMESH_BLAS_CHECK
#undef LAPMESH_BLAS_CHECK
#endif

#endif // LAPMESH_BLAS_H
