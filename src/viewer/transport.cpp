// The transport of `lapmesh view` (transport.h).
#include "transport.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace lapmesh_viewer {

thread_local Connection* current_connection = nullptr;

bool Limited_stream::begin_request()
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

ssize_t Limited_stream::read(char* ptr, std::size_t size)
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

ssize_t Limited_stream::write(const char* ptr, std::size_t size)
{
  if(!wait(POLLOUT, m_l.io_ms)) return -1;
  const ssize_t n = ::send(m_c.fd, ptr, size, MSG_NOSIGNAL);
  return n < 0 ? -1 : n;
}

ssize_t Limited_stream::stop(Connection::Limit why)
{
  m_c.limit = why;
  m_c.must_close = true;
  return -1;
}

bool Limited_stream::wait(short events, int ms) const
{
  pollfd p{m_c.fd, events, 0};
  int r;
  do r = ::poll(&p, 1, ms);
  while(r < 0 && errno == EINTR);
  return r > 0;
}

bool Limited_stream::fill(Clock::time_point deadline)
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

void Limited_stream::address_of(bool peer, std::string& ip, int& port) const
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

int Listener::bind(const std::string& host, int port)
{
  if(listen_fd >= 0) throw std::runtime_error("the server is bound already");
  const std::string where = (host.find(':') != std::string::npos ? "[" + host + "]" : host) + ":" + std::to_string(port);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if(const int rc = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found); rc != 0)
    throw std::runtime_error("cannot bind to " + where + ": " + ::gai_strerror(rc));
  int error = 0;
  for(addrinfo* a = found; a && listen_fd < 0; a = a->ai_next) {
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
      listen_fd = fd;
    } else {
      error = errno;
      ::close(fd);
    }
  }
  ::freeaddrinfo(found);
  if(listen_fd < 0)
    throw std::runtime_error("cannot bind to " + where + ": " + std::strerror(error) +
                             (error == EADDRINUSE ? " (another server listens there: try another --port, or none for a free one)"
                                                  : ""));
  return bound_port();
}

int Listener::bound_port() const
{
  sockaddr_storage a{};
  socklen_t len = sizeof a;
  if(listen_fd < 0 || ::getsockname(listen_fd, (sockaddr*)&a, &len) != 0) return 0;
  return ntohs(a.ss_family == AF_INET6 ? ((sockaddr_in6*)&a)->sin6_port : ((sockaddr_in*)&a)->sin_port);
}

int Listener::start()
{
  if(listen_fd < 0) throw std::runtime_error("the server is not bound");
  accepting = true;
  accept_thread = std::thread([this] { accept_loop(); });
  return bound_port();
}

void Listener::accept_loop()
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
void Listener::reap_locked()
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

void Listener::reap()
{
  std::lock_guard<std::mutex> g(connections_mutex);
  reap_locked();
}

/// Gives a new connection its thread, within the limits: over a limit, the connection
/// (of this address, or any) that has stalled longest is closed to make room; if none has
/// stalled, the newcomer gets 503.
void Listener::admit(int fd, const std::string& address)
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
  if(same >= max_per_address) {
    victim = oldest_same;
    refuse = !victim;
  } else if(total >= max_connections) {
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

void Listener::serve(Connection& c)
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

void Listener::stop_accepting()
{
  stopping = true;
  if(accept_thread.joinable()) accept_thread.join();
  for(int i = 0; i < 50 && accepting; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if(listen_fd >= 0) {
    ::close(listen_fd);
    listen_fd = -1;
  }
}

void Listener::close_connections()
{
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

} // namespace lapmesh_viewer
