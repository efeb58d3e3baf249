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

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
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
    const json* v = take(key);
    if(!v) return fallback;
    if(!v->is_string()) throw Http_error(400, "'" + key + "' must be a string");
    const std::string s = v->get<std::string>();
    std::string list;
    for(const char* a : allowed) {
      if(s == a) return s;
      list += std::string(list.empty() ? "" : ", ") + a;
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

// ---- per-mesh state --------------------------------------------------------------------

struct Mesh_state
{
  explicit Mesh_state(Mesh_source s) : source(std::move(s)) {}
  const Mesh_source source;

  std::mutex mutex;  // guards everything up to the progress block
  bool loaded = false;
  Mesh original, current;
  std::vector<std::array<std::size_t, 3>> triangles;
  long long version = 0;  // bumped at every change of the geometry
  std::map<std::string, std::vector<double>> scalars;
  json scalar_info = json::object();  // what produced the scalars
  std::optional<lapmesh::Spectral_basis> basis;
  long long basis_version = -1;

  // Progress of the running operation: read without the mutex.
  std::atomic<bool> running{false}, cancel{false};
  std::atomic<long long> done{0}, total{0};
  std::atomic<long long> started_ns{0};
  std::mutex progress_mutex;  // guards operation, stage
  std::string operation, stage;

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
  Running(Mesh_state& s, const std::string& op) : m_s(s)
  {
    {
      std::lock_guard<std::mutex> g(s.progress_mutex);
      s.operation = op;
      s.stage = "";
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
  httplib::Server http;
  std::thread thread;
  bool bound = false;

  Impl(std::vector<Mesh_source> sources, Server_options o) : options(std::move(o))
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

  void load(Mesh_state& s)  // with s.mutex held
  {
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
    s.loaded = true;
    s.version = 1;
  }

  /// The mesh's lock, taken without waiting: a busy mesh answers 409.
  std::unique_lock<std::mutex> lock(Mesh_state& s)
  {
    std::unique_lock<std::mutex> l(s.mutex, std::try_to_lock);
    if(!l)
      throw Http_error(409, "mesh '" + s.source.id + "' is busy with another operation (GET .../progress, POST .../cancel)");
    load(s);
    return l;
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
    bool cached = s.basis && s.basis_version == s.version && s.basis->laplacian() == L && s.basis->vertex_area() == A &&
                  s.basis->size() >= k;
    if(!cached) {
      s.basis.reset();
      s.set_stage("eigenpairs");
      auto progress = [&s](const lapmesh::Spectral_progress& pr) {
        s.done = pr.operations;
        s.set_stage(pr.stage);
        if(s.cancel) throw Cancelled{};
      };
      s.basis = lapmesh::Spectral_basis::compute<CGAL::Parallel_if_available_tag>(
        s.current, k, LP::spectral_progress(progress, LP::vertex_area(A, LP::laplacian(L))));
      s.basis_version = s.version;
    }
    const Eigen::MatrixXd R = s.basis->reconstruct(positions(s), k);
    const bool split = s.basis->splits_eigenspace(k);
    json out = {{"k", k}, {"laplacian", lap}, {"area", area}, {"basis_size", s.basis->size()}, {"basis_cached", cached},
                {"eigenvalue_k_minus_1", s.basis->eigenvalues()[k - 1]}};
    if(split)
      out["warning"] = "lambda_" + std::to_string(k - 1) + " and lambda_" + std::to_string(k) +
                       " agree to 1e-8 relative: the reconstruction depends on the basis chosen inside that eigenspace";
    set_positions(s, R);
    geometry_changed(s, "reconstruct");
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
    const double lambda = lambda_auto ? lapmesh::automatic_time_step(s.current, sch, base)
                                      : lapmesh::time_step(s.current, lambda_value, *lapmesh::parse_time_step_unit(unit), base);
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
    if(sch == lapmesh::Smoothing_scheme::explicit_euler) out["stability_bound"] = report.stability_bound;
    if(report.above_stability_bound)
      out["warning"] = "lambda " + Params::fmt(lambda) + " exceeds the explicit stability bound " +
                       Params::fmt(report.stability_bound) + " (use lambda \"auto\" or lambda_unit \"bound\")";
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
    std::unique_lock<std::mutex> l(s.mutex, std::try_to_lock);
    if(l && s.loaded) {
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
    c.quantity = p.choice("quantity", fallback, {"mean", "gaussian", "k1", "k2", "displacement", ""});
    c.colormap = p.choice("colormap", "jet", {"jet", "viridis", "coolwarm", "diverging", "gray"});
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
    }
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

  void routes()
  {
    http.set_payload_max_length(options.max_body_bytes);
    http.set_read_timeout(10, 0);
    http.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
      if(!res.body.empty()) return;
      const std::string what = res.status == 404   ? "not found: " + req.path.substr(0, 80)
                               : res.status == 413 ? "request body too large"
                               : res.status == 400 ? "bad request"
                                                   : "HTTP " + std::to_string(res.status);
      send_error(res, res.status, what);
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
                          {"max_vertices", options.max_vertices}}},
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
        for(const char* name : {"jet", "viridis", "coolwarm", "gray"}) {
          json samples = json::array();
          for(int i = 0; i < 256; ++i) {
            const lapmesh::Rgb c = lapmesh::map_color(*lapmesh::parse_colormap(name), i / 255.0);
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
        auto l = lock(s);
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
        if(action == "cancel") {
          p.finish();
          const bool running = s.running;
          if(running) s.cancel = true;
          return send_json(res, {{"cancelling", running}});
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
        auto l = lock(s);
        Running running(s, action);
        const auto t0 = Clock::now();
        json out = (this->*(op->second))(s, p);
        out["elapsed_ms"] = ms_since(t0);
        out["operation"] = action;
        out["version"] = s.version;
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
    std::lock_guard<std::mutex> l(s->mutex);
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
  int port = m->options.port;
  if(port == 0) {
    port = m->http.bind_to_any_port(m->options.host);
    if(port < 0) throw std::runtime_error("cannot bind to " + m->options.host);
  } else if(!m->http.bind_to_port(m->options.host, port)) {
    throw std::runtime_error("cannot bind to " + m->options.host + ":" + std::to_string(port) +
                             " (in use? try another --port, or none for a free one)");
  }
  m->bound = true;
  return port;
}

void Server::listen()
{
  if(!m->bound) bind();
  m->http.listen_after_bind();
}

int Server::start()
{
  const int port = bind();
  m->thread = std::thread([this] { m->http.listen_after_bind(); });
  for(int i = 0; i < 5000 && !m->http.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return port;
}

void Server::stop()
{
  if(m->http.is_running()) m->http.stop();
  if(m->thread.joinable()) m->thread.join();
}

} // namespace lapmesh_viewer
