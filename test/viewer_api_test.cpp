// The HTTP API of `lapmesh view` (src/viewer/viewer_server.h), served in process on a free
// loopback port: every endpoint, the values it serves (bitwise equal to the library's), and
// hostile or malformed requests, after which the server must still answer.
#include "test_helpers.h"
#include "viewer_server.h"

#include <lapmesh/colormap.h>
#include <lapmesh/curvature.h>
#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/noise.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
using json = nlohmann::json;
namespace fs = std::filesystem;
namespace LP = lapmesh::parameters;

const std::string cow_path = std::string(LAPMESH_CGAL_MESHES) + "/cow.off";

/// A decoded binary frame: JSON header and raw buffers.
struct Frame
{
  json header;
  std::string data;

  template <typename T>
  std::vector<T> buffer(const std::string& name) const
  {
    const json& b = header.at("buffers").at(name);
    const std::size_t offset = b.at("offset"), count = b.at("count");
    std::vector<T> out(count);
    EXPECT_LE(offset + count * sizeof(T), data.size());
    std::memcpy(out.data(), data.data() + offset, count * sizeof(T));
    return out;
  }
};

Frame decode(const std::string& body)
{
  Frame f;
  EXPECT_GE(body.size(), 4u);
  std::uint32_t len = 0;
  for(int i = 0; i < 4; ++i) len |= std::uint32_t(std::uint8_t(body[std::size_t(i)])) << (8 * i);
  f.header = json::parse(body.substr(4, len));
  EXPECT_EQ((4 + len) % 8, 0u);
  f.data = body.substr(4 + len);
  return f;
}

Mesh load(const std::string& path)
{
  Mesh m;
  lapmesh::io::read_triangle_mesh(path, m);
  return m;
}

class ViewerApi : public ::testing::Test
{
protected:
  static void SetUpTestSuite()
  {
    // A directory of this process's own: another process runs this set-up at the same time, and
    // removing a shared one under its feet made its set-up fail (gtest then reports skipped tests).
    tmp = fs::path(lapmesh_test::scratch_dir());
    fs::remove_all(tmp);
    fs::create_directories(tmp / "assets" / "sub");
    std::ofstream(tmp / "assets" / "index.html") << "<!doctype html><title>test page</title>";
    std::ofstream(tmp / "assets" / "sub" / "app.js") << "console.log('app');";
    std::ofstream(tmp / "secret.txt") << "SECRET-CONTENT";
    lapmesh_viewer::Server_options o;
    o.assets_dir = (tmp / "assets").string();
    o.max_k = 200;
    server = new lapmesh_viewer::Server(lapmesh_viewer::default_mesh_sources({cow_path}, ""), o);
    port = server->start();
  }
  static void TearDownTestSuite()
  {
    delete server;
    server = nullptr;
    std::error_code ec;
    fs::remove_all(tmp, ec);
  }

  static httplib::Client client()
  {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(120, 0);
    return c;
  }
  static json post(const std::string& path, const json& body, int expected = 200)
  {
    auto r = client().Post(path.c_str(), body.dump(), "application/json");
    EXPECT_TRUE(r) << path;
    if(!r) return {};
    EXPECT_EQ(r->status, expected) << path << " " << body.dump() << " -> " << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
    return json::parse(r->body);
  }
  static httplib::Result get(const std::string& path)
  {
    auto r = client().Get(path.c_str());
    EXPECT_TRUE(r) << path;
    return r;
  }
  static json get_json(const std::string& path, int expected = 200)
  {
    auto r = get(path);
    if(!r) return {};
    EXPECT_EQ(r->status, expected) << path << " -> " << r->body;
    return json::parse(r->body);
  }
  static Frame get_frame(const std::string& path)
  {
    auto r = get(path);
    EXPECT_EQ(r->status, 200) << path << " -> " << r->body;
    return decode(r->body);
  }
  static std::vector<double> positions(const std::string& id)
  {
    return get_frame("/api/meshes/" + id + "/geometry").buffer<double>("positions");
  }
  /// The error of a refused request: 4xx JSON with a message, and the server still serves.
  static void expect_refused(httplib::Result r, int status, const std::string& needle = "")
  {
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, status) << r->body;
    const json j = json::parse(r->body);
    ASSERT_TRUE(j.contains("error")) << r->body;
    EXPECT_NE(j["error"].get<std::string>().find(needle), std::string::npos) << j["error"];
    EXPECT_EQ(r->body.find("SECRET"), std::string::npos);
    EXPECT_EQ(get_json("/api/info")["name"], "lapmesh view");
  }

  static fs::path tmp;
  static lapmesh_viewer::Server* server;
  static int port;
};
fs::path ViewerApi::tmp;
lapmesh_viewer::Server* ViewerApi::server = nullptr;
int ViewerApi::port = 0;

