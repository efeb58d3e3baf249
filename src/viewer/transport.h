// The transport of `lapmesh view`: the listening socket, the connections and the stream
// requests are read from.
//
// httplib parses requests and routes them, but its own accept loop cannot stand up to slow
// or hostile clients (a fixed pool of 8 threads held by half-sent requests, header lines
// without a total limit, chunked bodies without a size limit, SO_REUSEPORT on the listening
// socket). So the server accepts connections itself, gives each its own thread (bounded in
// number, overall and per client address) and hands httplib a stream that enforces a
// deadline and a byte budget on every request.
#ifndef LAPMESH_VIEWER_TRANSPORT_H
#define LAPMESH_VIEWER_TRANSPORT_H

#include <httplib.h>

#include <poll.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace lapmesh_viewer {

using Clock = std::chrono::steady_clock;

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

/// The connection the calling thread serves (nullptr outside a connection thread).
extern thread_local Connection* current_connection;

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
  bool begin_request();

  bool is_readable() const override { return m_pos < m_end || wait(POLLIN, m_l.io_ms); }
  bool is_writable() const override { return wait(POLLOUT, m_l.io_ms); }
  ssize_t read(char* ptr, std::size_t size) override;
  ssize_t write(const char* ptr, std::size_t size) override;
  void get_remote_ip_and_port(std::string& ip, int& port) const override { address_of(true, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { address_of(false, ip, port); }
  int socket() const override { return m_c.fd; }

private:
  ssize_t stop(Connection::Limit why);
  bool wait(short events, int ms) const;
  /// Refills the buffer, waiting until `deadline` at most (in steps of io_ms).
  bool fill(Clock::time_point deadline);
  void address_of(bool peer, std::string& ip, int& port) const;

  Connection& m_c;
  const Transport_limits& m_l;
  char m_buf[4096];
  std::size_t m_pos = 0, m_end = 0;
  bool m_eof = false, m_head_done = false;
  std::size_t m_head_bytes = 0, m_body_bytes = 0;
  std::uint64_t m_tail = 0;
  Clock::time_point m_deadline;
};

/// The listening socket and the connections: each accepted connection gets its own thread
/// (bounded in number, overall and per client address), which feeds its requests to the
/// router through a Limited_stream.
class Listener
{
public:
  Listener(Http_router& http, const Transport_limits& limits, int max_connections, int max_per_address)
    : http(http), limits(limits), max_connections(max_connections), max_per_address(max_per_address)
  {}
  Listener(const Listener&) = delete;
  Listener& operator=(const Listener&) = delete;

  /// Binds and listens on host:port (0: a free port); returns the port.
  int bind(const std::string& host, int port);
  bool bound() const { return listen_fd >= 0; }
  /// Accepts connections in the calling thread until stop_accepting().
  void accept_loop();
  /// Accepts connections in a thread of its own; returns the port.
  int start();
  /// Stops accepting and closes the listening socket; the connections go on.
  void stop_accepting();
  /// Shuts the connections down and joins their threads.
  void close_connections();

private:
  int bound_port() const;
  void reap_locked();
  void reap();
  void admit(int fd, const std::string& address);
  void serve(Connection& c);

  /// A connection waiting for (the rest of) a request this long counts as stalled: it may be
  /// closed to make room. Shorter waits are spared (a request in flight, a loaded machine).
  static constexpr long long stalled_after_ns = 1'000'000'000;
  static constexpr int max_requests_per_connection = 1000;

  Http_router& http;
  const Transport_limits limits;
  const int max_connections, max_per_address;
  int listen_fd = -1;
  std::atomic<bool> stopping{false}, accepting{false};
  std::thread accept_thread;
  std::mutex connections_mutex;
  std::list<std::unique_ptr<Connection>> connections;
};

/// Before closing a connection whose request was not read to its end: stop sending, then
/// read (and drop) what the client still sends for a short, bounded while, so that the
/// answer is not lost to a reset.
void drain(int fd);

} // namespace lapmesh_viewer

#endif
