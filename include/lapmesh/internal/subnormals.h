// lapmesh — flushing subnormal numbers to zero during sparse factorisations.
//
// Why. The Cholesky factor of a smoothing system M - lambda S, where the mass dominates, decays
// with the distance from the diagonal: far fill entries underflow into the subnormal range,
// where every operation on Intel CPUs takes a slow micro-code path, and the factorisation takes
// several times as long (doc/benchmarks-history.md has the measurement). Subnormal values next to
// entries of order one change nothing a factorisation or a solve can resolve, so lapmesh flushes
// them, on the calling thread, for the duration of its own factorisations and solves, and
// restores the caller's setting afterwards.
#ifndef LAPMESH_INTERNAL_SUBNORMALS_H
#define LAPMESH_INTERNAL_SUBNORMALS_H

#if defined(__SSE2__) || defined(_M_X64)
#include <xmmintrin.h>
#define LAPMESH_HAS_MXCSR 1
#endif

namespace lapmesh {
namespace internal {

/// While alive, subnormal results are flushed to zero and subnormal operands read as zero on
/// this thread (x86-64: the FTZ and DAZ bits of MXCSR); elsewhere it does nothing.
class Subnormals_flushed_scope
{
public:
#ifdef LAPMESH_HAS_MXCSR
  Subnormals_flushed_scope() : m_saved(_mm_getcsr()) { _mm_setcsr(m_saved | flush_to_zero | denormals_are_zero); }
  ~Subnormals_flushed_scope() { _mm_setcsr(m_saved); }
#else
  Subnormals_flushed_scope() = default;
#endif
  Subnormals_flushed_scope(const Subnormals_flushed_scope&) = delete;
  Subnormals_flushed_scope& operator=(const Subnormals_flushed_scope&) = delete;

private:
#ifdef LAPMESH_HAS_MXCSR
  static constexpr unsigned flush_to_zero = 0x8000;
  static constexpr unsigned denormals_are_zero = 0x0040;
  unsigned m_saved;
#endif
};

} // namespace internal
} // namespace lapmesh

#endif
