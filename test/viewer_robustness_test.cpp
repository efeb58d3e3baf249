// `lapmesh view` against hostile and unlucky clients, in process on loopback: a busy port,
// slow and half-sent requests, chunked and oversized bodies, many concurrent reads, methods
// a route does not take, the eigenbasis cache, and a mesh switch during an operation. Every
// loop is bounded in count and in time; only built-in meshes are used.
#include "viewer_server.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <future>
#include <thread>

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// A blocking loopback socket with send/receive timeouts (no call here waits for ever).
class Raw_client
{
public:
  explicit Raw_client(int port)
  {
    m_fd = ::socket(AF_INET, SOCK_STREAM, 0);
    timeval tv{5, 0};
    ::setsockopt(m_fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    ::setsockopt(m_fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(std::uint16_t(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    m_connected = ::connect(m_fd, (sockaddr*)&a, sizeof a) == 0;
  }
  ~Raw_client() { ::close(m_fd); }
  Raw_client(const Raw_client&) = delete;
  Raw_client& operator=(const Raw_client&) = delete;

  bool connected() const { return m_connected; }
  bool send(const std::string& s)
  {
    std::size_t at = 0;
    while(at < s.size()) {
      const ssize_t n = ::send(m_fd, s.data() + at, s.size() - at, MSG_NOSIGNAL);
      if(n <= 0) return false;
      at += std::size_t(n);
    }
    return true;
  }
  /// Everything until the server closes or `seconds` pass.
  std::string receive_all(double seconds)
  {
    std::string out;
    const auto t0 = Clock::now();
    char buf[4096];
    while(seconds_since(t0) < seconds) {
      pollfd p{m_fd, POLLIN, 0};
      if(::poll(&p, 1, 100) <= 0) continue;
      const ssize_t n = ::recv(m_fd, buf, sizeof buf, 0);
      if(n <= 0) break;
      out.append(buf, std::size_t(n));
    }
    return out;
  }
  /// True once the server has closed the connection (end of file or reset), within `seconds`.
  bool closed_within(double seconds)
  {
    const auto t0 = Clock::now();
    char buf[4096];
    while(seconds_since(t0) < seconds) {
      pollfd p{m_fd, POLLIN, 0};
      if(::poll(&p, 1, 100) <= 0) continue;
      if(::recv(m_fd, buf, sizeof buf, 0) <= 0) return true;
    }
    return false;
  }

private:
  int m_fd = -1;
  bool m_connected = false;
};

/// The status code of a raw answer ("HTTP/1.1 413 ..."), 0 if there is none.
int code(const std::string& answer)
{
  return answer.rfind("HTTP/1.1 ", 0) == 0 && answer.size() >= 12 ? std::atoi(answer.substr(9, 3).c_str()) : 0;
}

long long rss_kib()
{
  std::ifstream in("/proc/self/status");
  std::string line;
  while(std::getline(in, line))
    if(line.rfind("VmRSS:", 0) == 0) return std::stoll(line.substr(6));
  return -1;
}

class ViewerRobustness : public ::testing::Test
{
protected:
  static void SetUpTestSuite()
  {
    lapmesh_viewer::Server_options o;
    o.request_timeout_ms = 3000;  // shorter than the default 10 s, to keep the test short
    o.io_timeout_ms = 2000;
    o.max_k = 100;
    server = new lapmesh_viewer::Server(lapmesh_viewer::default_mesh_sources({}, ""), o);
    server->preload();
    port = server->start();
  }
  static void TearDownTestSuite()
  {
    delete server;
    server = nullptr;
  }
  static httplib::Client client()
  {
    httplib::Client c("127.0.0.1", port);
    c.set_connection_timeout(5, 0);
    c.set_read_timeout(60, 0);
    return c;
  }
  /// Seconds /api/info takes, and that it answered 200.
  static double info_latency()
  {
    const auto t0 = Clock::now();
    auto r = client().Get("/api/info");
    const double s = seconds_since(t0);
    EXPECT_TRUE(r && r->status == 200);
    return s;
  }
  static json post(const std::string& path, const json& body, int expected = 200)
  {
    auto r = client().Post(path.c_str(), body.dump(), "application/json");
    EXPECT_TRUE(r) << path;
    if(!r) return {};
    EXPECT_EQ(r->status, expected) << path << " -> " << r->body;
    return json::parse(r->body);
  }

  static std::size_t get_cache_bytes() { return json::parse(client().Get("/api/info")->body)["cache"]["bytes"]; }
  static void expect_bad_request_id()
  {
    auto r = client().Post("/api/meshes/icosphere/curvature", R"({"request_id": "a b"})", "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400);
    EXPECT_NE(r->body.find("request_id"), std::string::npos);
  }

  static lapmesh_viewer::Server* server;
  static int port;
};
lapmesh_viewer::Server* ViewerRobustness::server = nullptr;
int ViewerRobustness::port = 0;

TEST_F(ViewerRobustness, ABusyPortIsNotShared)
{
  lapmesh_viewer::Server_options o;
  o.port = port;
  lapmesh_viewer::Server second(lapmesh_viewer::default_mesh_sources({}, ""), o);
  try {
    second.bind();
    FAIL() << "a second server bound the busy port " << port;
  } catch(const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot bind to 127.0.0.1:" + std::to_string(port)), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("in use"), std::string::npos) << e.what();
  }
  // The command line: one line on stderr and a non-zero exit, at once (bounded by timeout).
  const std::string cmd = "timeout 60 " LAPMESH_CLI " view --port " + std::to_string(port) + " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[512];
  while(std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = ::pclose(p);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1) << out;
  EXPECT_NE(out.find("cannot bind to 127.0.0.1:" + std::to_string(port)), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  EXPECT_LT(info_latency(), 1.0);
}

TEST_F(ViewerRobustness, SlowHeaderLinesDoNotFreezeOthersAndAreCutOff)
{
  // Eight clients each send a header line every second and never finish their request.
  std::vector<std::unique_ptr<Raw_client>> slow;
  for(int i = 0; i < 8; ++i) {
    slow.push_back(std::make_unique<Raw_client>(port));
    ASSERT_TRUE(slow.back()->connected());
    slow.back()->send("GET /api/info HTTP/1.1\r\nHost: x\r\n");
  }
  std::atomic<bool> stop{false};
  std::thread dribble([&] {
    for(int round = 0; round < 10 && !stop; ++round) {
      for(auto& c : slow) c->send("X-Slow-" + std::to_string(round) + ": 1\r\n");
      for(int i = 0; i < 10 && !stop; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  });
  double worst = 0;
  for(int i = 0; i < 10; ++i) {
    worst = std::max(worst, info_latency());
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
  }
  EXPECT_LT(worst, 1.0);
  // The request deadline (3 s here) ends each of them with 408, well before 10 rounds.
  const auto t0 = Clock::now();
  for(auto& c : slow) {
    const std::string answer = c->receive_all(6.0);
    EXPECT_EQ(code(answer), 408) << answer.substr(0, 200);
  }
  EXPECT_LT(seconds_since(t0), 6.0);
  stop = true;
  dribble.join();
}

TEST_F(ViewerRobustness, HalfSentRequestsDoNotDelayOthers)
{
  // Thirty half-sent requests; then more than this address may hold (64): the ones that
  // stalled longest (over 1 s) make room.
  std::vector<std::unique_ptr<Raw_client>> half;
  for(int i = 0; i < 70; ++i) {
    if(i == 30) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      EXPECT_LT(info_latency(), 1.0);
    }
    if(i == 60) std::this_thread::sleep_for(std::chrono::milliseconds(1100));
    half.push_back(std::make_unique<Raw_client>(port));
    ASSERT_TRUE(half.back()->connected());
    half.back()->send(i % 2 ? "GET /api/info HTTP/1.1\r\nHost: x\r\nX-Half: " :
                              "POST /api/meshes/icosphere/curvature HTTP/1.1\r\nContent-Length: 40\r\n\r\n{\"lapl");
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  double worst = 0;
  for(int i = 0; i < 5; ++i) worst = std::max(worst, info_latency());
  EXPECT_LT(worst, 1.0);
  int closed = 0;
  for(int i = 0; i < 30; ++i) closed += half[std::size_t(i)]->closed_within(0.05);
  EXPECT_GE(closed, 6) << "the oldest stalled connections were not closed to make room";
  EXPECT_LE(closed, 30);
  // A header without end: cut at the header limit with 431.
  Raw_client big(port);
  ASSERT_TRUE(big.connected());
  big.send("GET /api/info HTTP/1.1\r\n");
  std::string fields;
  for(int i = 0; i < 1000; ++i) fields += "X-Filler-" + std::to_string(i) + ": " + std::string(40, 'a') + "\r\n";
  big.send(fields);  // ~55 KB, more than the 16 KiB limit
  EXPECT_EQ(code(big.receive_all(5.0)), 431);
  // A request line without end.
  Raw_client line(port);
  line.send("GET /" + std::string(40000, 'a'));
  EXPECT_EQ(code(line.receive_all(5.0)), 431);
  EXPECT_LT(info_latency(), 1.0);
}

TEST_F(ViewerRobustness, ChunkedAndOversizedBodiesAreRefusedEarly)
{
  const std::string head = "POST /api/meshes/icosphere/curvature HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n";
  auto chunk = [](const std::string& data) {
    char size[32];
    std::snprintf(size, sizeof size, "%zx\r\n", data.size());
    return size + data + "\r\n";
  };
  // A small chunked body is read and parsed.
  {
    Raw_client c(port);
    c.send(head + "Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n" + chunk("{\"laplacian\":") + chunk(" \"uniform\"}") + "0\r\n\r\n");
    const std::string answer = c.receive_all(30.0);
    EXPECT_EQ(code(answer), 200) << answer.substr(0, 300);
    EXPECT_NE(answer.find("\"laplacian\":\"uniform\""), std::string::npos);
  }
  // 2 MB of chunked JSON: 413, not parsed.
  {
    Raw_client c(port);
    std::atomic<std::size_t> sent{0};
    std::thread sender([&] {
      if(!c.send(head + "Transfer-Encoding: chunked\r\n\r\n" + chunk("{\"laplacian\": \"") )) return;
      const std::string piece = chunk(std::string(64 * 1024, 'x'));
      for(int i = 0; i < 32 && c.send(piece); ++i) sent += piece.size();
    });
    const std::string answer = c.receive_all(10.0);
    sender.join();
    EXPECT_EQ(code(answer), 413) << answer.substr(0, 300);
    EXPECT_NE(answer.find("request body too large"), std::string::npos);
  }
  // 200 MB of spaces, chunked: refused after the first few hundred KB, nothing buffered.
  {
    const long long rss0 = rss_kib();
    Raw_client c(port);
    std::atomic<std::size_t> sent{0};
    std::thread sender([&] {
      if(!c.send(head + "Transfer-Encoding: chunked\r\n\r\n")) return;
      const std::string piece = chunk(std::string(1 << 20, ' '));
      for(int i = 0; i < 200 && c.send(piece); ++i) sent += piece.size();
    });
    const auto t0 = Clock::now();
    const std::string answer = c.receive_all(10.0);
    const double took = seconds_since(t0);
    sender.join();
    EXPECT_EQ(code(answer), 413) << answer.substr(0, 300);
    EXPECT_LT(took, 5.0);
    EXPECT_LT(sent.load(), std::size_t(64) << 20) << "the server kept reading";
    EXPECT_LT(rss_kib() - rss0, 64 * 1024) << "the server buffered the body";
  }
  // A declared length above the limit: 413 before the body is sent.
  {
    Raw_client c(port);
    c.send(head + "Content-Length: 1000000000\r\n\r\n");
    EXPECT_EQ(code(c.receive_all(5.0)), 413);
  }
  // A compressed body (its inflated size is unknown): 415.
  {
    Raw_client c(port);
    c.send(head + "Content-Encoding: gzip\r\nContent-Length: 4\r\n\r\nabcd");
    EXPECT_EQ(code(c.receive_all(5.0)), 415);
  }
  EXPECT_LT(info_latency(), 1.0);
}

TEST_F(ViewerRobustness, ConcurrentReadsNeverConflict)
{
  post("/api/meshes/torus/reset", json::object());
  post("/api/meshes/torus/curvature", json::object());
  std::atomic<int> ok{0}, conflicts{0}, other{0};
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::vector<std::thread> threads;
  for(int t = 0; t < 20; ++t) {
    threads.emplace_back([&, t] {
      httplib::Client c = client();
      for(int i = 0; i < 10; ++i) {
        auto r = c.Get((t + i) % 3 ? "/api/meshes/torus/geometry" : "/api/meshes/torus/scalars?quantity=mean");
        if(r && r->status == 200) ++ok;
        else if(r && r->status == 409) ++conflicts;
        else {
          ++other;
          std::lock_guard<std::mutex> g(failures_mutex);
          if(failures.size() < 5) failures.push_back(r ? std::to_string(r->status) + " " + r->body.substr(0, 100) : httplib::to_string(r.error()));
        }
      }
    });
  }
  for(auto& t : threads) t.join();
  EXPECT_EQ(conflicts.load(), 0);
  EXPECT_EQ(other.load(), 0) << ::testing::PrintToString(failures);
  EXPECT_EQ(ok.load(), 200);
}

TEST_F(ViewerRobustness, MethodsARouteDoesNotTakeGet405WithAllow)
{
  struct Case
  {
    const char* method;
    const char* path;
    const char* allow;
  };
  for(const Case& c : {Case{"DELETE", "/api/info", "GET, HEAD"}, Case{"PUT", "/api/meshes", "GET, HEAD"},
                       Case{"POST", "/api/colormaps", "GET, HEAD"}, Case{"DELETE", "/api/meshes/torus/geometry", "GET, HEAD"},
                       Case{"POST", "/api/meshes/torus/geometry", "GET, HEAD"}, Case{"PATCH", "/api/meshes/torus/scalars", "GET, HEAD"},
                       Case{"GET", "/api/meshes/torus/smooth", "POST"}, Case{"DELETE", "/api/meshes/torus/reset", "POST"},
                       Case{"PUT", "/index.html", "GET, HEAD"}}) {
    Raw_client r(port);
    r.send(std::string(c.method) + " " + c.path + " HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\nConnection: close\r\n\r\n{}");
    const std::string answer = r.receive_all(5.0);
    EXPECT_EQ(code(answer), 405) << c.method << " " << c.path;
    EXPECT_NE(answer.find("Allow: " + std::string(c.allow) + "\r\n"), std::string::npos) << c.method << " " << c.path << "\n" << answer;
  }
  // Unknown resources stay 404.
  auto r = client().Get("/api/meshes/torus/passwords");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
}

TEST_F(ViewerRobustness, ASecondKReusesTheBasisAndTheCacheIsBounded)
{
  post("/api/meshes/icosphere/reset", json::object());
  const json first = post("/api/meshes/icosphere/reconstruct", {{"k", 25}});
  const std::size_t held = get_cache_bytes();
  EXPECT_GE(held, 2562u * 25 * 8);
  post("/api/meshes/icosphere/reset", json::object());
  const json second = post("/api/meshes/icosphere/reconstruct", {{"k", 16}});
  EXPECT_TRUE(second["basis_cached"].get<bool>()) << second;
  EXPECT_EQ(second["basis_size"], first["basis_size"]);
  // On the reconstructed geometry a new basis is needed; it is dropped once that geometry
  // is gone, so only the basis of the loaded geometry stays.
  const json third = post("/api/meshes/icosphere/reconstruct", {{"k", 16}});
  EXPECT_FALSE(third["basis_cached"].get<bool>());
  EXPECT_EQ(get_cache_bytes(), held);
  post("/api/meshes/icosphere/reset", json::object());
  EXPECT_TRUE(post("/api/meshes/icosphere/reconstruct", {{"k", 25}})["basis_cached"].get<bool>());
  EXPECT_FALSE(post("/api/meshes/icosphere/reconstruct", {{"k", 26}, {"laplacian", "uniform"}})["basis_cached"].get<bool>());

  // A budget of 1 MiB: a basis above it is used once and not kept; the least recently used
  // basis makes room for a new one.
  lapmesh_viewer::Server_options o;
  o.cache_bytes = 1 << 20;
  lapmesh_viewer::Server small(lapmesh_viewer::default_mesh_sources({}, ""), o);
  const int small_port = small.start();
  httplib::Client c("127.0.0.1", small_port);
  c.set_read_timeout(60, 0);
  auto reconstruct = [&](const std::string& mesh, int k) {
    auto r = c.Post(("/api/meshes/" + mesh + "/reconstruct").c_str(), json{{"k", k}}.dump(), "application/json");
    EXPECT_TRUE(r && r->status == 200) << (r ? r->body : "no answer");
    c.Post(("/api/meshes/" + mesh + "/reset").c_str(), "{}", "application/json");
    return r ? json::parse(r->body) : json();
  };
  auto cache = [&] { return json::parse(c.Get("/api/info")->body)["cache"]; };
  auto bytes_of = [](const json& r, std::size_t n) {
    const std::size_t m = r["basis_size"];
    return 8 * (n * m + m + n);
  };
  const json ico = reconstruct("icosphere", 30);  // about 0.6 MB
  EXPECT_EQ(cache()["entries"], 1);
  EXPECT_EQ(cache()["bytes"].get<std::size_t>(), bytes_of(ico, 2562));
  reconstruct("torus", 30);  // 4608 x 30 doubles: above the budget, not kept
  EXPECT_EQ(cache()["entries"], 1);
  EXPECT_EQ(cache()["bytes"].get<std::size_t>(), bytes_of(ico, 2562));
  const json bumpy = reconstruct("bumpy-sphere", 8);  // about 0.66 MB: the icosphere's basis makes room
  EXPECT_EQ(cache()["entries"], 1);
  EXPECT_EQ(cache()["bytes"].get<std::size_t>(), bytes_of(bumpy, 10242));
  EXPECT_TRUE(reconstruct("bumpy-sphere", 8)["basis_cached"].get<bool>());
  EXPECT_FALSE(reconstruct("icosphere", 30)["basis_cached"].get<bool>());
  EXPECT_LE(cache()["bytes"].get<std::size_t>(), std::size_t(1) << 20);
  small.stop();
}

TEST_F(ViewerRobustness, AMeshSwitchDuringAnOperationCancelsOnlyThatOperation)
{
  post("/api/meshes/bumpy-sphere/reset", json::object());
  auto job = std::async(std::launch::async, [] {
    return client().Post("/api/meshes/bumpy-sphere/smooth",
                         json{{"scheme", "explicit"}, {"lambda", "auto"}, {"iterations", 10000}, {"request_id", "op-A"}}.dump(),
                         "application/json");
  });
  json p;
  for(int i = 0; i < 2000; ++i) {
    p = json::parse(client().Get("/api/meshes/bumpy-sphere/progress")->body);
    if(p["running"].get<bool>() && p["done"].get<long long>() > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(p["running"].get<bool>()) << p;
  EXPECT_EQ(p["request_id"], "op-A");
  EXPECT_EQ(p["mesh"], "bumpy-sphere");
  // The user switches to the icosphere and works there meanwhile.
  post("/api/meshes/icosphere/reset", json::object());
  const json ico = post("/api/meshes/icosphere/curvature", {{"request_id", "op-B"}});
  EXPECT_EQ(ico["mesh"], "icosphere");
  EXPECT_EQ(ico["request_id"], "op-B");
  // A cancel for another operation, or on the other mesh, stops nothing.
  EXPECT_FALSE(post("/api/meshes/icosphere/cancel", {{"request_id", "op-A"}})["cancelling"].get<bool>());
  EXPECT_FALSE(post("/api/meshes/bumpy-sphere/cancel", {{"request_id", "op-B"}})["cancelling"].get<bool>());
  EXPECT_TRUE(json::parse(client().Get("/api/meshes/bumpy-sphere/progress")->body)["running"].get<bool>());
  EXPECT_TRUE(post("/api/meshes/bumpy-sphere/cancel", {{"request_id", "op-A"}})["cancelling"].get<bool>());
  auto res = job.get();
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 409);
  EXPECT_EQ(json::parse(res->body)["error"], "cancelled");
  expect_bad_request_id();
}

} // namespace
