// Internal: the one place where lapmesh chooses between a serial loop and TBB.
#ifndef LAPMESH_INTERNAL_PARALLEL_H
#define LAPMESH_INTERNAL_PARALLEL_H

#include <CGAL/tags.h>

#include <type_traits>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
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
template <typename IndexType, typename Body>
void for_each_index(IndexType n, bool parallel, const Body& body)
{
#ifdef CGAL_LINKED_WITH_TBB
  if(parallel && n > 4096) {
    tbb::parallel_for(tbb::blocked_range<IndexType>(0, n, 2048),
                      [&](const tbb::blocked_range<IndexType>& r) {
                        for(IndexType i = r.begin(); i != r.end(); ++i) body(i);
                      });
    return;
  }
#endif
  (void)parallel;
  for(IndexType i = 0; i < n; ++i) body(i);
}

} // namespace internal
} // namespace lapmesh

#endif
