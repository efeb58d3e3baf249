// Internal: the CPU features that choose between the builds of lapmesh's own kernels (the thin
// products of the block eigensolver, the supernodal solves), asked once per process.
#ifndef LAPMESH_INTERNAL_CPU_FEATURES_H
#define LAPMESH_INTERNAL_CPU_FEATURES_H

namespace lapmesh {
namespace internal {

/// Whether the CPU has AVX2 and FMA; false where the question cannot be asked (not x86-64 with
/// GCC or Clang), where the kernels have no AVX2 build either.
inline bool cpu_has_avx2_fma()
{
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
#else
  return false;
#endif
}

/// Whether the CPU has AVX-512 F and VL besides AVX2 and FMA: the third build of the kernels uses
/// 64-byte vectors and the 32 vector registers of AVX-512.
inline bool cpu_has_avx512()
{
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  static const bool has =
    cpu_has_avx2_fma() && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
  return has;
#else
  return false;
#endif
}

} // namespace internal
} // namespace lapmesh

#endif
