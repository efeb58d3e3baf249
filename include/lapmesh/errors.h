// lapmesh — the exceptions the library throws.
//
// Every failure on bad input is reported, never turned into NaN or a silent early stop:
// Mesh_error names the offending vertex or face (in the vertex/face index order of the
// input), Numerical_error reports a failed factorisation, solve or eigen-solve.
#ifndef LAPMESH_ERRORS_H
#define LAPMESH_ERRORS_H

#include <cstdint>
#include <stdexcept>
#include <string>

namespace lapmesh {

/// The input mesh cannot be processed: invalid, degenerate or non-manifold.
class Mesh_error : public std::runtime_error
{
public:
  /// The kind of mesh element a problem is attached to.
  enum class Element { none, vertex, face, edge };

  /// A problem attached to no particular element.
  explicit Mesh_error(const std::string& what) : std::runtime_error(what) {}
  /// A problem attached to the element `e` of index `index` in the input.
  Mesh_error(const std::string& what, Element e, std::int64_t index)
    : std::runtime_error(what), m_element(e), m_index(index)
  {}

  /// The kind of element the problem is attached to, Element::none if none.
  Element element() const { return m_element; }
  /// Its index (vertex or face index of the input), -1 if none.
  std::int64_t index() const { return m_index; }

private:
  Element m_element = Element::none;
  std::int64_t m_index = -1;
};

/// A numerical method failed (factorisation, linear solve, eigensolver not converged).
class Numerical_error : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

} // namespace lapmesh

#endif
