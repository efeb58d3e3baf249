// The transport of `lapmesh view` (transport.h).
#include "transport.h"

#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>

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

} // namespace lapmesh_viewer
