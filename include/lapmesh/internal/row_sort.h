// Internal: sorting the rows of mesh matrices, a vertex's neighbours by index.
//
// A usual vertex has a handful of neighbours, for which insertion sort is quickest; it is
// quadratic in the row's length, though, and a vertex of very many faces (the apex of a fan,
// a pole, a polygon triangulated from one corner) would make it the slowest step of all.
// Longer rows go to std::stable_sort. Both are stable: equal keys keep their order.
#ifndef LAPMESH_INTERNAL_ROW_SORT_H
#define LAPMESH_INTERNAL_ROW_SORT_H

#include <algorithm>
#include <cstddef>
#include <numeric>
#include <type_traits>
#include <vector>

namespace lapmesh {
namespace internal {

/// Up to how many entries sort_row() sorts by insertion.
constexpr std::size_t max_insertion_sorted_row = 64;

/// No values carried along by sort_row().
struct No_row_values
{};

/// Sorts keys[0 .. count) in ascending order, stably, and values[0 .. count) (unless
/// No_row_values) along with them.
template <typename Key, typename Value = No_row_values>
void sort_row(Key* keys, std::size_t count, Value* values = nullptr)
{
  constexpr bool carried = !std::is_same<Value, No_row_values>::value;
  if(count <= max_insertion_sorted_row) {
    for(std::size_t a = 1; a < count; ++a) {
      const Key key = keys[a];
      std::size_t b = a;
      if constexpr(carried) {
        const Value value = values[a];
        for(; b > 0 && keys[b - 1] > key; --b) {
          keys[b] = keys[b - 1];
          values[b] = values[b - 1];
        }
        values[b] = value;
      } else {
        for(; b > 0 && keys[b - 1] > key; --b) keys[b] = keys[b - 1];
      }
      keys[b] = key;
    }
    return;
  }
  if constexpr(carried) {
    std::vector<std::size_t> order(count);
    std::iota(order.begin(), order.end(), std::size_t(0));
    std::stable_sort(order.begin(), order.end(), [keys](std::size_t a, std::size_t b) { return keys[a] < keys[b]; });
    const std::vector<Key> key_copy(keys, keys + count);
    const std::vector<Value> value_copy(values, values + count);
    for(std::size_t k = 0; k < count; ++k) {
      keys[k] = key_copy[order[k]];
      values[k] = value_copy[order[k]];
    }
  } else {
    std::stable_sort(keys, keys + count);
  }
}

} // namespace internal
} // namespace lapmesh

#endif
