// The HTTP server of `lapmesh view` (API reference: doc/viewer.md): the per-mesh state, the
// operations and the routes.
//
// A front end of the operations layer (src/operations), as the command line is: each
// operation reads its parameters (request_params.h), calls lapmesh_ops and encodes the answer
// (JSON, or a binary frame: frames.h). One state per mesh, guarded by its own lock: a second
// operation on a busy mesh gets 409 instead of waiting. The socket and the connections:
// transport.h.
#include "viewer_server.h"

// The library's headers first: the socket headers (through transport.h) define macros such as
// _res that Eigen's sparse module uses as a name.
#include <operations/operations.h>

#include <lapmesh/colormap.h>
#include <lapmesh/errors.h>
#include <lapmesh/io.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include "frames.h"
#include "request_params.h"
#include "transport.h"

#include <httplib.h>
#include <nlohmann/json.hpp>

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

using Mesh = lapmesh_ops::Mesh;
using json = nlohmann::json;
namespace fs = std::filesystem;

/// Thrown from a progress callback when the client asked to cancel.
struct Cancelled
{};

double ms_since(Clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

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
  std::vector<std::string> notes;  // what the reader found and kept (zero-area faces, ...)
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

std::string sanitize_id(const std::string& s)
{
  std::string id;
  for(char c : s) id += (std::isalnum((unsigned char)c) || c == '_' || c == '-') ? c : '-';
  if(id.empty()) id = "mesh";
  return id.substr(0, 64);
}

std::vector<double> to_vector(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }

const std::vector<std::string> quantity_names = {"mean", "gaussian", "k1", "k2", "displacement"};

// The viewer's bounds on the work of one request, beyond the server options.
constexpr double max_lambda = 1e12;            // on the time step as given
constexpr long long max_seed = 4294967295LL;   // the noise seed (2^32 - 1, as documented)

/// The viewer's spelling of a setting of the operations layer: its JSON parameter, which has
/// the settings field's name ("lambda", "lambda_unit", "k", "level", ...).
std::string spelling(const std::string& parameter) { return parameter; }

/// A suggestion in the viewer's spelling: lambda "auto".
std::string spelling(const lapmesh_ops::Suggestion& s) { return spelling(s.parameter) + " \"" + s.value + "\""; }

/// The one-line "warning" of an answer: each warning with its ways out, "(use A or B)".
std::string warning_text(const std::vector<lapmesh_ops::Warning>& warnings)
{
  std::string text;
  for(const auto& w : warnings) {
    text += (text.empty() ? "" : "; ") + w.message;
    for(std::size_t i = 0; i < w.suggestions.size(); ++i)
      text += (i == 0 ? " (use " : " or ") + spelling(w.suggestions[i]);
    if(!w.suggestions.empty()) text += ")";
  }
  return text;
}

/// The name table of `Enum` for /api/info: the default and every value with its description.
template <typename Enum>
json choices(Enum fallback)
{
  json values = json::array();
  for(const auto& entry : lapmesh::name_table<Enum>())
    values.push_back({{"name", entry.name}, {"description", entry.description}});
  return {{"default", lapmesh::to_string(fallback)}, {"values", values}};
}

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
  lapmesh_ops::Basis_cache bases;
  std::atomic<long long> last_geometry{0};  // geometry ids handed out

  json cache_stats()
  {
    const lapmesh_ops::Basis_cache::Stats st = bases.stats();
    return {{"bytes", st.bytes}, {"budget_bytes", st.budget_bytes}, {"entries", st.entries}};
  }

  Http_router http;
  Listener listener;  // the socket and the connections (transport.h)

  Impl(std::vector<Mesh_source> sources, Server_options o)
    : options(std::move(o)),
      bases(options.cache_bytes),
      listener(http,
               {options.request_timeout_ms, options.io_timeout_ms, options.keep_alive_ms, options.max_header_bytes,
                // the body as sent: chunk framing of reasonably sized chunks fits in the margin
                2 * options.max_body_bytes + 4096},
               options.max_connections, options.max_connections_per_address)
  {
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
    std::vector<std::string> notes;
    const Mesh_source& src = s.source;
    try {
      switch(src.kind) {
        case Mesh_source::Kind::file: {
          lapmesh_ops::Loaded_mesh loaded = lapmesh_ops::load_mesh(src.path);
          mesh = std::move(loaded.mesh);
          notes = std::move(loaded.notes);
          break;
        }
        case Mesh_source::Kind::icosphere: lapmesh::make_mesh(lapmesh::icosphere(4, 1.0), mesh); break;
        case Mesh_source::Kind::torus: lapmesh::make_mesh(lapmesh::torus(96, 48, 1.0, 0.4), mesh); break;
        case Mesh_source::Kind::bumpy_sphere: lapmesh::make_mesh(lapmesh::bumpy_sphere(5), mesh); break;
      }
    } catch(const std::exception& e) {
      throw Http_error(422, src.label + ": " + e.what());
    }
    if((long long)lapmesh_ops::vertex_count(mesh) > options.max_vertices)
      throw Http_error(422, src.label + ": " + std::to_string(lapmesh_ops::vertex_count(mesh)) + " vertices, more than the limit " +
                              std::to_string(options.max_vertices));
    s.original = mesh;
    s.current = std::move(mesh);
    s.notes = std::move(notes);
    s.triangles = lapmesh_ops::triangles(s.current);
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

  static lapmesh::Vertex_vectors positions(const Mesh_state& s) { return lapmesh_ops::positions(s.current); }

  /// After a change of the geometry: curvatures are stale, show the displacement from the input.
  void geometry_changed(Mesh_state& s, const std::string& what)
  {
    ++s.version;
    s.geometry = ++last_geometry;
    bases.forget(s.source.id, 0, s.geometry);  // the previous geometry is gone unless it was the loaded one
    s.scalars.clear();
    s.scalars["displacement"] = lapmesh_ops::displacement(s.original, s.current);
    s.scalar_info = {{"source", what}};
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

  /// The intrinsic Delaunay operator's mollification factor, as the command line's range.
  static double mollification(Params& p)
  {
    return p.number("mollification", lapmesh::default_mollification_factor, 0.0, 1.0);
  }

  json op_curvature(Mesh_state& s, Params& p)
  {
    lapmesh_ops::Curvature_settings settings;
    settings.laplacian = p.option("laplacian", settings.laplacian);
    settings.area = p.option("area", settings.area);
    settings.mollification = mollification(p);
    p.finish();
    s.set_stage("curvature");
    const lapmesh::Vertex_curvatures c = lapmesh_ops::curvature(s.current, settings);
    s.scalars.clear();
    s.scalars["mean"] = to_vector(c.mean);
    s.scalars["gaussian"] = to_vector(c.gaussian);
    s.scalars["k1"] = to_vector(c.k1);
    s.scalars["k2"] = to_vector(c.k2);
    const std::string lap = lapmesh::to_string(settings.laplacian), area = lapmesh::to_string(settings.area);
    s.scalar_info = {{"source", "curvature"}, {"laplacian", lap}, {"area", area}};
    return {{"laplacian", lap}, {"area", area}};
  }

  json op_reconstruct(Mesh_state& s, Params& p)
  {
    const long long n = (long long)lapmesh_ops::vertex_count(s.current);
    lapmesh_ops::Reconstruct_settings settings;
    settings.k = p.integer("k", std::nullopt, 1, std::min<long long>(n, options.max_k));
    settings.laplacian = p.option("laplacian", settings.laplacian);
    settings.area = p.option("area", settings.area);
    settings.mollification = mollification(p);
    p.finish();
    s.set_stage("eigenpairs");  // shown only while the basis is computed (a cached one is immediate)
    settings.progress = [&s](const lapmesh::Spectral_progress& pr) {
      s.done = pr.operations;
      s.set_stage(pr.stage);
      if(s.cancel) throw Cancelled{};
    };
    const lapmesh_ops::Reconstruction r = lapmesh_ops::reconstruct(s.current, settings, bases, {s.source.id, s.geometry});
    json out = {{"k", settings.k}, {"laplacian", lapmesh::to_string(settings.laplacian)},
                {"area", lapmesh::to_string(settings.area)}, {"basis_size", r.basis->size()},
                {"basis_cached", r.basis_from_cache}, {"eigenvalue_k_minus_1", r.eigenvalue_k_minus_1}};
    if(!r.warnings.empty()) out["warning"] = warning_text(r.warnings);
    lapmesh_ops::set_positions(s.current, r.positions);
    geometry_changed(s, "reconstruct");
    out["cache"] = cache_stats();
    return out;
  }

  json op_smooth(Mesh_state& s, Params& p)
  {
    lapmesh_ops::Smooth_settings settings;
    settings.scheme = p.option("scheme", settings.scheme);
    // "auto" or a number: its range is the operations layer's check (with the limits below).
    const json* lambda = p.raw("lambda");
    if(lambda && !(lambda->is_string() && *lambda == "auto")) {
      if(!lambda->is_number()) throw Http_error(400, "'lambda' must be a positive number or \"auto\"");
      settings.lambda.automatic = false;
      settings.lambda.value = lambda->get<double>();
    }
    settings.lambda.unit = p.option("lambda_unit", settings.lambda.unit);
    settings.iterations = p.integer("iterations", 1, 1, options.max_iterations);
    settings.laplacian = p.option("laplacian", settings.laplacian);
    settings.area = p.option("area", settings.area);
    settings.mollification = mollification(p);
    settings.fixed_operator = p.boolean("fixed_operator", false);
    settings.restore_volume = p.boolean("restore_volume", false);
    settings.restore_area = p.boolean("restore_area", false);
    settings.fix_boundary = p.boolean("fix_boundary", true);
    p.finish();
    const lapmesh_ops::Smoothing_limits limits{options.max_iterations, max_lambda};
    lapmesh_ops::check(settings, limits);  // before the mesh is copied or anything computed

    settings.progress = [&s](int done, int total) {
      s.done = done;
      s.total = total;
      if(s.cancel) throw Cancelled{};
    };
    s.total = settings.iterations;
    s.set_stage("smoothing");
    const lapmesh_ops::Smooth_result r = lapmesh_ops::smooth(s.current, settings, limits);
    const bool explicit_scheme = settings.scheme == lapmesh::Smoothing_scheme::explicit_euler;
    json out = {{"scheme", lapmesh::to_string(settings.scheme)}, {"lambda", r.lambda},
                {"iterations", r.report.iterations}, {"free_vertices", r.report.free_vertices},
                {"laplacian", lapmesh::to_string(settings.laplacian)}, {"area", lapmesh::to_string(settings.area)},
                {"fixed_operator", settings.fixed_operator}, {"restore_volume", settings.restore_volume},
                {"restore_area", settings.restore_area}, {"fix_boundary", settings.fix_boundary}};
    if(explicit_scheme) out["stability_bound"] = r.stability_bound;
    if(!r.warnings.empty()) out["warning"] = warning_text(r.warnings);
    geometry_changed(s, "smooth");
    return out;
  }

  json op_noise(Mesh_state& s, Params& p)
  {
    lapmesh_ops::Noise_settings settings;
    settings.level = p.number("level", 0.1, 0.0, 10.0);
    settings.seed = std::uint64_t(p.integer("seed", 0, 0, max_seed));
    settings.scale = p.option("scale", settings.scale);
    settings.direction = p.option("direction", settings.direction);
    p.finish();
    s.set_stage("noise");
    const double sigma = lapmesh_ops::add_noise(s.current, settings);
    geometry_changed(s, "noise");
    return {{"level", settings.level}, {"seed", settings.seed}, {"scale", lapmesh::to_string(settings.scale)},
            {"direction", lapmesh::to_string(settings.direction)}, {"sigma", sigma}};
  }

  // ---- reads ----

  json mesh_summary(Mesh_state& s)
  {
    json j = {{"id", s.source.id}, {"label", s.source.label},
              {"kind", s.source.kind == Mesh_source::Kind::file ? "file" : "builtin"}};
    if(s.loaded && s.lock.try_read()) {
      Busy_guard l(s.lock, false);
      j["vertices"] = lapmesh_ops::vertex_count(s.current);
      j["faces"] = num_faces(s.current);
      j["notes"] = s.notes;
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
    c.colormap = lapmesh::to_string(p.option("colormap", lapmesh::Colormap::jet));
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
    f.header()["notes"] = s.notes;
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
    } catch(const lapmesh::Parameter_error& e) {
      // A setting the operations layer refused, named as the request names it.
      std::string what = "'" + spelling(e.parameter()) + "' " + e.what();
      if(!e.suggested_value().empty())
        what += " (use " + spelling(lapmesh_ops::Suggestion{e.parameter(), e.suggested_value()}) + ")";
      send_error(res, 400, what);
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

  void stop()
  {
    listener.stop_accepting();
    for(auto& s : meshes) s->cancel = true;
    listener.close_connections();
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
                        {"cache", cache_stats()},
                        {"quantities", quantity_names},
                        {"colormaps", lapmesh::names<lapmesh::Colormap>()},
                        // The choices of the operations (the page's dropdowns), by parameter.
                        {"choices",
                         {{"laplacian", choices(lapmesh_ops::Curvature_settings{}.laplacian)},
                          {"area", choices(lapmesh_ops::Curvature_settings{}.area)},
                          {"scheme", choices(lapmesh_ops::Smooth_settings{}.scheme)},
                          {"lambda_unit", choices(lapmesh_ops::Time_step{}.unit)},
                          {"scale", choices(lapmesh_ops::Noise_settings{}.scale)},
                          {"direction", choices(lapmesh_ops::Noise_settings{}.direction)},
                          {"colormap", choices(lapmesh::Colormap::jet)}}}});
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
        out["vertices"] = lapmesh_ops::vertex_count(s.current);
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

int Server::bind() { return m->listener.bind(m->options.host, m->options.port); }

void Server::listen()
{
  if(!m->listener.bound()) bind();
  m->listener.accept_loop();
}

int Server::start()
{
  if(!m->listener.bound()) bind();
  return m->listener.start();
}

void Server::stop() { m->stop(); }

} // namespace lapmesh_viewer
