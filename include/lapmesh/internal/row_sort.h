// Internal: sorting the rows of mesh matrices, a vertex's neighbours by index.
//
// A usual vertex has a handful of neighbours, for which insertion sort is quickest; it is
// quadratic in the row's length, though, and a vertex of very many faces (the apex of a fan,
// a pole, a polygon triangulated from one corner) would make it the slowest step of all.
// Longer rows go to std::stable_sort. Both are stable: equal keys keep their order.
// Rows of up to eight indices, most rows of most meshes, also have a sorting network
// (sort_short_row()), whose compare-exchanges do not branch on the values: insertion sort
// mispredicts a branch at nearly every step where a vertex's neighbours come in no particular
// order (a mesh numbered along a space-filling curve, or shuffled).
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

/// Sorts keys[0 .. 8) in ascending order by a sorting network of 19 compare-exchanges (Batcher's
/// odd-even merge sort of 8), with no branch on the values. The keys are at least 0; pad a
/// shorter row with a key above every other. Not stable, which equal integers do not need.
template <typename Integer>
void sort_short_row(Integer* keys)
{
  static_assert(std::is_integral<Integer>::value && std::is_signed<Integer>::value, "signed integer keys");
  // y - x where y < x, else 0: x and y are at least 0, so y - x does not overflow.
  const auto exchange = [keys](int i, int j) {
    const Integer x = keys[i], y = keys[j];
    const Integer d = static_cast<Integer>((y - x) & ((y - x) >> (8 * sizeof(Integer) - 1)));
    keys[i] = static_cast<Integer>(x + d);
    keys[j] = static_cast<Integer>(y - d);
  };
  exchange(0, 2), exchange(1, 3), exchange(4, 6), exchange(5, 7);
  exchange(0, 4), exchange(1, 5), exchange(2, 6), exchange(3, 7);
  exchange(0, 1), exchange(2, 3), exchange(4, 5), exchange(6, 7);
  exchange(2, 4), exchange(3, 5);
  exchange(1, 4), exchange(3, 6);
  exchange(1, 2), exchange(3, 4), exchange(5, 6);
}

} // namespace internal
} // namespace lapmesh

#endif
