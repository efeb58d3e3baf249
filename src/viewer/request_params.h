// The request parameters of the viewer's API: the members of a JSON body (POST) or the query
// parameters (GET), read with type and range checks, and the HTTP errors that refuse a request.
#ifndef LAPMESH_VIEWER_REQUEST_PARAMS_H
#define LAPMESH_VIEWER_REQUEST_PARAMS_H

#include <lapmesh/types.h>

#include <nlohmann/json.hpp>

#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace httplib {
struct Request;
}

namespace lapmesh_viewer {

/// A request the server refuses: HTTP status and a one-line message.
struct Http_error : std::runtime_error
{
  Http_error(int s, const std::string& what) : std::runtime_error(what), status(s) {}
  int status;
};

/// Reads the members of a JSON object (a POST body) or the query parameters of a GET, with
/// type and range checks; unknown names are an error (typos must not pass silently).
class Params
{
public:
  using json = nlohmann::json;

  static Params from_body(const std::string& body);
  static Params from_query(const httplib::Request& req);

  /// `fallback` when the key is absent; otherwise one of `allowed`, which the error lists.
  std::string choice(const std::string& key, const std::string& fallback, const std::vector<std::string>& allowed);
  /// An enumerator of `Enum`, by the names of its table (lapmesh::names<Enum>()).
  template <typename Enum>
  Enum option(const std::string& key, Enum fallback)
  {
    return *lapmesh::parse<Enum>(choice(key, lapmesh::to_string(fallback), lapmesh::names<Enum>()));
  }
  double number(const std::string& key, double fallback, double lo, double hi);
  long long integer(const std::string& key, std::optional<long long> fallback, long long lo, long long hi);
  bool boolean(const std::string& key, bool fallback);
  bool has(const std::string& key) const { return m_json.contains(key); }
  /// The client's id of an operation (echoed in its answer and progress): "" or up to 64 of
  /// [A-Za-z0-9_-], or a non-negative integer.
  std::string request_id();
  /// The value as sent (nullptr when absent or null), for parameters of several types.
  const json* raw(const std::string& key) { return take(key); }
  /// After reading every parameter: refuses the ones nobody asked for.
  void finish() const;

  static std::string fmt(double x);

private:
  const json* take(const std::string& key);
  json m_json = json::object();
  std::set<std::string> m_used;
  bool m_from_query = false;
};

} // namespace lapmesh_viewer

#endif
