// lapmesh — the exceptions the library throws.
//
// Every failure on bad input is reported, never turned into NaN or a silent early stop:
//   Mesh_error        the mesh cannot be processed; names the offending vertex or face (in the
//                     vertex/face index order of the input)
//   Numerical_error   a factorisation, solve or eigen-solve failed
//   Io_error          a file cannot be read or written, or its content is malformed
//   Parameter_error   a setting is out of its range or conflicts with another; names the
//                     setting, so that each front end can point at its own spelling of it
// Parameter_error is a std::invalid_argument, as every other rejected argument.
#ifndef LAPMESH_ERRORS_H
#define LAPMESH_ERRORS_H

#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

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

/// A file cannot be read or written, or its content is malformed. what() does not repeat
/// the file name: callers prefix it ("cow.off: line 12: ...").
class Io_error : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// A setting is invalid: out of range, or in conflict with another setting or the mesh.
/// parameter() is the setting's name in the library (the named parameter or the settings
/// field, e.g. "fix_boundary"); what() does not spell any front end's option. When setting
/// parameter() to suggested_value() resolves a conflict, the error says so.
class Parameter_error : public std::invalid_argument
{
public:
  /// A problem `what` with the setting `parameter`; `suggested_value` resolves it, if given.
  Parameter_error(std::string parameter, const std::string& what, std::string suggested_value = {})
    : std::invalid_argument(what), m_parameter(std::move(parameter)), m_suggested_value(std::move(suggested_value))
  {}
  /// The name of the setting at fault (or to change).
  const std::string& parameter() const { return m_parameter; }
  /// A value of parameter() that resolves the problem, or "" if the message is about its range.
  const std::string& suggested_value() const { return m_suggested_value; }

private:
  std::string m_parameter, m_suggested_value;
};

/// A number as lapmesh's messages print it ("%g"), for front ends whose messages sit beside the
/// library's: std::to_string's fixed six decimals print a tolerance of 1e-10 or a vertex area
/// of -1e-9 as 0.000000.
inline std::string message_number(double x)
{
  char text[32];
  std::snprintf(text, sizeof text, "%g", x);
  return text;
}

} // namespace lapmesh

#endif