TEST(ViewerSources, IdsAreUniqueAndBuiltinsFollow)
{
  const auto s = lapmesh_viewer::default_mesh_sources({"a/cow.off", "b/cow.off", "x/my mesh.v2.ply"}, cow_path);
  std::vector<std::string> ids;
  for(const auto& m : s) ids.push_back(m.id);
  EXPECT_EQ(ids, (std::vector<std::string>{"cow", "cow-2", "my-mesh-v2", "icosphere", "torus", "bumpy-sphere", "cow-3"}));
  EXPECT_EQ(lapmesh_viewer::default_mesh_sources({}, "/no/such/cow.off").size(), 3u);
}

TEST_F(ViewerApi, InfoMeshesAndColormaps)
{
  const json info = get_json("/api/info");
  EXPECT_EQ(info["limits"]["max_k"], 200);
  // The page's dropdowns: the library's name tables, with the defaults of the operations.
  const auto names_of = [&](const char* key) {
    std::vector<std::string> out;
    for(const json& v : info["choices"][key]["values"]) {
      EXPECT_FALSE(v["description"].get<std::string>().empty()) << key;
      out.push_back(v["name"]);
    }
    return out;
  };
  EXPECT_EQ(names_of("laplacian"), lapmesh::names<lapmesh::Laplacian>());
  EXPECT_EQ(names_of("area"), lapmesh::names<lapmesh::Vertex_area>());
  EXPECT_EQ(names_of("scheme"), lapmesh::names<lapmesh::Smoothing_scheme>());
  EXPECT_EQ(names_of("lambda_unit"), lapmesh::names<lapmesh::Time_step_unit>());
  EXPECT_EQ(names_of("scale"), lapmesh::names<lapmesh::Noise_scale>());
  EXPECT_EQ(names_of("direction"), lapmesh::names<lapmesh::Noise_direction>());
  EXPECT_EQ(names_of("colormap"), lapmesh::names<lapmesh::Colormap>());
  EXPECT_EQ(info["choices"]["laplacian"]["default"], "cotangent");
  EXPECT_EQ(info["choices"]["area"]["default"], "barycentric");
  EXPECT_EQ(info["choices"]["scheme"]["default"], "implicit");
  EXPECT_EQ(info["choices"]["lambda_unit"]["default"], "absolute");
  EXPECT_EQ(info["choices"]["scale"]["default"], "mean-edge");
  EXPECT_EQ(info["choices"]["direction"]["default"], "isotropic");
  EXPECT_EQ(info["choices"]["colormap"]["default"], "jet");
  const json meshes = get_json("/api/meshes")["meshes"];
  ASSERT_EQ(meshes.size(), 4u);
  EXPECT_EQ(meshes[0]["id"], "cow");
  EXPECT_EQ(meshes[0]["kind"], "file");
  EXPECT_EQ(meshes[1]["id"], "icosphere");
  EXPECT_EQ(meshes[3]["id"], "bumpy-sphere");
  const json maps = get_json("/api/colormaps");
  EXPECT_EQ(maps["samples"], 256);
  for(const char* name : {"jet", "viridis", "coolwarm", "gray"}) {
    const auto& t = maps["maps"][name];
    ASSERT_EQ(t.size(), 768u);
    for(int i : {0, 77, 128, 255}) {
      const lapmesh::Rgb c = lapmesh::map_color(*lapmesh::parse_colormap(name), i / 255.0);
      EXPECT_EQ(t[3 * i], c.r);
      EXPECT_EQ(t[3 * i + 1], c.g);
      EXPECT_EQ(t[3 * i + 2], c.b);
    }
  }
}

TEST_F(ViewerApi, GeometryIsTheFileBitwise)
{
  post("/api/meshes/cow/reset", json::object());
  const Mesh cow = load(cow_path);
  const auto [P, tris] = lapmesh::io::mesh_arrays(cow);
  const Frame f = get_frame("/api/meshes/cow/geometry");
  EXPECT_EQ(f.header["vertices"], 2904);
  EXPECT_EQ(f.header["faces"], 5804);
  const auto pos = f.buffer<double>("positions");
  const auto idx = f.buffer<std::uint32_t>("indices");
  ASSERT_EQ(pos.size(), std::size_t(3 * P.rows()));
  ASSERT_EQ(idx.size(), 3 * tris.size());
  EXPECT_EQ(std::memcmp(pos.data(), P.data(), pos.size() * sizeof(double)), 0);
  for(std::size_t t = 0; t < tris.size(); ++t)
    for(int a = 0; a < 3; ++a) ASSERT_EQ(idx[3 * t + a], tris[t][a]);
}

