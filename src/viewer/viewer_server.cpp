// The HTTP server of `lapmesh view` (API reference: doc/viewer.md).
//
// Every computation is a call into the public lapmesh headers; this file only validates
// requests, keeps one state per mesh (guarded by its own mutex: a second operation on a
// busy mesh gets 409 instead of waiting) and encodes the answers. Large arrays travel as one
// binary "frame": uint32 little-endian header length, a JSON header, zero padding to a
// multiple of 8, then the buffers at the offsets the header gives.
#include "viewer_server.h"

#include <lapmesh/colormap.h>
#include <lapmesh/curvature.h>
#include <lapmesh/errors.h>
#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/noise.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <list>
#include <map>
#include <mutex>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

namespace lapmesh_viewer {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;
namespace LP = lapmesh::parameters;

/// A request the server refuses: HTTP status and a one-line message.
struct Http_error : std::runtime_error
{
  Http_error(int s, const std::string& what) : std::runtime_error(what), status(s) {}
  int status;
};

/// Thrown from a progress callback when the client asked to cancel.
struct Cancelled
{};

double ms_since(Clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// ---- request parameters -------------------------------------------------------------

/// Reads the members of a JSON object (a POST body) or the query parameters of a GET, with
/// type and range checks; unknown names are an error (typos must not pass silently).
class Params
{
public:
  static Params from_body(const std::string& body)
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
  static Params from_query(const httplib::Request& req)
  {
    Params p;
    for(const auto& [key, value] : req.params) {
      if(p.m_json.contains(key)) throw Http_error(400, "query parameter '" + key + "' given twice");
      p.m_json[key] = value;
      p.m_from_query = true;
    }
    return p;
  }

  std::string choice(const std::string& key, const std::string& fallback, std::initializer_list<const char*> allowed)
  {
    return choice(key, fallback, std::vector<std::string>(allowed.begin(), allowed.end()));
  }
  /// `fallback` when the key is absent; otherwise one of `allowed`, which the error lists.
  std::string choice(const std::string& key, const std::string& fallback, const std::vector<std::string>& allowed)
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
  double number(const std::string& key, double fallback, double lo, double hi)
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
  long long integer(const std::string& key, std::optional<long long> fallback, long long lo, long long hi)
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
  bool boolean(const std::string& key, bool fallback)
  {
    const json* v = take(key);
    if(!v) return fallback;
    if(v->is_boolean()) return v->get<bool>();
    if(m_from_query && v->is_string() && (*v == "true" || *v == "false")) return *v == "true";
    throw Http_error(400, "'" + key + "' must be true or false");
  }
  bool has(const std::string& key) const { return m_json.contains(key); }
  /// The client's id of an operation (echoed in its answer and progress): "" or up to 64 of
  /// [A-Za-z0-9_-], or a non-negative integer.
  std::string request_id()
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
  const json* raw(const std::string& key) { return take(key); }
  /// After reading every parameter: refuses the ones nobody asked for.
  void finish() const
  {
    for(auto it = m_json.begin(); it != m_json.end(); ++it)
      if(!m_used.count(it.key())) throw Http_error(400, "unknown parameter '" + it.key().substr(0, 40) + "'");
  }

  static std::string fmt(double x)
  {
    std::ostringstream os;
    os << x;
    return os.str();
  }

private:
  const json* take(const std::string& key)
  {
    m_used.insert(key);
    auto it = m_json.find(key);
    if(it == m_json.end() || it->is_null()) return nullptr;
    return &*it;
  }
  json m_json = json::object();
  std::set<std::string> m_used;
  bool m_from_query = false;
};

// ---- binary frames -------------------------------------------------------------------

class Frame
{
public:
  template <typename T>
  void add(const std::string& name, const char* type, const T* data, std::size_t count, int components = 1)
  {
    const std::size_t bytes = sizeof(T) * count;
    m_header["buffers"][name] = {{"type", type}, {"offset", m_data.size()}, {"count", count},
                                 {"components", components}};
    m_data.append(reinterpret_cast<const char*>(data), bytes);
    m_data.append((8 - m_data.size() % 8) % 8, '\0');
  }
  json& header() { return m_header; }
  std::string str() const
  {
    std::string h = m_header.dump();
    h.append((8 - (4 + h.size()) % 8) % 8, ' ');
    const std::uint32_t len = std::uint32_t(h.size());
    std::string out(4, '\0');
    for(int i = 0; i < 4; ++i) out[std::size_t(i)] = char((len >> (8 * i)) & 0xff);  // little-endian
    out += h;
    out += m_data;
    return out;
  }

private:
  json m_header = {{"buffers", json::object()}};
  std::string m_data;
};

// ---- transport ---------------------------------------------------------------------------
//
// httplib parses requests and routes them, but its own accept loop cannot stand up to slow
// or hostile clients (a fixed pool of 8 threads held by half-sent requests, header lines
// without a total limit, chunked bodies without a size limit, SO_REUSEPORT on the listening
// socket). So the server accepts connections itself, gives each its own thread (bounded in
// number, overall and per client address) and hands httplib a stream that enforces a
// deadline and a byte budget on every request.

/// httplib's request parser and router, driven one request at a time.
class Http_router : public httplib::Server
{
public:
  using httplib::Server::process_request;
};

struct Transport_limits
{
  int request_ms, io_ms, keep_alive_ms;
  std::size_t max_head_bytes, max_body_wire_bytes;
};

/// One accepted connection; its fd stays open until the entry leaves the connection table,
/// so that another thread may shut it down (eviction, stop) without hitting a reused fd.
struct Connection
{
  enum class Phase { waiting, reading, handling };
  enum class Limit { none, head, body, time };
  int fd = -1;
  std::string address;
  std::atomic<Phase> phase{Phase::waiting};
  std::atomic<long long> phase_since_ns{0};
  Limit limit = Limit::none;    // what stopped the current request, if anything
  bool must_close = false;      // the request's body was not read: the next bytes are not a request
  std::atomic<bool> finished{false};
  bool evicted = false;  // shut down to make room (connections_mutex)
  std::thread thread;

  void set_phase(Phase p)
  {
    phase = p;
    phase_since_ns = Clock::now().time_since_epoch().count();
  }
};

thread_local Connection* current_connection = nullptr;

/// The stream httplib reads requests from and writes answers to. Each request must arrive
/// within request_ms of its first byte, with a head of at most max_head_bytes and a body
/// (as sent, chunk framing included) of at most max_body_wire_bytes; every wait for the
/// socket is bounded by io_ms.
class Limited_stream final : public httplib::Stream
{
public:
  Limited_stream(Connection& c, const Transport_limits& l) : m_c(c), m_l(l) {}

  /// Before each request: waits up to keep_alive_ms for its first byte; false when the
  /// client closed the connection or stayed silent.
  bool begin_request()
  {
    m_c.limit = Connection::Limit::none;
    m_head_done = false;
    m_head_bytes = m_body_bytes = 0;
    m_tail = 0;
    m_c.set_phase(Connection::Phase::waiting);
    if(m_pos == m_end && !fill(Clock::now() + std::chrono::milliseconds(m_l.keep_alive_ms))) return false;
    m_c.set_phase(Connection::Phase::reading);
    m_deadline = Clock::now() + std::chrono::milliseconds(m_l.request_ms);
    return true;
  }

  bool is_readable() const override { return m_pos < m_end || wait(POLLIN, m_l.io_ms); }
  bool is_writable() const override { return wait(POLLOUT, m_l.io_ms); }

  ssize_t read(char* ptr, std::size_t size) override
  {
    if(m_c.limit != Connection::Limit::none) return -1;
    if(m_pos == m_end && !fill(m_deadline)) {
      m_c.must_close = true;  // a request cut short: what follows is not a request
      return m_eof ? 0 : -1;
    }
    std::size_t n = std::min(size, m_end - m_pos);
    // Count what httplib consumes: the head up to its blank line, then the body.
    for(std::size_t i = 0; i < n && !m_head_done; ++i) {
      m_tail = (m_tail << 8) | std::uint8_t(m_buf[m_pos + i]);
      if(++m_head_bytes > m_l.max_head_bytes) return stop(Connection::Limit::head);
      if((m_tail & 0xffffffffu) == 0x0d0a0d0au) {
        m_head_done = true;
        n = i + 1;  // hand over the head alone; the body is counted from the next read
      }
    }
    std::memcpy(ptr, m_buf + m_pos, n);
    m_pos += n;
    return ssize_t(n);
  }

  ssize_t write(const char* ptr, std::size_t size) override
  {
    if(!wait(POLLOUT, m_l.io_ms)) return -1;
    const ssize_t n = ::send(m_c.fd, ptr, size, MSG_NOSIGNAL);
    return n < 0 ? -1 : n;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override { address_of(true, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { address_of(false, ip, port); }
  int socket() const override { return m_c.fd; }

private:
  ssize_t stop(Connection::Limit why)
  {
    m_c.limit = why;
    m_c.must_close = true;
    return -1;
  }

  bool wait(short events, int ms) const
  {
    pollfd p{m_c.fd, events, 0};
    int r;
    do r = ::poll(&p, 1, ms);
    while(r < 0 && errno == EINTR);
    return r > 0;
  }

  /// Refills the buffer, waiting until `deadline` at most (in steps of io_ms).
  bool fill(Clock::time_point deadline)
  {
    m_pos = m_end = 0;
    for(;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if(left <= 0) {
        if(m_c.phase != Connection::Phase::waiting) stop(Connection::Limit::time);
        return false;
      }
      if(!wait(POLLIN, int(std::min<long long>(left, m_l.io_ms)))) {
        if(left <= m_l.io_ms) continue;  // the deadline check above ends it
        if(m_c.phase != Connection::Phase::waiting) stop(Connection::Limit::time);
        return false;
      }
      const ssize_t n = ::recv(m_c.fd, m_buf, sizeof m_buf, 0);
      if(n > 0) {
        m_end = std::size_t(n);
        if(m_head_done) {
          m_body_bytes += m_end;
          if(m_body_bytes > m_l.max_body_wire_bytes) {
            m_end = 0;
            stop(Connection::Limit::body);
            return false;
          }
        }
        return true;
      }
      if(n == 0) m_eof = true;
      if(n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
      return false;
    }
  }

  void address_of(bool peer, std::string& ip, int& port) const
  {
    sockaddr_storage a{};
    socklen_t len = sizeof a;
    ip.clear();
    port = 0;
    if((peer ? ::getpeername(m_c.fd, (sockaddr*)&a, &len) : ::getsockname(m_c.fd, (sockaddr*)&a, &len)) != 0) return;
    char host[NI_MAXHOST], serv[NI_MAXSERV];
    if(::getnameinfo((sockaddr*)&a, len, host, sizeof host, serv, sizeof serv, NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
      ip = host;
      port = std::atoi(serv);
    }
  }

  Connection& m_c;
  const Transport_limits& m_l;
  char m_buf[4096];
  std::size_t m_pos = 0, m_end = 0;
  bool m_eof = false, m_head_done = false;
  std::size_t m_head_bytes = 0, m_body_bytes = 0;
  std::uint64_t m_tail = 0;
  Clock::time_point m_deadline;
};

// ---- per-mesh state --------------------------------------------------------------------

/// Many readers or one writer, taken without waiting: reads never exclude each other, and a
/// mesh busy with an operation answers 409 instead of queueing requests behind it.
class Busy_lock
{
public:
  bool try_read()
  {
    std::lock_guard<std::mutex> g(m_mutex);
    if(m_writer) return false;
    ++m_readers;
    return true;
  }
  void end_read()
  {
    std::lock_guard<std::mutex> g(m_mutex);
    --m_readers;
  }
  bool try_write()
  {
    std::lock_guard<std::mutex> g(m_mutex);
    if(m_writer || m_readers > 0) return false;
    m_writer = true;
    return true;
  }
  void end_write()
  {
    std::lock_guard<std::mutex> g(m_mutex);
    m_writer = false;
  }

private:
  std::mutex m_mutex;
  int m_readers = 0;
  bool m_writer = false;
};

/// Holds a Busy_lock taken by try_read() (write = false) or try_write() (write = true).
class Busy_guard
{
public:
  Busy_guard(Busy_lock& l, bool write) : m_lock(&l), m_write(write) {}
  Busy_guard(Busy_guard&& o) noexcept : m_lock(std::exchange(o.m_lock, nullptr)), m_write(o.m_write) {}
  Busy_guard(const Busy_guard&) = delete;
  Busy_guard& operator=(const Busy_guard&) = delete;
  ~Busy_guard()
  {
    if(m_lock) m_write ? m_lock->end_write() : m_lock->end_read();
  }

private:
  Busy_lock* m_lock;
  bool m_write;
};

struct Mesh_state
{
  explicit Mesh_state(Mesh_source s) : source(std::move(s)) {}
  const Mesh_source source;

  std::mutex load_mutex;       // the first load (blocking: it happens once)
  std::atomic<bool> loaded{false};
  Busy_lock lock;              // guards everything up to the progress block once loaded
  Mesh original, current;
  std::vector<std::array<std::size_t, 3>> triangles;
  long long version = 0;       // bumped at every change of the geometry (and by reset)
  long long geometry = 0;      // which geometry `current` is: 0 as loaded, else unique to one change
  std::map<std::string, std::vector<double>> scalars;
  json scalar_info = json::object();  // what produced the scalars

  // Progress of the running operation: read without the lock.
  std::atomic<bool> running{false}, cancel{false};
  std::atomic<long long> done{0}, total{0};
  std::atomic<long long> started_ns{0};
  std::mutex progress_mutex;  // guards operation, stage, request_id
  std::string operation, stage, request_id;

  void set_stage(const std::string& s)
  {
    std::lock_guard<std::mutex> g(progress_mutex);
    stage = s;
  }
};

/// Marks an operation as running for its lifetime (progress, cancel).
class Running
{
public:
  Running(Mesh_state& s, const std::string& op, const std::string& request_id) : m_s(s)
  {
    {
      std::lock_guard<std::mutex> g(s.progress_mutex);
      s.operation = op;
      s.stage = "";
      s.request_id = request_id;
    }
    s.done = 0;
    s.total = 0;
    s.cancel = false;
    s.started_ns = Clock::now().time_since_epoch().count();
    s.running = true;
  }
  ~Running() { m_s.running = false; }
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;

private:
  Mesh_state& m_s;
};

/// Eigenbases by (mesh, geometry, Laplacian, vertex area), least recently used first out,
/// within a byte budget. A basis of m pairs serves every k <= m on the geometry it was
/// computed from.
class Basis_cache
{
public:
  explicit Basis_cache(std::size_t budget) : m_budget(budget) {}

  std::shared_ptr<const lapmesh::Spectral_basis> find(const std::string& mesh, long long geometry, lapmesh::Laplacian L,
                                                      lapmesh::Vertex_area A, Eigen::Index k)
  {
    std::lock_guard<std::mutex> g(m_mutex);
    for(auto it = m_lru.begin(); it != m_lru.end(); ++it) {
      if(it->mesh == mesh && it->geometry == geometry && it->L == L && it->A == A && it->basis->size() >= k) {
        m_lru.splice(m_lru.begin(), m_lru, it);
        return m_lru.front().basis;
      }
    }
    return nullptr;
  }

  void insert(const std::string& mesh, long long geometry, std::shared_ptr<const lapmesh::Spectral_basis> basis)
  {
    const std::size_t bytes = bytes_of(*basis);
    std::lock_guard<std::mutex> g(m_mutex);
    m_lru.remove_if([&](const Entry& e) {
      const bool same = e.mesh == mesh && e.geometry == geometry && e.L == basis->laplacian() && e.A == basis->vertex_area();
      if(same) m_bytes -= e.bytes;
      return same;
    });
    if(bytes > m_budget) return;  // used for this request only
    while(!m_lru.empty() && m_bytes + bytes > m_budget) {
      m_bytes -= m_lru.back().bytes;
      m_lru.pop_back();
    }
    m_lru.push_front({mesh, geometry, basis->laplacian(), basis->vertex_area(), basis, bytes});
    m_bytes += bytes;
  }

  /// Drops the bases of `mesh` on geometries other than `keep_a` and `keep_b`: those
  /// geometries cannot come back.
  void forget(const std::string& mesh, long long keep_a, long long keep_b)
  {
    std::lock_guard<std::mutex> g(m_mutex);
    m_lru.remove_if([&](const Entry& e) {
      const bool gone = e.mesh == mesh && e.geometry != keep_a && e.geometry != keep_b;
      if(gone) m_bytes -= e.bytes;
      return gone;
    });
  }

  json stats()
  {
    std::lock_guard<std::mutex> g(m_mutex);
    return {{"bytes", m_bytes}, {"budget_bytes", m_budget}, {"entries", m_lru.size()}};
  }

  static std::size_t bytes_of(const lapmesh::Spectral_basis& b)
  {
    const std::size_t n = std::size_t(b.num_vertices()), m = std::size_t(b.size());
    return sizeof(double) * (n * m + m + n);  // eigenvectors, eigenvalues, mass
  }

private:
  struct Entry
  {
    std::string mesh;
    long long geometry;
    lapmesh::Laplacian L;
    lapmesh::Vertex_area A;
    std::shared_ptr<const lapmesh::Spectral_basis> basis;
    std::size_t bytes;
  };
  std::mutex m_mutex;
  std::list<Entry> m_lru;  // most recently used first
  std::size_t m_bytes = 0, m_budget;
};

std::string sanitize_id(const std::string& s)
{
  std::string id;
  for(char c : s) id += (std::isalnum((unsigned char)c) || c == '_' || c == '-') ? c : '-';
  if(id.empty()) id = "mesh";
  return id.substr(0, 64);
}

std::vector<double> to_vector(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }

const std::vector<std::string> quantity_names = {"mean", "gaussian", "k1", "k2", "displacement"};

struct Static_file
{
  fs::path path;
  std::string type;
};

std::string content_type_of(const fs::path& p)
{
  const std::string e = p.extension().string();
  if(e == ".html") return "text/html; charset=utf-8";
  if(e == ".js" || e == ".mjs") return "text/javascript; charset=utf-8";
  if(e == ".css") return "text/css; charset=utf-8";
  if(e == ".svg") return "image/svg+xml";
  if(e == ".png") return "image/png";
  if(e == ".json") return "application/json";
  if(e == ".ico") return "image/x-icon";
  return "application/octet-stream";
}

} // namespace

// ---------------------------------------------------------------------------------------

std::vector<Mesh_source> default_mesh_sources(const std::vector<std::string>& paths, const std::string& cgal_cow)
{
  std::vector<Mesh_source> out;
  std::set<std::string> ids;
  auto unique = [&](std::string id) {
    std::string u = id;
    for(int i = 2; ids.count(u); ++i) u = id + "-" + std::to_string(i);
    ids.insert(u);
    return u;
  };
  for(const std::string& p : paths) {
    Mesh_source s;
    s.kind = Mesh_source::Kind::file;
    s.path = p;
    s.id = unique(sanitize_id(fs::path(p).stem().string()));
    s.label = fs::path(p).filename().string();
    out.push_back(s);
  }
  auto builtin = [&](Mesh_source::Kind k, const std::string& id, const std::string& label, const std::string& path = "") {
    Mesh_source s;
    s.kind = k;
    s.id = unique(id);
    s.label = label;
    s.path = path;
    out.push_back(s);
  };
  builtin(Mesh_source::Kind::icosphere, "icosphere", "icosphere (level 4, r = 1)");
  builtin(Mesh_source::Kind::torus, "torus", "torus (96 x 48, R = 1, r = 0.4)");
  builtin(Mesh_source::Kind::bumpy_sphere, "bumpy-sphere", "bumpy sphere (level 5)");
  std::error_code ec;
  if(!cgal_cow.empty() && fs::is_regular_file(cgal_cow, ec))
    builtin(Mesh_source::Kind::file, "cow", "cow.off (CGAL data)", cgal_cow);
  return out;
}

struct Server::Impl
{
  Server_options options;
  std::vector<std::unique_ptr<Mesh_state>> meshes;
  std::map<std::string, Mesh_state*> by_id;
  std::map<std::string, Static_file> files;  // URL path -> file, fixed at start-up
  Basis_cache bases;
  std::atomic<long long> last_geometry{0};  // geometry ids handed out

  // Transport (see "transport" above).
  Http_router http;
  Transport_limits limits;
  int listen_fd = -1;
  std::atomic<bool> stopping{false}, accepting{false};
  std::thread accept_thread;
  std::mutex connections_mutex;
  std::list<std::unique_ptr<Connection>> connections;
  static constexpr int max_requests_per_connection = 1000;

  Impl(std::vector<Mesh_source> sources, Server_options o) : options(std::move(o)), bases(options.cache_bytes)
  {
    limits = {options.request_timeout_ms, options.io_timeout_ms, options.keep_alive_ms, options.max_header_bytes,
              // the body as sent: chunk framing of reasonably sized chunks fits in the margin
              2 * options.max_body_bytes + 4096};
    for(auto& s : sources) {
      if(s.id.empty() || s.id != sanitize_id(s.id) || by_id.count(s.id))
        throw std::invalid_argument("invalid or duplicate mesh id '" + s.id + "'");
      meshes.push_back(std::make_unique<Mesh_state>(std::move(s)));
      by_id[meshes.back()->source.id] = meshes.back().get();
    }
    scan_assets();
    routes();
  }

  void scan_assets()
  {
    std::error_code ec;
    if(options.assets_dir.empty() || !fs::is_directory(options.assets_dir, ec)) return;
    const fs::path root = fs::canonical(options.assets_dir, ec);
    for(auto it = fs::recursive_directory_iterator(root, ec); !ec && it != fs::recursive_directory_iterator();
        it.increment(ec)) {
      if(!it->is_regular_file(ec)) continue;
      const std::string rel = fs::relative(it->path(), root, ec).generic_string();
      if(ec || rel.empty() || rel.find("..") != std::string::npos) continue;
      files["/" + rel] = {it->path(), content_type_of(it->path())};
      if(files.size() > 1000) break;
    }
  }

  // ---- loading ----

  Mesh_state& find(const std::string& id)
  {
    auto it = by_id.find(id);
    if(it == by_id.end()) throw Http_error(404, "unknown mesh id '" + sanitize_id(id) + "' (see GET /api/meshes)");
    return *it->second;
  }

  /// Loads (or generates) the mesh on first use; concurrent first users wait for one load.
  void load(Mesh_state& s)
  {
    if(s.loaded) return;
    std::lock_guard<std::mutex> g(s.load_mutex);
    if(s.loaded) return;
    Mesh mesh;
    const Mesh_source& src = s.source;
    try {
      switch(src.kind) {
        case Mesh_source::Kind::file: lapmesh::io::read_triangle_mesh(src.path, mesh); break;
        case Mesh_source::Kind::icosphere: lapmesh::make_mesh(lapmesh::icosphere(4, 1.0), mesh); break;
        case Mesh_source::Kind::torus: lapmesh::make_mesh(lapmesh::torus(96, 48, 1.0, 0.4), mesh); break;
        case Mesh_source::Kind::bumpy_sphere: lapmesh::make_mesh(lapmesh::bumpy_sphere(5), mesh); break;
      }
    } catch(const std::exception& e) {
      throw Http_error(422, src.label + ": " + e.what());
    }
    if((long long)num_vertices(mesh) > options.max_vertices)
      throw Http_error(422, src.label + ": " + std::to_string(num_vertices(mesh)) + " vertices, more than the limit " +
                              std::to_string(options.max_vertices));
    s.original = mesh;
    s.current = std::move(mesh);
    s.triangles = lapmesh::io::mesh_arrays(s.current).second;
    s.version = 1;
    s.geometry = 0;
    s.loaded = true;
  }

  [[noreturn]] static void busy(Mesh_state& s, const char* what)
  {
    throw Http_error(409, "mesh '" + s.source.id + "' is busy " + what + " (GET .../progress, POST .../cancel)");
  }
  /// For an operation: exclusive, taken without waiting (a busy mesh answers 409).
  Busy_guard write_lock(Mesh_state& s)
  {
    load(s);
    if(!s.lock.try_write()) busy(s, "with another operation or a read in progress");
    return Busy_guard(s.lock, true);
  }
  /// For a read: shared with every other read; 409 only while an operation runs.
  Busy_guard read_lock(Mesh_state& s)
  {
    load(s);
    if(!s.lock.try_read()) busy(s, "with an operation");
    return Busy_guard(s.lock, false);
  }

  lapmesh::Vertex_vectors positions(const Mesh_state& s) const { return lapmesh::io::mesh_arrays(s.current).first; }

  void set_positions(Mesh_state& s, const Eigen::Ref<const Eigen::MatrixXd>& P)
  {
    for(Mesh::Vertex_index v : s.current.vertices()) {
      const Eigen::Index i = Eigen::Index(std::size_t(v));
      s.current.point(v) = Kernel::Point_3(P(i, 0), P(i, 1), P(i, 2));
    }
  }

  /// After a change of the geometry: curvatures are stale, show the displacement from the input.
  void geometry_changed(Mesh_state& s, const std::string& what)
  {
    ++s.version;
    s.geometry = ++last_geometry;
    bases.forget(s.source.id, 0, s.geometry);  // the previous geometry is gone unless it was the loaded one
    const lapmesh::Vertex_vectors P = positions(s), P0 = lapmesh::io::mesh_arrays(s.original).first;
    const Eigen::VectorXd d = (P - P0).rowwise().norm();
    s.scalars.clear();
    s.scalars["displacement"] = to_vector(d);
    s.scalar_info = {{"source", what}};
  }

  static std::function<void(int, int)> smoothing_progress(Mesh_state& s)
  {
    return [&s](int done, int total) {
      s.done = done;
      s.total = total;
      if(s.cancel) throw Cancelled{};
    };
  }

  // ---- operations (s.mutex held) ----

  json op_reset(Mesh_state& s, Params& p)
  {
    p.finish();
    s.current = s.original;
    ++s.version;
    s.geometry = 0;
    bases.forget(s.source.id, 0, 0);
    s.scalars.clear();
    s.scalar_info = json::object();
    return json::object();
  }

  json op_curvature(Mesh_state& s, Params& p)
  {
    const std::string lap = p.choice("laplacian", "cotangent", {"cotangent", "uniform"});
    const std::string area = p.choice("area", "barycentric", {"barycentric", "voronoi", "mixed"});
    p.finish();
    s.set_stage("curvature");
    const lapmesh::Vertex_curvatures c = lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(
      s.current, LP::vertex_area(*lapmesh::parse_vertex_area(area), LP::laplacian(*lapmesh::parse_laplacian(lap))));
    s.scalars.clear();
    s.scalars["mean"] = to_vector(c.mean);
    s.scalars["gaussian"] = to_vector(c.gaussian);
    s.scalars["k1"] = to_vector(c.k1);
    s.scalars["k2"] = to_vector(c.k2);
    s.scalar_info = {{"source", "curvature"}, {"laplacian", lap}, {"area", area}};
    return {{"laplacian", lap}, {"area", area}};
  }

  json op_reconstruct(Mesh_state& s, Params& p)
  {
    const long long n = (long long)num_vertices(s.current);
    const long long kmax = std::min<long long>(n, options.max_k);
    const long long k = p.integer("k", std::nullopt, 1, kmax);
    const std::string lap = p.choice("laplacian", "cotangent", {"cotangent", "uniform"});
    const std::string area = p.choice("area", "barycentric", {"barycentric", "voronoi", "mixed"});
    p.finish();
    const auto L = *lapmesh::parse_laplacian(lap);
    const auto A = *lapmesh::parse_vertex_area(area);
    std::shared_ptr<const lapmesh::Spectral_basis> basis = bases.find(s.source.id, s.geometry, L, A, k);
    const bool cached = basis != nullptr;
    if(!cached) {
      s.set_stage("eigenpairs");
      auto progress = [&s](const lapmesh::Spectral_progress& pr) {
        s.done = pr.operations;
        s.set_stage(pr.stage);
        if(s.cancel) throw Cancelled{};
      };
      basis = std::make_shared<const lapmesh::Spectral_basis>(lapmesh::Spectral_basis::compute<CGAL::Parallel_if_available_tag>(
        s.current, k, LP::spectral_progress(progress, LP::vertex_area(A, LP::laplacian(L)))));
      bases.insert(s.source.id, s.geometry, basis);
    }
    const Eigen::MatrixXd R = basis->reconstruct(positions(s), k);
    const bool split = basis->splits_eigenspace(k);
    json out = {{"k", k}, {"laplacian", lap}, {"area", area}, {"basis_size", basis->size()}, {"basis_cached", cached},
                {"eigenvalue_k_minus_1", basis->eigenvalues()[k - 1]}};
    if(split)
      out["warning"] = "lambda_" + std::to_string(k - 1) + " and lambda_" + std::to_string(k) +
                       " agree to 1e-8 relative: the reconstruction depends on the basis chosen inside that eigenspace";
    set_positions(s, R);
    geometry_changed(s, "reconstruct");
    out["cache"] = bases.stats();
    return out;
  }

  json op_smooth(Mesh_state& s, Params& p)
  {
    const std::string scheme = p.choice("scheme", "implicit", {"explicit", "implicit", "conformal"});
    const json* lambda_json = p.raw("lambda");
    bool lambda_auto = !lambda_json || (lambda_json->is_string() && *lambda_json == "auto");
    double lambda_value = 0;
    if(!lambda_auto) {
      if(!lambda_json->is_number()) throw Http_error(400, "'lambda' must be a positive number or \"auto\"");
      lambda_value = lambda_json->get<double>();
      if(!(lambda_value > 0) || !std::isfinite(lambda_value) || lambda_value > 1e12)
        throw Http_error(400, "'lambda' must be a positive finite time step (got " + lambda_json->dump() + ")");
    }
    std::string unit = p.choice("lambda_unit", "absolute", {"absolute", "edge2", "bound"});
    const long long iterations = p.integer("iterations", 1, 1, options.max_iterations);
    const std::string lap = p.choice("laplacian", "cotangent", {"cotangent", "uniform"});
    const std::string area = p.choice("area", "barycentric", {"barycentric", "voronoi", "mixed"});
    const bool fixed_operator = p.boolean("fixed_operator", false);
    const bool restore_volume = p.boolean("restore_volume", false);
    const bool restore_area = p.boolean("restore_area", false);
    const bool fix_boundary = p.boolean("fix_boundary", true);
    p.finish();

    const auto sch = *lapmesh::parse_smoothing_scheme(scheme);  // p.choice checked the name
    const auto base = LP::fix_boundary(
      fix_boundary, LP::vertex_area(*lapmesh::parse_vertex_area(area), LP::laplacian(*lapmesh::parse_laplacian(lap))));
    s.set_stage("time step");
    // One bound for the explicit scheme, as the CLI computes it: explicit_stability_bound() on the
    // input's free vertices (the smoother's report may hold a cheaper Gershgorin lower bound).
    const bool explicit_scheme = sch == lapmesh::Smoothing_scheme::explicit_euler;
    const double bound = explicit_scheme ? lapmesh::explicit_stability_bound(s.current, base)
                                         : std::numeric_limits<double>::quiet_NaN();
    const auto step_unit = *lapmesh::parse_time_step_unit(unit);
    double lambda = 0;
    if(lambda_auto)
      lambda = explicit_scheme ? lapmesh::automatic_explicit_time_step(bound)
                               : lapmesh::automatic_time_step(s.current, sch, base);
    else
      lambda = explicit_scheme && step_unit == lapmesh::Time_step_unit::stability_bound
                 ? lambda_value * bound
                 : lapmesh::time_step(s.current, lambda_value, step_unit, base);
    s.total = iterations;
    s.set_stage("smoothing");
    Mesh work = s.current;  // a cancelled or failed run leaves the mesh as it was
    const auto np =
      LP::progress_callback(smoothing_progress(s), LP::restore_area(restore_area, LP::restore_volume(
                                                                                 restore_volume, LP::fixed_operator(fixed_operator, base))))
        .number_of_iterations(unsigned(iterations));
    lapmesh::Smoothing_report report;
    switch(sch) {
      case lapmesh::Smoothing_scheme::explicit_euler:
        report = lapmesh::smooth_laplacian_explicit<CGAL::Parallel_if_available_tag>(work, lambda, np);
        break;
      case lapmesh::Smoothing_scheme::implicit_euler:
        report = lapmesh::smooth_laplacian_implicit<CGAL::Parallel_if_available_tag>(work, lambda, np);
        break;
      default: report = lapmesh::smooth_conformal_flow<CGAL::Parallel_if_available_tag>(work, lambda, np);
    }
    s.current = std::move(work);
    json out = {{"scheme", scheme}, {"lambda", lambda}, {"iterations", report.iterations},
                {"free_vertices", report.free_vertices}, {"laplacian", lap}, {"area", area},
                {"fixed_operator", fixed_operator}, {"restore_volume", restore_volume}, {"restore_area", restore_area},
                {"fix_boundary", fix_boundary}};
    if(explicit_scheme) out["stability_bound"] = bound;
    if(explicit_scheme && lambda > bound)
      out["warning"] = "lambda " + Params::fmt(lambda) + " exceeds the explicit stability bound " +
                       Params::fmt(bound) + " (use lambda \"auto\" or lambda_unit \"bound\")";
    geometry_changed(s, "smooth");
    return out;
  }

  json op_noise(Mesh_state& s, Params& p)
  {
    const double level = p.number("level", 0.1, 0.0, 10.0);
    const long long seed = p.integer("seed", 0, 0, 4294967295LL);
    const std::string scale = p.choice("scale", "mean-edge", {"mean-edge", "bbox"});
    const std::string direction = p.choice("direction", "isotropic", {"isotropic", "normal"});
    p.finish();
    s.set_stage("noise");
    const double sigma = lapmesh::add_noise(
      s.current, level,
      LP::noise_direction(direction == "normal" ? lapmesh::Noise_direction::normal : lapmesh::Noise_direction::isotropic,
                          LP::noise_scale(scale == "bbox" ? lapmesh::Noise_scale::bounding_box_diagonal
                                                          : lapmesh::Noise_scale::mean_edge_length,
                                          CGAL::parameters::random_seed(unsigned(seed)))));
    geometry_changed(s, "noise");
    return {{"level", level}, {"seed", seed}, {"scale", scale}, {"direction", direction}, {"sigma", sigma}};
  }

  // ---- reads ----

  json mesh_summary(Mesh_state& s)
  {
    json j = {{"id", s.source.id}, {"label", s.source.label},
              {"kind", s.source.kind == Mesh_source::Kind::file ? "file" : "builtin"}};
    if(s.loaded && s.lock.try_read()) {
      Busy_guard l(s.lock, false);
      j["vertices"] = num_vertices(s.current);
      j["faces"] = num_faces(s.current);
    }
    return j;
  }

  /// The values of a quantity and the colour range/map the query asks for (s.mutex held).
  struct Coloring
  {
    std::string quantity, colormap, mode;
    const std::vector<double>* values = nullptr;
    lapmesh::Value_range range;
    double clip = 0;
  };

  Coloring coloring(Mesh_state& s, Params& p, bool required)
  {
    Coloring c;
    const std::string fallback = s.scalars.count("mean") ? "mean" : s.scalars.empty() ? "" : s.scalars.begin()->first;
    // The fallback may be empty (no values yet); a given quantity must be a named one.
    c.quantity = p.choice("quantity", fallback, quantity_names);
    std::vector<std::string> colormaps;
    for(const auto& n : lapmesh::colormap_names()) colormaps.push_back(n.name);
    c.colormap = p.choice("colormap", "jet", colormaps);
    c.mode = p.choice("range", "auto", {"auto", "percentile", "symmetric", "manual"});
    c.clip = p.number("clip", c.mode == "percentile" ? 1.0 : 0.0, 0.0, 49.9);
    const bool manual = c.mode == "manual";
    const double lo = manual ? p.number("min", 0, -1e300, 1e300) : 0, hi = manual ? p.number("max", 1, -1e300, 1e300) : 1;
    if(manual && !(lo < hi)) throw Http_error(400, "manual range: 'min' must be less than 'max'");
    if(!manual && (p.has("min") || p.has("max"))) throw Http_error(400, "'min' and 'max' need range=manual");
    if(c.quantity.empty()) {
      if(required) throw Http_error(409, "mesh '" + s.source.id + "' has no per-vertex values yet: run an operation first");
      return c;
    }
    auto it = s.scalars.find(c.quantity);
    if(it == s.scalars.end())
      throw Http_error(409, "no '" + c.quantity + "' values on mesh '" + s.source.id + "' now" +
                              (s.scalars.empty() ? " (run an operation first)"
                                                 : c.quantity == "displacement" ? " (run smoothing, noise or reconstruction)"
                                                                                : " (run curvature)"));
    c.values = &it->second;
    if(c.mode == "auto") c.range = lapmesh::auto_range(*c.values, c.mode == "auto" && p.has("clip") ? c.clip : 0.0);
    else if(c.mode == "percentile") c.range = lapmesh::auto_range(*c.values, c.clip);
    else if(c.mode == "symmetric") c.range = lapmesh::symmetric_range(*c.values, c.clip);
    else c.range = {lo, hi};
    return c;
  }

  std::string get_scalars(Mesh_state& s, Params& p)
  {
    Coloring c = coloring(s, p, true);
    p.finish();
    const std::vector<lapmesh::Rgb> rgb = lapmesh::colorize(*c.values, *lapmesh::parse_colormap(c.colormap), c.range);
    double lo = INFINITY, hi = -INFINITY;
    for(double x : *c.values)
      if(std::isfinite(x)) lo = std::min(lo, x), hi = std::max(hi, x);
    Frame f;
    f.header()["quantity"] = c.quantity;
    f.header()["colormap"] = c.colormap;
    f.header()["range_mode"] = c.mode;
    f.header()["clip"] = c.clip;
    f.header()["range"] = {c.range.min, c.range.max};
    f.header()["data_range"] = std::isfinite(lo) ? json{lo, hi} : json(nullptr);
    f.header()["available"] = json::array();
    for(const auto& kv : s.scalars) f.header()["available"].push_back(kv.first);
    f.header()["info"] = s.scalar_info;
    f.header()["version"] = s.version;
    f.add("values", "float64", c.values->data(), c.values->size());
    static_assert(sizeof(lapmesh::Rgb) == 3, "packed RGB");
    f.add("colors", "uint8", reinterpret_cast<const std::uint8_t*>(rgb.data()), 3 * rgb.size(), 3);
    return f.str();
  }

  std::string get_geometry(Mesh_state& s, Params& p)
  {
    p.finish();
    const lapmesh::Vertex_vectors P = positions(s);
    std::vector<std::uint32_t> idx;
    idx.reserve(3 * s.triangles.size());
    for(const auto& t : s.triangles)
      for(std::size_t v : t) idx.push_back(std::uint32_t(v));
    Frame f;
    f.header()["id"] = s.source.id;
    f.header()["vertices"] = P.rows();
    f.header()["faces"] = s.triangles.size();
    f.header()["version"] = s.version;
    f.header()["scalars"] = json::array();
    for(const auto& kv : s.scalars) f.header()["scalars"].push_back(kv.first);
    f.add("positions", "float64", P.data(), std::size_t(P.size()), 3);
    f.add("indices", "uint32", idx.data(), idx.size(), 3);
    return f.str();
  }

  std::string get_download(Mesh_state& s, Params& p, std::string& filename)
  {
    const std::string format = p.choice("format", "ply", {"ply", "off"});
    Coloring c = coloring(s, p, false);
    p.finish();
    lapmesh::io::Vertex_attributes a;
    if(format == "ply")
      for(const auto& kv : s.scalars) a.scalars.push_back(kv);
    if(c.values) a.colors = lapmesh::colorize(*c.values, *lapmesh::parse_colormap(c.colormap), c.range);
    std::ostringstream os;
    lapmesh::io::write_mesh(os, format, positions(s), s.triangles, a);
    filename = s.source.id + (c.values ? "_" + c.quantity : std::string()) + "." + format;
    return os.str();
  }

  json progress(Mesh_state& s)
  {
    json j = {{"running", s.running.load()}, {"done", s.done.load()}, {"total", s.total.load()}};
    {
      std::lock_guard<std::mutex> g(s.progress_mutex);
      j["operation"] = s.operation;
      j["stage"] = s.stage;
      j["request_id"] = s.request_id;
    }
    j["mesh"] = s.source.id;
    if(s.running) j["elapsed_ms"] = ms_since(Clock::time_point(Clock::duration(s.started_ns.load())));
    j["cancel_requested"] = s.cancel.load();
    return j;
  }

  // ---- HTTP ----

  static void send_json(httplib::Response& res, const json& j, int status = 200)
  {
    res.status = status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(j.dump(), "application/json");
  }

  static void send_error(httplib::Response& res, int status, const std::string& what)
  {
    send_json(res, {{"error", what}}, status);
  }

  /// Runs a handler and turns every exception into a JSON error: the server never dies.
  template <typename F>
  static void guarded(httplib::Response& res, F&& f)
  {
    // From here on the connection is being answered: it is not closed to make room for others.
    if(current_connection) current_connection->set_phase(Connection::Phase::handling);
    try {
      f();
    } catch(const Http_error& e) {
      send_error(res, e.status, e.what());
    } catch(const Cancelled&) {
      send_error(res, 409, "cancelled");
    } catch(const lapmesh::Mesh_error& e) {
      send_error(res, 422, std::string("mesh error: ") + e.what());
    } catch(const lapmesh::Numerical_error& e) {
      send_error(res, 500, std::string("numerical failure: ") + e.what());
    } catch(const lapmesh::Io_error& e) {
      send_error(res, 500, std::string("i/o error: ") + e.what());
    } catch(const std::invalid_argument& e) {
      send_error(res, 400, e.what());
    } catch(const std::bad_alloc&) {
      send_error(res, 507, "out of memory");
    } catch(const std::exception& e) {
      send_error(res, 500, e.what());
    } catch(...) {
      send_error(res, 500, "unknown failure");
    }
  }

  // ---- connections ----

  void accept_loop()
  {
    accepting = true;
    while(!stopping) {
      pollfd p{listen_fd, POLLIN, 0};
      const int r = ::poll(&p, 1, 100);  // wakes up to see `stopping`
      if(r <= 0) {
        reap();
        continue;
      }
      sockaddr_storage a{};
      socklen_t len = sizeof a;
      const int fd = ::accept4(listen_fd, (sockaddr*)&a, &len, SOCK_CLOEXEC);
      if(fd < 0) {
        if(errno == EMFILE || errno == ENFILE) std::this_thread::sleep_for(std::chrono::milliseconds(10));
        continue;
      }
      char host[NI_MAXHOST] = "?";
      ::getnameinfo((sockaddr*)&a, len, host, sizeof host, nullptr, 0, NI_NUMERICHOST);
      admit(fd, host);
    }
    accepting = false;
  }

  /// Joins the threads of finished connections (connections_mutex held).
  void reap_locked()
  {
    for(auto it = connections.begin(); it != connections.end();) {
      if((*it)->finished) {
        if((*it)->thread.joinable()) (*it)->thread.join();
        it = connections.erase(it);
      } else {
        ++it;
      }
    }
  }
  void reap()
  {
    std::lock_guard<std::mutex> g(connections_mutex);
    reap_locked();
  }

  /// A connection waiting for (the rest of) a request this long counts as stalled: it may be
  /// closed to make room. Shorter waits are spared (a request in flight, a loaded machine).
  static constexpr long long stalled_after_ns = 1'000'000'000;

  /// Gives a new connection its thread, within the limits: over a limit, the connection
  /// (of this address, or any) that has stalled longest is closed to make room; if none has
  /// stalled, the newcomer gets 503.
  void admit(int fd, const std::string& address)
  {
    std::lock_guard<std::mutex> g(connections_mutex);
    reap_locked();
    int total = 0, same = 0;
    Connection *oldest_same = nullptr, *oldest_any = nullptr;
    auto older = [](Connection* a, Connection* b) { return !a || b->phase_since_ns < a->phase_since_ns; };
    const long long now = Clock::now().time_since_epoch().count();
    for(auto& c : connections) {
      if(c->finished || c->fd < 0 || c->evicted) continue;
      // A connection its client has closed is about to end (its thread may just not have run
      // yet on a loaded machine): it does not count.
      pollfd p{c->fd, POLLRDHUP, 0};
      if(::poll(&p, 1, 0) > 0 && (p.revents & (POLLRDHUP | POLLHUP | POLLERR))) continue;
      ++total;
      const bool idle = c->phase != Connection::Phase::handling && now - c->phase_since_ns >= stalled_after_ns;
      if(c->address == address) {
        ++same;
        if(idle && older(oldest_same, c.get())) oldest_same = c.get();
      }
      if(idle && older(oldest_any, c.get())) oldest_any = c.get();
    }
    Connection* victim = nullptr;
    bool refuse = false;
    if(same >= options.max_connections_per_address) {
      victim = oldest_same;
      refuse = !victim;
    } else if(total >= options.max_connections) {
      victim = oldest_any;
      refuse = !victim;
    }
    if(refuse) {
      static const std::string body = R"({"error": "too many connections"})";
      const std::string answer = "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
                                 "Connection: close\r\nContent-Length: " +
                                 std::to_string(body.size()) + "\r\n\r\n" + body;
      [[maybe_unused]] const ssize_t n = ::send(fd, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      ::close(fd);
      return;
    }
    if(victim) {
      victim->evicted = true;
      ::shutdown(victim->fd, SHUT_RDWR);  // its thread sees end of file and finishes
    }
    auto c = std::make_unique<Connection>();
    c->fd = fd;
    c->address = address;
    c->set_phase(Connection::Phase::waiting);
    Connection* raw = c.get();
    connections.push_back(std::move(c));
    raw->thread = std::thread([this, raw] {
      serve(*raw);
      raw->finished = true;
    });
  }

  void serve(Connection& c)
  {
    current_connection = &c;
    Limited_stream stream(c, limits);
    for(int i = 0; i < max_requests_per_connection && !stopping; ++i) {
      if(!stream.begin_request()) break;
      bool closed = false;
      const bool ok = http.process_request(stream, i + 1 == max_requests_per_connection, closed, nullptr);
      if(!ok && c.limit != Connection::Limit::none) {
        // httplib gives up without an answer when the request line itself is cut short.
        const int status = c.limit == Connection::Limit::head ? 431 : c.limit == Connection::Limit::body ? 413 : 408;
        const std::string body = R"({"error": "request )" +
                                 std::string(status == 431 ? "header too large" : status == 413 ? "body too large" : "timed out") +
                                 "\"}";
        const std::string answer = "HTTP/1.1 " + std::to_string(status) +
                                   " Refused\r\nContent-Type: application/json\r\nConnection: close\r\nContent-Length: " +
                                   std::to_string(body.size()) + "\r\n\r\n" + body;
        stream.write(answer.data(), answer.size());
      }
      if(!ok || closed || c.must_close) break;
    }
    if(c.must_close) drain(c.fd);
    {
      std::lock_guard<std::mutex> g(connections_mutex);
      ::close(c.fd);  // under the lock: nobody shuts down this number once it may be reused
      c.fd = -1;
    }
    current_connection = nullptr;
  }

  /// Before closing a connection whose request was not read to its end: stop sending, then
  /// read (and drop) what the client still sends for a short, bounded while, so that the
  /// answer is not lost to a reset.
  void drain(int fd)
  {
    ::shutdown(fd, SHUT_WR);
    char buf[16384];
    std::size_t total = 0;
    const auto until = Clock::now() + std::chrono::milliseconds(500);
    while(total < (std::size_t(4) << 20) && Clock::now() < until) {
      pollfd p{fd, POLLIN, 0};
      if(::poll(&p, 1, 100) <= 0) continue;
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if(n <= 0) break;
      total += std::size_t(n);
    }
  }

  void stop()
  {
    stopping = true;
    if(accept_thread.joinable()) accept_thread.join();
    for(int i = 0; i < 50 && accepting; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if(listen_fd >= 0) {
      ::close(listen_fd);
      listen_fd = -1;
    }
    for(auto& s : meshes) s->cancel = true;
    {
      std::lock_guard<std::mutex> g(connections_mutex);
      for(auto& c : connections)
        if(c->fd >= 0) ::shutdown(c->fd, SHUT_RDWR);
    }
    // Connection threads only take connections_mutex briefly: join outside it.
    std::list<std::unique_ptr<Connection>> all;
    {
      std::lock_guard<std::mutex> g(connections_mutex);
      all.swap(connections);
    }
    for(auto& c : all)
      if(c->thread.joinable()) c->thread.join();
  }

  static bool has_body(const httplib::Request& req)
  {
    return req.has_header("Transfer-Encoding") ||
           (req.has_header("Content-Length") && req.get_header_value("Content-Length") != "0");
  }

  /// The methods a path answers to ("" for an unknown /api path: the handlers say 404).
  static std::string allowed_methods(const std::string& path)
  {
    static const std::regex mesh_route(R"(/api/meshes/[^/]*/([^/]*))");
    std::smatch m;
    if(std::regex_match(path, m, mesh_route)) {
      static const std::set<std::string> reads = {"geometry", "scalars", "download", "progress"};
      static const std::set<std::string> ops = {"reset", "curvature", "reconstruct", "smooth", "noise", "cancel"};
      return reads.count(m[1]) ? "GET, HEAD" : ops.count(m[1]) ? "POST" : "";
    }
    if(path == "/api/info" || path == "/api/meshes" || path == "/api/colormaps") return "GET, HEAD";
    return path.rfind("/api/", 0) == 0 ? "" : "GET, HEAD";
  }

  /// Refuses, before its body is read, a request no handler must see: a method the route
  /// does not take (405 with Allow), a declared body above the limit, a compressed body (its
  /// inflated size is unknown), a transfer coding other than chunked, byte ranges.
  std::optional<std::pair<int, std::string>> screen(const httplib::Request& req, httplib::Response& res)
  {
    const std::string allow = allowed_methods(req.path);
    bool known = false;
    for(std::size_t at = 0; at < allow.size();) {
      const std::size_t end = std::min(allow.find(", ", at), allow.size());
      known = known || allow.compare(at, end - at, req.method) == 0;
      at = end + 2;
    }
    if(req.method == "OPTIONS" && !allow.empty()) {
      res.set_header("Allow", allow + ", OPTIONS");
      return std::make_pair(204, std::string());
    }
    if(allow.empty() && req.method != "GET" && req.method != "POST")
      return std::make_pair(404, "not found: " + req.path.substr(0, 80));
    if(!allow.empty() && !known) {
      res.set_header("Allow", allow);
      return std::make_pair(405, "method " + req.method.substr(0, 16) + " not allowed on " + req.path.substr(0, 80) +
                                   " (allowed: " + allow + ")");
    }
    if(req.has_header("Content-Encoding") && req.get_header_value("Content-Encoding") != "identity")
      return std::make_pair(415, std::string("compressed request bodies are not accepted"));
    if(req.has_header("Transfer-Encoding")) {
      if(req.get_header_value("Transfer-Encoding") != "chunked" || req.has_header("Content-Length"))
        return std::make_pair(400, std::string("only 'Transfer-Encoding: chunked' without Content-Length is accepted"));
    }
    if(req.has_header("Content-Length")) {
      const std::string v = req.get_header_value("Content-Length");
      if(v.empty() || v.size() > 18 || v.find_first_not_of("0123456789") != std::string::npos ||
         req.get_header_value_count("Content-Length") != 1)
        return std::make_pair(400, std::string("invalid Content-Length"));
      if(std::stoull(v) > options.max_body_bytes)
        return std::make_pair(413, "request body too large (limit " + std::to_string(options.max_body_bytes) + " bytes)");
    }
    if(req.has_header("Range")) return std::make_pair(416, std::string("byte ranges are not served"));
    return std::nullopt;
  }

  void routes()
  {
    http.set_payload_max_length(options.max_body_bytes);
    http.set_error_handler([this](const httplib::Request& req, httplib::Response& res) {
      if(!res.body.empty()) return;
      // A request the stream cut short: say which limit it hit.
      const Connection::Limit limit = current_connection ? current_connection->limit : Connection::Limit::none;
      if(limit == Connection::Limit::head) res.status = 431;
      if(limit == Connection::Limit::body) res.status = 413;
      if(limit == Connection::Limit::time) res.status = 408;
      const std::string what =
        res.status == 404   ? "not found: " + req.path.substr(0, 80)
        : res.status == 413 ? "request body too large (limit " + std::to_string(options.max_body_bytes) + " bytes)"
        : res.status == 431 ? "request header too large (limit " + std::to_string(options.max_header_bytes) + " bytes)"
        : res.status == 408 ? "request not received within " + std::to_string(options.request_timeout_ms) + " ms"
        : res.status == 400 ? "bad request"
                            : "HTTP " + std::to_string(res.status);
      send_error(res, res.status, what);
    });
    // Before the body is read: methods, declared sizes and encodings.
    http.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      std::optional<std::pair<int, std::string>> refusal = screen(req, res);
      if(!refusal) return httplib::Server::HandlerResponse::Unhandled;
      // The body (if any) stays unread: the connection cannot carry another request.
      if(current_connection && has_body(req)) current_connection->must_close = true;
      if(refusal->first == 204) {
        res.status = 204;
        return httplib::Server::HandlerResponse::Handled;
      }
      send_error(res, refusal->first, refusal->second);
      return httplib::Server::HandlerResponse::Handled;
    });
    http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
      guarded(res, [&] { std::rethrow_exception(ep); });
    });

    http.Get("/api/info", [this](const httplib::Request&, httplib::Response& res) {
      guarded(res, [&] {
        send_json(res, {{"name", "lapmesh view"},
                        {"version", "0.1.0"},
                        {"limits",
                         {{"max_body_bytes", options.max_body_bytes},
                          {"max_k", options.max_k},
                          {"max_iterations", options.max_iterations},
                          {"max_vertices", options.max_vertices},
                          {"max_header_bytes", options.max_header_bytes},
                          {"request_timeout_ms", options.request_timeout_ms},
                          {"max_connections", options.max_connections},
                          {"max_connections_per_address", options.max_connections_per_address}}},
                        {"cache", bases.stats()},
                        {"quantities", quantity_names},
                        {"colormaps", {"jet", "viridis", "coolwarm", "gray"}}});
      });
    });
    http.Get("/api/meshes", [this](const httplib::Request&, httplib::Response& res) {
      guarded(res, [&] {
        json list = json::array();
        for(auto& m : meshes) list.push_back(mesh_summary(*m));
        send_json(res, {{"meshes", list}});
      });
    });
    http.Get("/api/colormaps", [](const httplib::Request&, httplib::Response& res) {
      guarded(res, [&] {
        json maps = json::object();
        for(const auto& [name, map] : lapmesh::colormap_names()) {
          json samples = json::array();
          for(int i = 0; i < 256; ++i) {
            const lapmesh::Rgb c = lapmesh::map_color(map, i / 255.0);
            samples.push_back(c.r);
            samples.push_back(c.g);
            samples.push_back(c.b);
          }
          maps[name] = samples;
        }
        send_json(res, {{"samples", 256}, {"maps", maps}});
      });
    });

    http.Get(R"(/api/meshes/([^/]*)/([^/]*))", [this](const httplib::Request& req, httplib::Response& res) {
      guarded(res, [&] {
        Mesh_state& s = find(req.matches[1]);
        const std::string action = req.matches[2];
        Params p = Params::from_query(req);
        if(action == "progress") {
          p.finish();
          return send_json(res, progress(s));
        }
        if(action != "geometry" && action != "scalars" && action != "download")
          throw Http_error(404, "unknown resource '" + sanitize_id(action) + "' (geometry, scalars, download, progress)");
        auto l = read_lock(s);
        if(action == "geometry") {
          res.set_content(get_geometry(s, p), "application/octet-stream");
        } else if(action == "scalars") {
          res.set_content(get_scalars(s, p), "application/octet-stream");
        } else {
          std::string name;
          const std::string body = get_download(s, p, name);
          res.set_header("Content-Disposition", "attachment; filename=\"" + name + "\"");
          res.set_content(body, "application/octet-stream");
        }
        res.set_header("Cache-Control", "no-store");
      });
    });

    http.Post(R"(/api/meshes/([^/]*)/([^/]*))", [this](const httplib::Request& req, httplib::Response& res) {
      guarded(res, [&] {
        Mesh_state& s = find(req.matches[1]);
        const std::string action = req.matches[2];
        Params p = Params::from_body(req.body);
        const std::string request_id = p.request_id();
        if(action == "cancel") {
          p.finish();
          // With a request id, only that operation is cancelled (not one started since).
          std::string running_id;
          {
            std::lock_guard<std::mutex> g(s.progress_mutex);
            running_id = s.request_id;
          }
          const bool running = s.running && (request_id.empty() || request_id == running_id);
          if(running) s.cancel = true;
          return send_json(res, {{"cancelling", running}, {"mesh", s.source.id}, {"request_id", running_id}});
        }
        using Op = json (Impl::*)(Mesh_state&, Params&);
        static const std::map<std::string, Op> ops = {{"reset", &Impl::op_reset},
                                                      {"curvature", &Impl::op_curvature},
                                                      {"reconstruct", &Impl::op_reconstruct},
                                                      {"smooth", &Impl::op_smooth},
                                                      {"noise", &Impl::op_noise}};
        auto op = ops.find(action);
        if(op == ops.end())
          throw Http_error(404, "unknown operation '" + sanitize_id(action) +
                                  "' (reset, curvature, reconstruct, smooth, noise, cancel)");
        auto l = write_lock(s);
        Running running(s, action, request_id);
        const auto t0 = Clock::now();
        json out = (this->*(op->second))(s, p);
        out["elapsed_ms"] = ms_since(t0);
        out["operation"] = action;
        out["mesh"] = s.source.id;
        out["request_id"] = request_id;
        out["version"] = s.version;
        out["geometry"] = s.geometry;
        out["vertices"] = num_vertices(s.current);
        out["scalars"] = json::array();
        for(const auto& kv : s.scalars) out["scalars"].push_back(kv.first);
        send_json(res, out);
      });
    });

    // The page: only the files found in the assets directory at start-up, by exact URL path.
    http.Get(R"(/(.*))", [this](const httplib::Request& req, httplib::Response& res) {
      guarded(res, [&] {
        if(req.path.rfind("/api/", 0) == 0) throw Http_error(404, "not found: " + req.path.substr(0, 80));
        const std::string path = req.path == "/" ? "/index.html" : req.path;
        auto it = files.find(path);
        if(it == files.end()) {
          if(path == "/index.html") {
            res.set_content("<!doctype html><title>lapmesh view</title><p>The page of lapmesh view was not found "
                            "(build the CMake target lapmesh_viewer_web, or pass --assets DIR). The API is at "
                            "<a href=\"/api/meshes\">/api/meshes</a>.</p>",
                            "text/html; charset=utf-8");
            return;
          }
          throw Http_error(404, "not found: " + req.path.substr(0, 80));
        }
        std::ifstream in(it->second.path, std::ios::binary);
        if(!in) throw Http_error(404, "not found: " + req.path.substr(0, 80));
        std::ostringstream os;
        os << in.rdbuf();
        res.set_content(os.str(), it->second.type);
      });
    });
  }
};

Server::Server(std::vector<Mesh_source> meshes, Server_options options)
  : m(std::make_unique<Impl>(std::move(meshes), std::move(options)))
{}

Server::~Server() { stop(); }

void Server::preload()
{
  for(auto& s : m->meshes) {
    try {
      m->load(*s);
    } catch(const Http_error& e) {
      throw std::runtime_error(s->source.kind == Mesh_source::Kind::file
                                 ? std::string(e.what()).replace(0, s->source.label.size(), s->source.path)
                                 : std::string(e.what()));
    }
  }
}

int Server::bind()
{
  if(m->listen_fd >= 0) throw std::runtime_error("the server is bound already");
  const std::string& host = m->options.host;
  const std::string where = (host.find(':') != std::string::npos ? "[" + host + "]" : host) + ":" +
                            std::to_string(m->options.port);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if(const int rc = ::getaddrinfo(host.c_str(), std::to_string(m->options.port).c_str(), &hints, &found); rc != 0)
    throw std::runtime_error("cannot bind to " + where + ": " + ::gai_strerror(rc));
  int error = 0;
  for(addrinfo* a = found; a && m->listen_fd < 0; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if(fd < 0) {
      error = errno;
      continue;
    }
    // SO_REUSEADDR only (a restart may bind over connections in TIME_WAIT); never
    // SO_REUSEPORT, which would let a second server share this port and its requests.
    const int yes = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    if(::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, 64) == 0) {
      m->listen_fd = fd;
    } else {
      error = errno;
      ::close(fd);
    }
  }
  ::freeaddrinfo(found);
  if(m->listen_fd < 0)
    throw std::runtime_error("cannot bind to " + where + ": " + std::strerror(error) +
                             (error == EADDRINUSE ? " (another server listens there: try another --port, or none for a free one)"
                                                  : ""));
  sockaddr_storage a{};
  socklen_t len = sizeof a;
  ::getsockname(m->listen_fd, (sockaddr*)&a, &len);
  return ntohs(a.ss_family == AF_INET6 ? ((sockaddr_in6*)&a)->sin6_port : ((sockaddr_in*)&a)->sin_port);
}

void Server::listen()
{
  if(m->listen_fd < 0) bind();
  m->accept_loop();
}

int Server::start()
{
  int port = 0;
  {
    sockaddr_storage a{};
    socklen_t len = sizeof a;
    if(m->listen_fd < 0) port = bind();
    else if(::getsockname(m->listen_fd, (sockaddr*)&a, &len) == 0)
      port = ntohs(a.ss_family == AF_INET6 ? ((sockaddr_in6*)&a)->sin6_port : ((sockaddr_in*)&a)->sin_port);
  }
  m->accepting = true;
  m->accept_thread = std::thread([this] { m->accept_loop(); });
  return port;
}

void Server::stop() { m->stop(); }

} // namespace lapmesh_viewer
