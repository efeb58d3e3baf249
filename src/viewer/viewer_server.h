// The HTTP server of `lapmesh view`: the session state (one mesh state per id) and the
// routes of the JSON/binary API (doc/viewer.md). A thin layer over the public lapmesh
// headers: no geometry is computed here. Kept free of CGAL and httplib so that its users
// (cmd_view.cpp, the API test) stay light.
#ifndef LAPMESH_SRC_VIEWER_VIEWER_SERVER_H
#define LAPMESH_SRC_VIEWER_VIEWER_SERVER_H

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace lapmesh_viewer {

/// One mesh the page can pick, by id.
struct Mesh_source
{
  enum class Kind { file, icosphere, torus, bumpy_sphere };
  std::string id;     ///< [A-Za-z0-9_-]+, unique; the only thing the client names
  std::string label;  ///< shown in the page
  Kind kind = Kind::file;
  std::string path;   ///< for Kind::file
};

/// The meshes named on the command line (ids from their file names, made unique), then the
/// built-in ones: icosphere, torus, bumpy sphere, and `cgal_cow` (CGAL's cow.off) if that file
/// exists (pass "" to leave it out).
std::vector<Mesh_source> default_mesh_sources(const std::vector<std::string>& paths, const std::string& cgal_cow);

struct Server_options
{
  std::string host = "127.0.0.1";
  int port = 0;                          ///< 0: a free port
  std::string assets_dir;                ///< the built page (index.html, assets/); "" serves a notice
  std::size_t max_body_bytes = 64 * 1024;  ///< larger request bodies get 413
  long long max_vertices = 5'000'000;    ///< file meshes above this are refused at load
  int max_k = 2000;                      ///< reconstruction: 1 <= k <= min(n, max_k)
  int max_iterations = 10000;            ///< smoothing: 1 <= iterations <= max_iterations
  std::size_t cache_bytes = std::size_t(512) << 20;  ///< eigenbases kept (least recently used out)

  // Connections (doc/viewer.md, "Limits"): each has its own thread, within these bounds.
  int max_connections = 256;             ///< above: the longest-stalled connection is closed, else 503
  int max_connections_per_address = 64;  ///< the same per client address
  int request_timeout_ms = 10000;        ///< a request (head and body) must arrive within this
  int io_timeout_ms = 5000;              ///< the longest wait for the socket to be readable/writable
  int keep_alive_ms = 5000;              ///< an idle connection is closed after this
  std::size_t max_header_bytes = 16 * 1024;  ///< request line and header fields together
};

class Server
{
public:
  /// Loads nothing yet: a mesh is loaded or generated when it is first used.
  Server(std::vector<Mesh_source> meshes, Server_options options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Loads (or generates) every mesh now; throws std::runtime_error("path: problem") on the
  /// first that fails. `lapmesh view` calls it so that a bad file fails at start-up.
  void preload();

  /// Binds host:port; returns the port (the chosen one when options.port == 0). Throws
  /// std::runtime_error("cannot bind to HOST:PORT: reason") if the address cannot be bound,
  /// e.g. when another server listens there (the socket is not shared with it).
  int bind();
  /// Serves until stop() (blocking). bind() first.
  void listen();
  /// bind() and serve on a background thread; returns the port.
  int start();
  /// Stops listening, closes the connections, asks running operations to cancel and joins
  /// every thread it started.
  void stop();

private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

} // namespace lapmesh_viewer

#endif
