// Reading request parameters (request_params.h).
#include "request_params.h"

#include <httplib.h>

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace lapmesh_viewer {

Params Params::from_body(const std::string& body)
{
  Params p;
  if(body.find_first_not_of(" \t\r\n") == std::string::npos) return p;
  try {
    p.m_json = json::parse(body);
  } catch(const json::exception&) {
    throw Http_error(400, "the request body is not valid JSON");
  }
  if(!p.m_json.is_object()) throw Http_error(400, "the request body must be a JSON object");
  return p;
}

Params Params::from_query(const httplib::Request& req)
{
  Params p;
  for(const auto& [key, value] : req.params) {
    if(p.m_json.contains(key)) throw Http_error(400, "query parameter '" + key + "' given twice");
    p.m_json[key] = value;
    p.m_from_query = true;
  }
  return p;
}

std::string Params::choice(const std::string& key, const std::string& fallback, const std::vector<std::string>& allowed)
{
  const json* v = take(key);
  if(!v) return fallback;
  if(!v->is_string()) throw Http_error(400, "'" + key + "' must be a string");
  const std::string s = v->get<std::string>();
  std::string list;
  for(const std::string& a : allowed) {
    if(s == a) return s;
    list += (list.empty() ? "" : ", ") + a;
  }
  throw Http_error(400, "'" + key + "' must be one of " + list + " (got '" + s.substr(0, 40) + "')");
}

double Params::number(const std::string& key, double fallback, double lo, double hi)
{
  const json* v = take(key);
  if(!v) return fallback;
  double x = 0;
  if(v->is_number()) {
    x = v->get<double>();
  } else if(m_from_query && v->is_string()) {
    const std::string s = v->get<std::string>();
    char* end = nullptr;
    x = std::strtod(s.c_str(), &end);
    if(s.empty() || *end != '\0') throw Http_error(400, "'" + key + "' must be a number");
  } else {
    throw Http_error(400, "'" + key + "' must be a number");
  }
  if(!std::isfinite(x) || x < lo || x > hi)
    throw Http_error(400, "'" + key + "' must be in [" + fmt(lo) + ", " + fmt(hi) + "] (got " + fmt(x) + ")");
  return x;
}

long long Params::integer(const std::string& key, std::optional<long long> fallback, long long lo, long long hi)
{
  const json* v = take(key);
  if(!v) {
    if(!fallback) throw Http_error(400, "'" + key + "' is required");
    return *fallback;
  }
  long long x = 0;
  if(v->is_number_integer()) {
    x = v->get<long long>();
  } else if(v->is_number_float() && std::isfinite(v->get<double>()) && std::floor(v->get<double>()) == v->get<double>() &&
            std::abs(v->get<double>()) < 9e15) {
    x = (long long)v->get<double>();
  } else if(m_from_query && v->is_string()) {
    const std::string s = v->get<std::string>();
    std::size_t used = 0;
    try {
      x = std::stoll(s, &used);
    } catch(const std::exception&) {
      used = 0;
    }
    if(used == 0 || used != s.size()) throw Http_error(400, "'" + key + "' must be an integer");
  } else {
    throw Http_error(400, "'" + key + "' must be an integer (got " + v->dump().substr(0, 40) + ")");
  }
  if(x < lo || x > hi)
    throw Http_error(400, "'" + key + "' must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                            "] (got " + std::to_string(x) + ")");
  return x;
}

bool Params::boolean(const std::string& key, bool fallback)
{
  const json* v = take(key);
  if(!v) return fallback;
  if(v->is_boolean()) return v->get<bool>();
  if(m_from_query && v->is_string() && (*v == "true" || *v == "false")) return *v == "true";
  throw Http_error(400, "'" + key + "' must be true or false");
}

std::string Params::request_id()
{
  const json* v = take("request_id");
  if(!v) return "";
  if(v->is_number_unsigned()) return std::to_string(v->get<unsigned long long>());
  if(v->is_string()) {
    const std::string s = v->get<std::string>();
    if(s.size() <= 64 && s.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-") ==
                           std::string::npos)
      return s;
  }
  throw Http_error(400, "'request_id' must be up to 64 of A-Z a-z 0-9 _ - or a non-negative integer");
}

void Params::finish() const
{
  for(auto it = m_json.begin(); it != m_json.end(); ++it)
    if(!m_used.count(it.key())) throw Http_error(400, "unknown parameter '" + it.key().substr(0, 40) + "'");
}

std::string Params::fmt(double x)
{
  std::ostringstream os;
  os << x;
  return os.str();
}

const Params::json* Params::take(const std::string& key)
{
  m_used.insert(key);
  auto it = m_json.find(key);
  if(it == m_json.end() || it->is_null()) return nullptr;
  return &*it;
}

} // namespace lapmesh_viewer
