// Internal: the connected components of a pencil (S, M) that are copies of one another, the
// parts of an assembly placed several times. Every eigenvalue of a part is then an eigenvalue
// of the whole once per copy, and a Krylov run, which finds a block's width of copies of a value
// at a time, misses copies and fails its inertia check when they are many. The eigen-solver
// solves each part once instead (spectral_solver.h, eigenpairs_of_copies()).
#ifndef LAPMESH_INTERNAL_COMPONENT_COPIES_H
#define LAPMESH_INTERNAL_COMPONENT_COPIES_H

#include <lapmesh/internal/union_find.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cmath>
#include <cstddef>
#include <map>
#include <optional>
#include <utility>
#include <vector>

namespace lapmesh {
namespace internal {

/// The components of the graph of S's non-zero off-diagonal entries (its rows in ascending
/// order), grouped into classes of copies: components of equal size whose rows, taken in
/// ascending order, hold the same pattern and values of S and M to a relative round-off
/// (`tolerance`, against the diagonal of S, and against M). A class's first component stands
/// for it.
struct Component_copies
{
  std::vector<std::vector<int>> rows;     ///< per component, its rows in ascending order
  std::vector<std::vector<int>> classes;  ///< classes of two or more components, the first stands for the class
  std::vector<int> singles;               ///< the components with no copy
  std::vector<int> position;              ///< per row, its place in its component's rows
};

namespace copies_detail {

inline long long column_entries(const Eigen::SparseMatrix<double>& S, int j)
{
  long long count = 0;
  for(Eigen::SparseMatrix<double>::InnerIterator it(S, j); it; ++it) ++count;
  return count;
}

inline bool same_component(const Eigen::SparseMatrix<double>& S, const Eigen::VectorXd& mass,
                           const Eigen::VectorXd& diagonal, const std::vector<int>& a, const std::vector<int>& b,
                           const std::vector<int>& position, double tolerance)
{
  using Iterator = Eigen::SparseMatrix<double>::InnerIterator;
  for(std::size_t i = 0; i < a.size(); ++i) {
    const int ra = a[i], rb = b[i];
    if(!(std::abs(mass[ra] - mass[rb]) <= tolerance * mass[ra])) return false;
    const double scale = tolerance * std::abs(diagonal[ra]);
    Iterator ia(S, ra), ib(S, rb);
    for(; ia && ib; ++ia, ++ib)
      if(position[std::size_t(ia.index())] != position[std::size_t(ib.index())] ||
         !(std::abs(ia.value() - ib.value()) <= scale))
        return false;
    if(ia || ib) return false;
  }
  return true;
}

} // namespace copies_detail

/// Whether every row of S sums to zero to round-off: a Laplacian, whose null space holds the
/// constants on each component.
inline bool rows_sum_to_zero(const Eigen::SparseMatrix<double>& S)
{
  for(Eigen::Index j = 0; j < S.outerSize(); ++j) {
    double sum = 0, magnitude = 0;  // S is symmetric: column j is row j
    for(Eigen::SparseMatrix<double>::InnerIterator it(S, j); it; ++it) {
      sum += it.value();
      magnitude += std::abs(it.value());
    }
    if(!(std::abs(sum) <= 1e-10 * magnitude)) return false;
  }
  return true;
}

/// The classes of copies among the components of (S, M); none when no component has a copy
/// (a connected mesh among them). S is symmetric, column-major; the test is O(nnz(S)) per pair
/// of components compared, which only components of equal size and number of entries are.
inline std::optional<Component_copies> find_component_copies(const Eigen::SparseMatrix<double>& S,
                                                             const Eigen::VectorXd& mass, double tolerance = 1e-10)
{
  const int n = int(S.rows());
  Smallest_root_sets<int> sets(n);
  for(int j = 0; j < n; ++j)
    for(Eigen::SparseMatrix<double>::InnerIterator it(S, j); it; ++it)
      if(it.value() != 0 && it.index() != j) sets.join(int(it.index()), j);
  int count = 0;
  const std::vector<int> label = sets.labels(count);
  if(count < 2) return std::nullopt;

  Component_copies out;
  out.rows.resize(std::size_t(count));
  out.position.resize(std::size_t(n));
  std::vector<long long> entries(std::size_t(count), 0);
  for(int r = 0; r < n; ++r) {
    std::vector<int>& rows = out.rows[std::size_t(label[std::size_t(r)])];
    out.position[std::size_t(r)] = int(rows.size());
    rows.push_back(r);
    entries[std::size_t(label[std::size_t(r)])] += copies_detail::column_entries(S, r);
  }
  const Eigen::VectorXd diagonal = S.diagonal();
  // Candidates share a size and a number of entries; each is compared with the classes found so
  // far among them.
  std::map<std::pair<std::size_t, long long>, std::vector<int>> classes_of_shape;  // -> indices into `found`
  std::vector<std::vector<int>> found;
  for(int c = 0; c < count; ++c) {
    std::vector<int>& candidates = classes_of_shape[{out.rows[std::size_t(c)].size(), entries[std::size_t(c)]}];
    bool placed = false;
    for(const int f : candidates) {
      const int first = found[std::size_t(f)].front();
      if(copies_detail::same_component(S, mass, diagonal, out.rows[std::size_t(first)], out.rows[std::size_t(c)],
                                       out.position, tolerance)) {
        found[std::size_t(f)].push_back(c);
        placed = true;
        break;
      }
    }
    if(!placed) {
      candidates.push_back(int(found.size()));
      found.push_back({c});
    }
  }
  for(std::vector<int>& f : found) {
    if(f.size() > 1)
      out.classes.push_back(std::move(f));
    else
      out.singles.push_back(f.front());
  }
  if(out.classes.empty()) return std::nullopt;
  return out;
}

/// The pencil restricted to `rows` (ascending, closed under S's entries: whole components), with
/// `position[r]` the place of row r in `rows`.
inline std::pair<Eigen::SparseMatrix<double>, Eigen::VectorXd>
restricted_pencil(const Eigen::SparseMatrix<double>& S, const Eigen::VectorXd& mass, const std::vector<int>& rows,
                  const std::vector<int>& position)
{
  const Eigen::Index m = Eigen::Index(rows.size());
  long long entries = 0;
  for(const int r : rows) entries += copies_detail::column_entries(S, r);
  Eigen::SparseMatrix<double> sub(m, m);
  sub.resizeNonZeros(Eigen::Index(entries));
  Eigen::VectorXd sub_mass(m);
  Eigen::Index at = 0;
  for(Eigen::Index j = 0; j < m; ++j) {
    const int r = rows[std::size_t(j)];
    sub.outerIndexPtr()[j] = int(at);
    sub_mass[j] = mass[r];
    for(Eigen::SparseMatrix<double>::InnerIterator it(S, r); it; ++it, ++at) {
      sub.innerIndexPtr()[at] = position[std::size_t(it.index())];  // ascending: `rows` is
      sub.valuePtr()[at] = it.value();
    }
  }
  sub.outerIndexPtr()[m] = int(at);
  return {std::move(sub), std::move(sub_mass)};
}

} // namespace internal
} // namespace lapmesh

#endif
