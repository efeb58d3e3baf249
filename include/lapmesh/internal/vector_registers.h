// Internal: short vectors of doubles for lapmesh's own kernels (the thin products of the block
// eigensolver in dense_products.h, the supernodal solves in supernodal_solve.h), written with the
// vector extensions of GCC and Clang.
//
// Why vector types rather than loops left to the compiler: in both kernels the unit of arithmetic
// is a row of a thin block (1 to 8 values), and short loops over such a row were vectorised well
// or badly depending on the optimisation level and on small changes to the source. With these
// types the arithmetic is vector code whatever the level. Loads and stores go through memcpy, so
// they need only the alignment of a double. A 4-wide vector is one register with AVX2 (the
// baseline build splits it in two), an 8-wide one only with AVX-512.
#ifndef LAPMESH_INTERNAL_VECTOR_REGISTERS_H
#define LAPMESH_INTERNAL_VECTOR_REGISTERS_H

#include <cstring>

#if defined(__GNUC__)  // GCC and Clang
#define LAPMESH_VECTOR_REGISTERS 1
#if defined(__x86_64__)
/// The kernels have builds for the baseline, AVX2 + FMA and AVX-512, among which the CPU's
/// features (cpu_features.h) choose at run time.
#define LAPMESH_X86_KERNEL_BUILDS 1
#endif
/// The kernels' helpers are always inlined: only then are they compiled for the target of the
/// build that calls them.
#define LAPMESH_KERNEL_INLINE __attribute__((always_inline)) inline
#else
#define LAPMESH_KERNEL_INLINE inline
#endif

#if defined(__GNUC__)
// The baseline build returns 32- and 64-byte vectors from these inlined helpers, for which GCC
// notes that the ABI differs with AVX: nothing crosses a call boundary.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

namespace lapmesh {
namespace internal {
namespace vector_registers {

#ifdef LAPMESH_VECTOR_REGISTERS
typedef double Vec2 __attribute__((vector_size(2 * sizeof(double)), aligned(sizeof(double))));
typedef double Vec4 __attribute__((vector_size(4 * sizeof(double)), aligned(sizeof(double))));
typedef double Vec8 __attribute__((vector_size(8 * sizeof(double)), aligned(sizeof(double))));
#endif

/// The number of doubles in Vec (a plain double counts as a vector of one).
template <typename Vec>
constexpr int width = int(sizeof(Vec) / sizeof(double));

template <typename Vec>
LAPMESH_KERNEL_INLINE Vec load(const double* p)
{
  Vec v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

template <typename Vec>
LAPMESH_KERNEL_INLINE void store(double* p, const Vec& v)
{
  std::memcpy(p, &v, sizeof v);
}

template <typename Vec>
LAPMESH_KERNEL_INLINE Vec zero()
{
  Vec v;
  std::memset(&v, 0, sizeof v);
  return v;
}

} // namespace vector_registers
} // namespace internal
} // namespace lapmesh

#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

#endif
