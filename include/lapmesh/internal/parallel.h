// Internal: the one place where lapmesh chooses between a serial loop and TBB.
#ifndef LAPMESH_INTERNAL_PARALLEL_H
#define LAPMESH_INTERNAL_PARALLEL_H

#include <CGAL/tags.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <type_traits>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#endif

namespace lapmesh {
namespace internal {

/// True for CGAL::Parallel_tag (and Parallel_if_available_tag when TBB is linked).
template <typename ConcurrencyTag>
constexpr bool is_parallel()
{
#ifdef CGAL_LINKED_WITH_TBB
  return std::is_convertible<ConcurrencyTag, CGAL::Parallel_tag>::value;
#else
  return false;
#endif
}

/// Calls body(i) for i in [0, n); in parallel blocks when `parallel` and TBB is available.
/// The bodies lapmesh passes write disjoint outputs, so no synchronisation is needed.
/// `grain` is the fewest indices a task takes; below twice that the loop stays serial.
template <typename IndexType, typename Body>
void for_each_index(IndexType n, bool parallel, const Body& body, IndexType grain = 2048)
{
#ifdef CGAL_LINKED_WITH_TBB
  if(parallel && n >= 2 * grain) {
    tbb::parallel_for(tbb::blocked_range<IndexType>(0, n, grain),
                      [&](const tbb::blocked_range<IndexType>& r) {
                        for(IndexType i = r.begin(); i != r.end(); ++i) body(i);
                      });
    return;
  }
#endif
  (void)parallel;
  (void)grain;
  for(IndexType i = 0; i < n; ++i) body(i);
}

/// How many parts of `part_size` for_each_part() splits [0, n) into.
template <typename IndexType>
IndexType part_count(IndexType n, IndexType part_size)
{
  return n == 0 ? 0 : (n - 1) / part_size + 1;
}

/// Splits [0, n) into consecutive parts of `part_size` (the last one shorter) and calls
/// body(part, begin, end) for each; in parallel when `parallel` and TBB is available. The
/// split depends on n and part_size only, so a body that keeps per-part results and merges
/// them in part order computes the same thing serially and in parallel.
template <typename IndexType, typename Body>
void for_each_part(IndexType n, IndexType part_size, bool parallel, const Body& body)
{
  const IndexType parts = part_count(n, part_size);
  for_each_index(parts, parallel && parts > 1, [&](IndexType p) {
    const IndexType begin = p * part_size;
    body(p, begin, n - begin < part_size ? n : begin + part_size);
  }, IndexType(1));
}

/// The smallest index recorded by a loop that may run in parallel: the first element a check
/// refuses, the one a serial loop would have stopped at, so that the error names the same one.
template <typename IndexType>
class First_index
{
public:
  static constexpr IndexType none = std::numeric_limits<IndexType>::max();
  void record(IndexType i)
  {
    IndexType current = m_first.load(std::memory_order_relaxed);
    while(i < current && !m_first.compare_exchange_weak(current, i, std::memory_order_relaxed)) {}
  }
  bool empty() const { return get() == none; }
  IndexType get() const { return m_first.load(std::memory_order_relaxed); }

private:
  std::atomic<IndexType> m_first{none};
};

/// How many threads a parallel loop may use: the current arena's, within a limit set by
/// tbb::global_control; 1 when not `parallel` or without TBB.
inline int thread_count(bool parallel)
{
#ifdef CGAL_LINKED_WITH_TBB
  if(parallel)
    return std::max(1, std::min(tbb::this_task_arena::max_concurrency(),
                                int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism))));
#endif
  (void)parallel;
  return 1;
}

} // namespace internal
} // namespace lapmesh

#endif
