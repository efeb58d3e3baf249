// Internal: connected components by union–find, for the components of a mesh (topology.h) and
// of the graph of a stiffness matrix (spectral_solver.h), which must number them alike.
#ifndef LAPMESH_INTERNAL_UNION_FIND_H
#define LAPMESH_INTERNAL_UNION_FIND_H

#include <algorithm>
#include <cstddef>
#include <numeric>
#include <vector>

namespace lapmesh {
namespace internal {

/// Disjoint sets of 0 .. n - 1 whose root is always the smallest element of its set (a union
/// hangs the larger root under the smaller), with path halving. So each set's smallest element
/// is met before the rest of it, and labels() numbers the sets in one pass.
template <typename Int>
class Smallest_root_sets
{
public:
  explicit Smallest_root_sets(Int n) : m_parent(static_cast<std::size_t>(n))
  {
    std::iota(m_parent.begin(), m_parent.end(), Int(0));
  }

  Int find(Int v)
  {
    while(parent(v) != v) v = parent(v) = parent(parent(v));
    return v;
  }

  void join(Int a, Int b)
  {
    a = find(a);
    b = find(b);
    if(a != b) parent(std::max(a, b)) = std::min(a, b);
  }

  /// The set of each element, numbered from 0 in the order of the sets' smallest elements;
  /// `count` receives the number of sets.
  std::vector<Int> labels(Int& count)
  {
    std::vector<Int> label(m_parent.size());
    count = 0;
    for(Int v = 0; v < Int(m_parent.size()); ++v) {
      const Int r = find(v);
      label[std::size_t(v)] = r == v ? count++ : label[std::size_t(r)];
    }
    return label;
  }

private:
  Int& parent(Int v) { return m_parent[std::size_t(v)]; }

  std::vector<Int> m_parent;
};

} // namespace internal
} // namespace lapmesh

#endif
