// lapmesh view [MESH ...]: the interactive viewer, a local web application (doc/viewer.md).
#include "cli_common.h"

#include "viewer/viewer_server.h"

#include <filesystem>
#include <iostream>
#include <memory>

namespace lapmesh_cli {
namespace {

struct View_options
{
  std::vector<std::string> meshes;
  std::string host = "127.0.0.1", assets;
  int port = 0;
  int cache_mb = 512;
};

/// The built page: --assets, else share/lapmesh/viewer next to the executable's bin/ (the
/// installed layout, mirrored in the build tree), else the build tree it was compiled in.
std::string find_assets(const std::string& given)
{
  namespace fs = std::filesystem;
  std::error_code ec;
  if(!given.empty()) {
    if(!fs::is_regular_file(fs::path(given) / "index.html", ec))
      throw Failure(given + ": --assets: no index.html in this directory");
    return given;
  }
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if(!ec) {
    const fs::path dir = exe.parent_path().parent_path() / "share" / "lapmesh" / "viewer";
    if(fs::is_regular_file(dir / "index.html", ec)) return dir.string();
  }
#ifdef LAPMESH_VIEWER_BUILD_ASSETS
  if(fs::is_regular_file(fs::path(LAPMESH_VIEWER_BUILD_ASSETS) / "index.html", ec)) return LAPMESH_VIEWER_BUILD_ASSETS;
#endif
  return "";
}

void run(const View_options& o)
{
  if(o.port < 0 || o.port > 65535) throw Failure("--port must be in [0, 65535]");
  lapmesh_viewer::Server_options so;
  so.host = o.host;
  so.port = o.port;
  so.assets_dir = find_assets(o.assets);
  if(o.cache_mb < 0 || o.cache_mb > 1 << 20) throw Failure("--cache-mb must be in [0, 1048576]");
  so.cache_bytes = std::size_t(o.cache_mb) << 20;
  std::string cow;
#ifdef LAPMESH_CGAL_COW
  cow = LAPMESH_CGAL_COW;
#endif
  lapmesh_viewer::Server server(lapmesh_viewer::default_mesh_sources(o.meshes, cow), so);
  try {
    server.preload();
  } catch(const std::exception& e) {
    throw Failure(e.what());
  }
  int port = 0;
  try {
    port = server.bind();
  } catch(const std::exception& e) {
    throw Failure(std::string("view: ") + e.what());
  }
  const bool loopback = o.host == "127.0.0.1" || o.host == "localhost" || o.host == "::1";
  if(!loopback)
    std::cerr << "lapmesh view: warning: listening on " << o.host
              << ", not loopback: anyone who can reach this address can use the viewer (there is no authentication)\n";
  if(so.assets_dir.empty())
    std::cerr << "lapmesh view: warning: the page's files were not found (build the target lapmesh_viewer_web or "
                 "pass --assets DIR); only the API is served\n";
  const std::string shown_host = o.host.find(':') != std::string::npos ? "[" + o.host + "]" : o.host;
  std::cout << "lapmesh view: http://" << shown_host << ":" << port << "/" << std::endl;
  std::cerr << "(from another machine: ssh -L " << port << ":localhost:" << port
            << " THIS_HOST, then open http://localhost:" << port << "/ ; Ctrl-C stops the server)" << std::endl;
  server.listen();
}

} // namespace

void register_view(CLI::App& app)
{
  auto o = std::make_shared<View_options>();
  CLI::App* cmd = app.add_subcommand("view", "interactive viewer in the browser (a local web server)");
  cmd->footer("Serves a page on http://127.0.0.1:PORT/ where the meshes given here and built-in ones (icosphere,\n"
              "torus, bumpy sphere, CGAL's cow when found) can be coloured by curvature, reconstructed,\n"
              "smoothed and noised. The server binds to loopback only unless --host is given. On a remote\n"
              "machine, forward the port: ssh -L PORT:localhost:PORT HOST. See doc/viewer.md.\n");
  cmd->add_option("MESH", o->meshes, "meshes to offer (.off, .obj, .ply, .stl)");
  cmd->add_option("--port", o->port, "TCP port (0: a free one)")->capture_default_str();
  cmd->add_option("--host", o->host, "address to bind (default loopback; anything else is reachable by others)")
    ->capture_default_str();
  cmd->add_option("--cache-mb", o->cache_mb, "memory for eigenbases kept between reconstructions, in MiB")
    ->capture_default_str();
  cmd->add_option("--assets", o->assets, "directory of the built page (default: found next to the executable)");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