TEST_F(ViewerApi, CurvatureValuesRangesAndColoursAreTheLibrarys)
{
  const Mesh cow = load(cow_path);
  post("/api/meshes/cow/reset", json::object());
  for(const char* lap : {"cotangent", "uniform"}) {
    for(const char* area : {"barycentric", "voronoi", "mixed"}) {
      if(std::string(area) == "voronoi") {
        // The cow has obtuse triangles: a non-positive Voronoi area, a library Mesh_error -> 422.
        expect_refused(client().Post("/api/meshes/cow/curvature", json{{"laplacian", lap}, {"area", area}}.dump(),
                                     "application/json"),
                       422, "non-positive voronoi area");
        continue;
      }
      const json r = post("/api/meshes/cow/curvature", {{"laplacian", lap}, {"area", area}});
      EXPECT_GE(r["elapsed_ms"].get<double>(), 0.0);
      const lapmesh::Vertex_curvatures c = lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(
        cow, LP::vertex_area(*lapmesh::parse_vertex_area(area), LP::laplacian(*lapmesh::parse_laplacian(lap))));
      const std::pair<const char*, const Eigen::VectorXd*> qs[] = {
        {"mean", &c.mean}, {"gaussian", &c.gaussian}, {"k1", &c.k1}, {"k2", &c.k2}};
      for(const auto& [q, expected] : qs) {
        const Frame f = get_frame(std::string("/api/meshes/cow/scalars?quantity=") + q + "&colormap=viridis");
        const auto values = f.buffer<double>("values");
        ASSERT_EQ(values.size(), std::size_t(expected->size()));
        EXPECT_EQ(std::memcmp(values.data(), expected->data(), values.size() * sizeof(double)), 0) << lap << area << q;
        const lapmesh::Value_range range = lapmesh::auto_range(values);
        EXPECT_EQ(f.header["range"][0].get<double>(), range.min);
        EXPECT_EQ(f.header["range"][1].get<double>(), range.max);
        EXPECT_EQ(f.header["data_range"][0].get<double>(), expected->minCoeff());
        EXPECT_EQ(f.header["data_range"][1].get<double>(), expected->maxCoeff());
      }
    }
  }
  // Range modes on the mean curvature (cotangent, mixed) and the colours of each.
  post("/api/meshes/cow/curvature", {{"area", "mixed"}});
  const lapmesh::Vertex_curvatures c =
    lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(cow, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const std::vector<double> H(c.mean.data(), c.mean.data() + c.mean.size());
  const std::pair<std::string, lapmesh::Value_range> modes[] = {
    {"range=auto", lapmesh::auto_range(H)},
    {"range=percentile&clip=1", lapmesh::auto_range(H, 1)},
    {"range=percentile", lapmesh::auto_range(H, 1)},
    {"range=symmetric&clip=2.5", lapmesh::symmetric_range(H, 2.5)},
    {"range=manual&min=-3&max=40", {-3, 40}}};
  for(const auto& [query, range] : modes) {
    for(const char* map : {"jet", "coolwarm", "gray"}) {
      const Frame f = get_frame("/api/meshes/cow/scalars?quantity=mean&colormap=" + std::string(map) + "&" + query);
      EXPECT_EQ(f.header["range"][0].get<double>(), range.min) << query;
      EXPECT_EQ(f.header["range"][1].get<double>(), range.max) << query;
      const auto rgb = f.buffer<std::uint8_t>("colors");
      const auto expected = lapmesh::colorize(H, *lapmesh::parse_colormap(map), range);
      ASSERT_EQ(rgb.size(), 3 * expected.size());
      for(std::size_t i = 0; i < expected.size(); i += 97) {
        EXPECT_EQ(rgb[3 * i], expected[i].r);
        EXPECT_EQ(rgb[3 * i + 1], expected[i].g);
        EXPECT_EQ(rgb[3 * i + 2], expected[i].b);
      }
    }
  }
  // Bad colouring requests.
  expect_refused(get("/api/meshes/cow/scalars?quantity=curl"), 400, "quantity");
  // Choice errors list exactly the named choices: no empty entry, colour maps from the library's table.
  expect_refused(get("/api/meshes/cow/scalars?quantity=curl"), 400, "one of mean, gaussian, k1, k2, displacement (got 'curl')");
  expect_refused(get("/api/meshes/cow/scalars?quantity=mean&colormap=rainbow"), 400,
                 "one of " + lapmesh::colormap_name_list() + " (got 'rainbow')");
  expect_refused(get("/api/meshes/cow/scalars?colormap=rainbow"), 400, "colormap");
  expect_refused(get("/api/meshes/cow/scalars?range=manual&min=2&max=1"), 400, "min");
  expect_refused(get("/api/meshes/cow/scalars?range=manual&min=abc&max=1"), 400, "min");
  expect_refused(get("/api/meshes/cow/scalars?range=percentile&clip=50"), 400, "clip");
  expect_refused(get("/api/meshes/cow/scalars?quantity=displacement"), 409, "displacement");
  expect_refused(get("/api/meshes/cow/scalars?min=1"), 400, "manual");
}

TEST_F(ViewerApi, VoronoiCurvatureOnTheIcosphere)
{
  post("/api/meshes/icosphere/reset", json::object());
  post("/api/meshes/icosphere/curvature", {{"laplacian", "cotangent"}, {"area", "voronoi"}});
  Mesh ico;
  lapmesh::make_mesh(lapmesh::icosphere(4, 1.0), ico);
  const auto c = lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(ico, LP::vertex_area(lapmesh::Vertex_area::voronoi));
  const auto values = get_frame("/api/meshes/icosphere/scalars?quantity=gaussian").buffer<double>("values");
  ASSERT_EQ(values.size(), std::size_t(c.gaussian.size()));
  EXPECT_EQ(std::memcmp(values.data(), c.gaussian.data(), values.size() * sizeof(double)), 0);
}

TEST_F(ViewerApi, SmoothingMovesVerticesAsTheLibraryAndResetRestores)
{
  post("/api/meshes/cow/reset", json::object());
  const auto before = positions("cow");
  const json r = post("/api/meshes/cow/smooth",
                      {{"scheme", "implicit"}, {"lambda", "auto"}, {"iterations", 2}, {"laplacian", "cotangent"}});
  EXPECT_EQ(r["iterations"], 2);
  EXPECT_EQ(r["scalars"], json::array({"displacement"}));
  const auto after = positions("cow");
  // The same call through the library.
  Mesh cow = load(cow_path);
  const double lambda = lapmesh::scale_free_time_step(cow, 1.0, LP::laplacian(lapmesh::Laplacian::cotangent));
  EXPECT_DOUBLE_EQ(r["lambda"].get<double>(), lambda);
  lapmesh::smooth_laplacian_implicit<CGAL::Parallel_if_available_tag>(
    cow, lambda, LP::laplacian(lapmesh::Laplacian::cotangent).number_of_iterations(2));
  const auto expected = lapmesh::io::mesh_arrays(cow).first;
  double moved = 0;
  for(std::size_t i = 0; i < after.size(); ++i) {
    moved = std::max(moved, std::abs(after[i] - before[i]));
    ASSERT_NEAR(after[i], expected.data()[i], 1e-9);
  }
  EXPECT_GT(moved, 1e-4);
  // The displacement served is |P - P0|.
  const auto d = get_frame("/api/meshes/cow/scalars?quantity=displacement").buffer<double>("values");
  ASSERT_EQ(d.size(), after.size() / 3);
  for(std::size_t i = 0; i < d.size(); i += 31)
    EXPECT_NEAR(d[i], std::hypot(after[3 * i] - before[3 * i], after[3 * i + 1] - before[3 * i + 1], after[3 * i + 2] - before[3 * i + 2]), 1e-15);

  // Explicit, uniform, fixed operator, a step above the stability bound: a warning.
  const json e = post("/api/meshes/cow/smooth", {{"scheme", "explicit"}, {"lambda", 0.9}, {"lambda_unit", "bound"},
                                                 {"iterations", 3}, {"laplacian", "uniform"}, {"fixed_operator", true}});
  EXPECT_GT(e["stability_bound"].get<double>(), 0);
  EXPECT_FALSE(e.contains("warning"));
  const json w = post("/api/meshes/cow/smooth", {{"scheme", "explicit"}, {"lambda", 5.0}, {"iterations", 1}, {"laplacian", "uniform"}});
  EXPECT_TRUE(w.contains("warning"));
  EXPECT_NE(w["warning"].get<std::string>().find("exceeds the explicit stability bound"), std::string::npos);
  EXPECT_NE(w["warning"].get<std::string>().find("(use lambda \"auto\" or lambda_unit \"bound\")"), std::string::npos)
    << w["warning"];
  post("/api/meshes/cow/smooth", {{"scheme", "conformal"}, {"lambda", 0.5}, {"lambda_unit", "edge2"}, {"iterations", 1}, {"area", "mixed"}});

  // The bound served for a small lambda is explicit_stability_bound() of the mesh, as the CLI
  // prints it, not the smoother's cheaper Gershgorin lower bound.
  post("/api/meshes/cow/reset", json::object());
  const json small = post("/api/meshes/cow/smooth", {{"scheme", "explicit"}, {"lambda", 1e-9}, {"iterations", 1}});
  const double bound = lapmesh::explicit_stability_bound(load(cow_path), LP::laplacian(lapmesh::Laplacian::cotangent));
  EXPECT_NEAR(small["stability_bound"].get<double>(), bound, 1e-9 * bound);
  EXPECT_FALSE(small.contains("warning"));

  // Area restoration: the smoothed cow keeps the surface area of the input.
  post("/api/meshes/cow/reset", json::object());
  const json a = post("/api/meshes/cow/smooth", {{"scheme", "implicit"}, {"lambda", 2.0}, {"lambda_unit", "edge2"},
                                                 {"iterations", 3}, {"restore_area", true}});
  EXPECT_EQ(a["restore_area"], true);
  Mesh restored = load(cow_path);
  const double area0 = CGAL::Polygon_mesh_processing::area(restored);
  const auto P_area = positions("cow");
  for(auto v : vertices(restored))
    restored.point(v) = lapmesh_test::Point(P_area[3 * v.idx()], P_area[3 * v.idx() + 1], P_area[3 * v.idx() + 2]);
  EXPECT_NEAR(CGAL::Polygon_mesh_processing::area(restored), area0, 1e-12 * area0);
  EXPECT_NE(P_area, before);
  expect_refused(client().Post("/api/meshes/cow/smooth", json{{"restore_area", true}, {"restore_volume", true}}.dump(),
                               "application/json"),
                 400, "not both");

  post("/api/meshes/cow/reset", json::object());
  EXPECT_EQ(positions("cow"), before);

  // Bad smoothing parameters.
  for(const json& bad : {json{{"iterations", 0}}, json{{"iterations", 10001}}, json{{"iterations", 2.5}},
                         json{{"lambda", -1}}, json{{"lambda", 0}}, json{{"lambda", "fast"}}, json{{"lambda", 1e13}},
                         json{{"scheme", "magic"}}, json{{"laplacian", "fancy"}}, json{{"area", 3}},
                         json{{"fixed_operator", "yes"}}, json{{"lambda_unit", "furlong"}}, json{{"lamda", 1}},
                         json{{"restore_area", 1}}, json{{"fix_boundary", "no"}}})
    expect_refused(client().Post("/api/meshes/cow/smooth", bad.dump(), "application/json"), 400);
  // The operations layer's check, named as the request names the parameter.
  expect_refused(client().Post("/api/meshes/cow/smooth", json{{"lambda", 1e13}}.dump(), "application/json"), 400,
                 "'lambda' must be a positive finite time step");
  EXPECT_EQ(positions("cow"), before);
}

TEST_F(ViewerApi, ReconstructionIsTheLibrarysAndKIsChecked)
{
  post("/api/meshes/icosphere/reset", json::object());
  const json r = post("/api/meshes/icosphere/reconstruct", {{"k", 16}, {"laplacian", "cotangent"}, {"area", "mixed"}});
  EXPECT_EQ(r["k"], 16);
  EXPECT_FALSE(r["basis_cached"].get<bool>());
  Mesh ico;
  lapmesh::make_mesh(lapmesh::icosphere(4, 1.0), ico);
  const auto P = lapmesh::io::mesh_arrays(ico).first;
  const auto basis = lapmesh::Spectral_basis::compute(ico, 16, LP::vertex_area(lapmesh::Vertex_area::mixed));
  const Eigen::MatrixXd R = basis.reconstruct(P, 16);
  const auto got = positions("icosphere");
  for(Eigen::Index i = 0; i < R.rows(); ++i)
    for(int a = 0; a < 3; ++a) ASSERT_NEAR(got[std::size_t(3 * i + a)], R(i, a), 1e-8);
  // A second k on the geometry as loaded reuses that basis (no solve): the library's basis of
  // 16 pairs truncated to 9.
  post("/api/meshes/icosphere/reset", json::object());
  const json again = post("/api/meshes/icosphere/reconstruct", {{"k", 9}, {"laplacian", "cotangent"}, {"area", "mixed"}});
  EXPECT_TRUE(again["basis_cached"].get<bool>()) << again;
  EXPECT_EQ(again["basis_size"], basis.size());
  const Eigen::MatrixXd R9 = basis.reconstruct(P, 9);
  const auto got9 = positions("icosphere");
  for(Eigen::Index i = 0; i < R9.rows(); ++i)
    for(int a = 0; a < 3; ++a) ASSERT_NEAR(got9[std::size_t(3 * i + a)], R9(i, a), 1e-8);
  EXPECT_GT(again["cache"]["bytes"].get<std::size_t>(), std::size_t(8 * 2562 * 16));
  EXPECT_EQ(get_json("/api/info")["cache"], again["cache"]);
  // l = 0..3 on a sphere: 16 pairs close the eigenspace; k = 2 splits l = 1 (a warning).
  EXPECT_FALSE(r.contains("warning"));
  post("/api/meshes/icosphere/reset", json::object());
  const json w = post("/api/meshes/icosphere/reconstruct", {{"k", 2}});
  EXPECT_TRUE(w.contains("warning"));

  const std::string n = std::to_string(2562);
  for(const json& bad : {json{{"k", 0}}, json{{"k", -3}}, json{{"k", 201}}, json{{"k", 2562}}, json{{"k", 2.5}},
                         json{{"k", "ten"}}, json::object(), json{{"k", 5}, {"area", "random"}}})
    expect_refused(client().Post("/api/meshes/icosphere/reconstruct", bad.dump(), "application/json"), 400, "");
  auto r0 = client().Post("/api/meshes/icosphere/reconstruct", R"({"k": 0})", "application/json");
  expect_refused(std::move(r0), 400, "'k' must be an integer in [1, 200]");
}

TEST_F(ViewerApi, NoiseIsSeededAsTheLibrary)
{
  post("/api/meshes/torus/reset", json::object());
  const json r = post("/api/meshes/torus/noise", {{"level", 0.2}, {"seed", 7}, {"scale", "mean-edge"}, {"direction", "normal"}});
  Mesh torus;
  lapmesh::make_mesh(lapmesh::torus(96, 48, 1.0, 0.4), torus);
  const double sigma = lapmesh::add_noise(
    torus, 0.2, LP::noise_direction(lapmesh::Noise_direction::normal, CGAL::parameters::random_seed(7u)));
  EXPECT_EQ(r["sigma"].get<double>(), sigma);
  const auto expected = lapmesh::io::mesh_arrays(torus).first;
  const auto got = positions("torus");
  EXPECT_EQ(std::memcmp(got.data(), expected.data(), got.size() * sizeof(double)), 0);
  post("/api/meshes/torus/noise", {{"level", 0.01}, {"seed", 4294967295LL}, {"scale", "bbox"}, {"direction", "isotropic"}});
  for(const json& bad : {json{{"level", -0.1}}, json{{"level", 11}}, json{{"seed", -1}}, json{{"seed", 4294967296LL}},
                         json{{"scale", "huge"}}, json{{"direction", "up"}}, json{{"level", "lots"}}})
    expect_refused(client().Post("/api/meshes/torus/noise", bad.dump(), "application/json"), 400);
}

TEST_F(ViewerApi, DownloadIsWhatWriteMeshWrites)
{
  post("/api/meshes/cow/reset", json::object());
  post("/api/meshes/cow/curvature", {{"area", "mixed"}});
  auto r = get("/api/meshes/cow/download?format=ply&quantity=gaussian&colormap=coolwarm&range=symmetric");
  ASSERT_EQ(r->status, 200);
  EXPECT_NE(r->get_header_value("Content-Disposition").find("cow_gaussian.ply"), std::string::npos);
  const Mesh cow = load(cow_path);
  const auto c = lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(cow, LP::vertex_area(lapmesh::Vertex_area::mixed));
  auto vec = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
  lapmesh::io::Vertex_attributes a;
  a.scalars = {{"gaussian", vec(c.gaussian)}, {"k1", vec(c.k1)}, {"k2", vec(c.k2)}, {"mean", vec(c.mean)}};
  a.colors = lapmesh::colorize(vec(c.gaussian), lapmesh::Colormap::coolwarm, lapmesh::symmetric_range(vec(c.gaussian)));
  const auto [P, tris] = lapmesh::io::mesh_arrays(cow);
  std::ostringstream expected;
  lapmesh::io::write_mesh(expected, "ply", P, tris, a);
  EXPECT_EQ(r->body, expected.str());
  auto off = get("/api/meshes/cow/download?format=off");
  ASSERT_EQ(off->status, 200);
  EXPECT_EQ(off->body.rfind("COFF\n2904 5804 0\n", 0), 0u);
  expect_refused(get("/api/meshes/cow/download?format=exe"), 400, "format");
  expect_refused(get("/api/meshes/cow/download?format=ply&path=/etc/passwd"), 400, "unknown parameter");
}

TEST_F(ViewerApi, HostileRequestsAreRefusedAndTheServerKeepsServing)
{
  // The page's own files, and nothing else of the file system.
  auto page = get("/");
  ASSERT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("test page"), std::string::npos);
  EXPECT_EQ(get("/sub/app.js")->body, "console.log('app');");
  for(const char* path : {"/../secret.txt", "/%2e%2e/secret.txt", "/sub/../../secret.txt", "/sub/%2e%2e/%2e%2e/secret.txt",
                          "/..%2fsecret.txt", "//etc/passwd", "/api/meshes/..%2f..%2fsecret/geometry",
                          "/api/meshes/../../secret.txt", "/sub/", "/nonexistent.js"}) {
    auto r = get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_GE(r->status, 400) << path;
    EXPECT_LT(r->status, 500) << path;
    EXPECT_EQ(r->body.find("SECRET"), std::string::npos) << path;
    EXPECT_EQ(r->body.find("root:"), std::string::npos) << path;
  }
  // Unknown ids, operations and resources.
  expect_refused(get("/api/meshes/nope/geometry"), 404, "unknown mesh id");
  expect_refused(client().Post("/api/meshes/nope/curvature", "{}", "application/json"), 404, "unknown mesh id");
  expect_refused(client().Post("/api/meshes/cow/format-disk", "{}", "application/json"), 404, "unknown operation");
  expect_refused(get("/api/meshes/cow/passwords"), 404, "unknown resource");
  expect_refused(get("/api/nothing"), 404, "not found");
  // Malformed and oversized bodies.
  expect_refused(client().Post("/api/meshes/cow/curvature", "{not json", "application/json"), 400, "JSON");
  expect_refused(client().Post("/api/meshes/cow/curvature", "[1, 2]", "application/json"), 400, "object");
  expect_refused(client().Post("/api/meshes/cow/curvature", R"({"laplacian": "cotangent", "path": "/etc/passwd"})",
                               "application/json"),
                 400, "unknown parameter 'path'");
  const std::string huge = "{\"k\": \"" + std::string(1 << 20, 'x') + "\"}";
  auto r = client().Post("/api/meshes/cow/reconstruct", huge, "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 413);
  EXPECT_EQ(get_json("/api/info")["name"], "lapmesh view");
  expect_refused(get("/api/meshes/cow/geometry?x=1"), 400, "unknown parameter");
}

TEST_F(ViewerApi, LongOperationsReportProgressDoNotBlockAndCanBeCancelled)
{
  post("/api/meshes/bumpy-sphere/reset", json::object());
  const auto before = positions("bumpy-sphere");
  EXPECT_FALSE(get_json("/api/meshes/bumpy-sphere/progress")["running"].get<bool>());
  auto job = std::async(std::launch::async, [] {
    return client().Post("/api/meshes/bumpy-sphere/smooth",
                         json{{"scheme", "explicit"}, {"lambda", "auto"}, {"iterations", 10000}}.dump(), "application/json");
  });
  json p;
  for(int i = 0; i < 2000; ++i) {
    p = get_json("/api/meshes/bumpy-sphere/progress");
    if(p["running"].get<bool>() && p["done"].get<long long>() > 2) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(p["running"].get<bool>()) << p;
  EXPECT_EQ(p["operation"], "smooth");
  EXPECT_EQ(p["total"], 10000);
  // Other meshes and the list answer at once; the busy mesh answers 409.
  const auto t0 = std::chrono::steady_clock::now();
  post("/api/meshes/icosphere/reset", json::object());
  post("/api/meshes/icosphere/curvature", json::object());
  get_json("/api/meshes");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
  expect_refused(client().Post("/api/meshes/bumpy-sphere/noise", "{}", "application/json"), 409, "busy");
  expect_refused(get("/api/meshes/bumpy-sphere/geometry"), 409, "busy");
  EXPECT_TRUE(post("/api/meshes/bumpy-sphere/cancel", json::object())["cancelling"].get<bool>());
  auto res = job.get();
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 409);
  EXPECT_EQ(json::parse(res->body)["error"], "cancelled");
  EXPECT_EQ(positions("bumpy-sphere"), before);  // a cancelled run changes nothing
  EXPECT_FALSE(post("/api/meshes/bumpy-sphere/cancel", json::object())["cancelling"].get<bool>());
}

} // namespace

// A file with defects the reader keeps: the viewer serves its notes (as the command line prints
// them) and takes the intrinsic Delaunay operator's mollification factor.
TEST(ViewerDefects, NotesAreServedAndMollificationReachesTheOperator)
{
  const fs::path dir = lapmesh_test::scratch_dir();
  lapmesh::Triangle_soup soup = lapmesh::icosphere(2);
  const auto first = soup.triangles.front();
  soup.points[std::size_t(first[1])] = soup.points[std::size_t(first[0])];  // collapses an edge: zero-area faces
  soup.points.push_back({5.0, 5.0, 5.0});                                   // a vertex in no face
  const fs::path path = dir / "defects.off";
  {
    std::ofstream out(path);
    out.precision(17);
    out << "OFF\n" << soup.points.size() << ' ' << soup.triangles.size() << " 0\n";
    for(const auto& p : soup.points) out << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
    for(const auto& t : soup.triangles) out << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  }
  lapmesh_viewer::Server_options o;
  o.assets_dir = dir.string();
  lapmesh_viewer::Server server(lapmesh_viewer::default_mesh_sources({path.string()}, ""), o);
  const int port = server.start();
  httplib::Client c("127.0.0.1", port);
  c.set_read_timeout(120, 0);

  const auto geometry = c.Get("/api/meshes/defects/geometry");
  ASSERT_TRUE(geometry);
  ASSERT_EQ(geometry->status, 200) << geometry->body;
  const json notes = decode(geometry->body).header["notes"];
  const std::string all = notes.dump();
  EXPECT_NE(all.find("zero-area face(s)"), std::string::npos) << all;
  EXPECT_NE(all.find("1 vertex(es) in no face"), std::string::npos) << all;
  const auto meshes = c.Get("/api/meshes");
  ASSERT_TRUE(meshes);
  EXPECT_EQ(json::parse(meshes->body)["meshes"][0]["notes"], notes);

  auto mean_curvature = [&](double mollification) {
    const auto r = c.Post("/api/meshes/defects/curvature",
                          json{{"laplacian", "intrinsic-delaunay"}, {"mollification", mollification}}.dump(),
                          "application/json");
    EXPECT_TRUE(r && r->status == 200) << (r ? r->body : "no answer");
    const auto s = c.Get("/api/meshes/defects/scalars?quantity=mean");
    return decode(s->body).buffer<double>("values");
  };
  const std::vector<double> weak = mean_curvature(1e-5), strong = mean_curvature(0.01);
  ASSERT_EQ(weak.size(), soup.points.size());
  EXPECT_TRUE(std::isnan(weak.back()));  // the vertex in no face
  double largest_change = 0;
  for(std::size_t i = 0; i + 1 < weak.size(); ++i) {
    ASSERT_TRUE(std::isfinite(weak[i]) && std::isfinite(strong[i])) << i;
    largest_change = std::max(largest_change, std::abs(weak[i] - strong[i]));
  }
  EXPECT_GT(largest_change, 1e-6) << "the factor must change the operator";
  // The basis cache tells intrinsic Delaunay operators of different mollification apart.
  auto reconstruct = [&](double mollification) {
    EXPECT_TRUE(c.Post("/api/meshes/defects/reset", "{}", "application/json"));
    const auto r = c.Post("/api/meshes/defects/reconstruct",
                          json{{"k", 10}, {"laplacian", "intrinsic-delaunay"}, {"mollification", mollification}}.dump(),
                          "application/json");
    EXPECT_TRUE(r && r->status == 200) << (r ? r->body : "no answer");
    return r ? json::parse(r->body)["basis_cached"].get<bool>() : false;
  };
  EXPECT_FALSE(reconstruct(1e-5));
  EXPECT_TRUE(reconstruct(1e-5));
  EXPECT_FALSE(reconstruct(0.01));
  EXPECT_TRUE(reconstruct(0.01));

  const auto refused = c.Post("/api/meshes/defects/curvature",
                              json{{"laplacian", "intrinsic-delaunay"}, {"mollification", 2}}.dump(), "application/json");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 400);
  EXPECT_NE(refused->body.find("mollification"), std::string::npos) << refused->body;
}
