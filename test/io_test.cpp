// Mesh input/output: formats, exact round trips, vertex order, repairs and every bad input.
#include "test_helpers.h"

#include <lapmesh/curvature.h>
#include <lapmesh/io.h>

#include <CGAL/Polygon_mesh_processing/measure.h>

#include <ctime>
#include <limits>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <cstring>

#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>

using namespace lapmesh_test;
namespace fs = std::filesystem;

namespace {

std::string tmp_path(const std::string& name) { return lapmesh_test::scratch_dir() + "/io_" + name; }

std::string write_text(const std::string& name, const std::string& text)
{
  const std::string path = tmp_path(name);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// The message of the exception read_triangle_mesh throws for `text` saved as `name`.
std::string read_error(const std::string& name, const std::string& text)
{
  Mesh m;
  try {
    lapmesh::io::read_triangle_mesh(write_text(name, text), m);
  } catch(const std::exception& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Runs the CLI with `args` (shell words); returns its exit status and its stderr.
std::pair<int, std::string> run_cli(const std::string& args)
{
  const Cli_result r = run_lapmesh(args);
  return {r.status, r.err};
}

// A regular tetrahedron (data/tetrahedron.off) with every coordinate multiplied by `scale`.
std::string scaled_tetrahedron(double scale)
{
  char buf[256];
  std::string off = "OFF\n4 4 0\n";
  for(const auto& p : {std::array<int, 3>{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}}) {
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g\n", p[0] * scale, p[1] * scale, p[2] * scale);
    off += buf;
  }
  return off + "3 0 1 2\n3 0 3 1\n3 0 2 3\n3 1 3 2\n";
}

// Peak resident memory of this process, in MiB.
double peak_rss_mib()
{
  struct rusage u;
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

} // namespace

TEST(Io, RoundTripIsExactInEveryFormatAndKeepsVertexOrder)
{
  auto soup = lapmesh::bumpy_sphere(2);
  for(auto& p : soup.points) p[0] += 1e-9 / 3.0;  // digits that need all 17 places
  const Mesh m = to_mesh(soup);
  const auto [P, tris] = lapmesh::io::mesh_arrays(m);
  for(const char* ext : {"off", "obj", "ply", "stl"}) {
    const std::string path = tmp_path(std::string("roundtrip.") + ext);
    lapmesh::io::write_mesh(path, P, tris);
    Mesh back;
    lapmesh::io::read_triangle_mesh(path, back);
    const auto [Q, back_tris] = lapmesh::io::mesh_arrays(back);
    ASSERT_EQ(Q.rows(), P.rows()) << ext;
    if(std::string(ext) != "stl") {
      EXPECT_EQ((P - Q).norm(), 0.0) << ext;  // bitwise: 17 significant digits
      EXPECT_EQ(back_tris, tris) << ext;
    } else {
      // STL has no shared vertices: merged by exact position in order of first appearance,
      // i.e. the order in which the faces first reach them. Same points, bitwise.
      std::vector<std::array<double, 3>> a, b;
      for(Eigen::Index i = 0; i < P.rows(); ++i) {
        a.push_back({P(i, 0), P(i, 1), P(i, 2)});
        b.push_back({Q(i, 0), Q(i, 1), Q(i, 2)});
      }
      std::sort(a.begin(), a.end());
      std::sort(b.begin(), b.end());
      EXPECT_EQ(a, b);
      EXPECT_EQ(Q(0, 0), P(Eigen::Index(tris[0][0]), 0));  // first vertex of the first face comes first
    }
  }
}

TEST(Io, ObjWithPolygonsNegativeIndicesAndAttributes)
{
  // An L-shaped (non-convex) hexagon and a quad given with v/vt/vn and relative indices.
  const std::string obj =
    "# L shape\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nvt 0 0\nvn 0 0 1\n"
    "f 1/1/1 2/1/1 3/1/1 4/1/1 5/1/1 6/1/1\n"
    "v 3 0 0\nv 3 1 0\nf -7 -2 -1 -6\n";
  Mesh m;
  const auto report = lapmesh::io::read_triangle_mesh(write_text("lshape.obj", obj), m);
  EXPECT_EQ(report.triangulated_polygons, 2u);
  EXPECT_EQ(num_vertices(m), 8u);
  EXPECT_EQ(num_faces(m), 6u);                                      // 4 + 2 triangles
  EXPECT_NEAR(CGAL::Polygon_mesh_processing::area(m), 4.0, 1e-14);  // 3 (L) + 1 (quad)
}

TEST(Io, OffVariantsCommentsAndCountsOnHeaderLine)
{
  const std::string off = "OFF 4 2 0 # counts on the header line\n# a comment\n0 0 0\n1 0 0\n1 1 0\n\n0 1 0\n"
                          "3 0 1 2 255 0 0\n3 0 2 3\n";
  Mesh m;
  lapmesh::io::read_triangle_mesh(write_text("variants.off", off), m);
  EXPECT_EQ(num_faces(m), 2u);
  const std::string coff = "COFF\n3 1 0\n0 0 0 1 0 0 1\n1 0 0 0 1 0 1\n0 1 0 0 0 1 1\n3 0 1 2\n";
  lapmesh::io::read_triangle_mesh(write_text("colors.off", coff), m);
  EXPECT_EQ(num_vertices(m), 3u);
}

TEST(Io, InconsistentOrientationIsRepairedWithoutMovingVertices)
{
  auto soup = lapmesh::icosphere(2);
  const double volume = CGAL::Polygon_mesh_processing::volume(to_mesh(soup));
  std::swap(soup.triangles[5][1], soup.triangles[5][2]);
  std::swap(soup.triangles[77][1], soup.triangles[77][2]);
  lapmesh::io::Polygon_soup ps;
  ps.points = soup.points;
  for(const auto& t : soup.triangles) ps.polygons.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
  lapmesh::io::Soup_report report;
  const auto tris = lapmesh::io::soup_to_triangles(ps, &report);
  EXPECT_EQ(report.flipped_faces, 2u);
  Mesh m;
  lapmesh::io::triangles_to_mesh(ps, tris, m);
  EXPECT_NEAR(CGAL::Polygon_mesh_processing::volume(m), volume, 1e-12);  // all outward again
}

TEST(Io, BadInputsAreReportedWithLineOrElement)
{
  const std::string tri = "0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_TRUE(contains(read_error("empty.off", ""), "empty file"));
  EXPECT_TRUE(contains(read_error("noheader.off", "3 1 0\n" + tri + "3 0 1 2\n"), "missing OFF header"));
  EXPECT_TRUE(contains(read_error("badcounts.off", "OFF\nthree 1 0\n"), "expected the number of vertices, found 'three'"));
  EXPECT_TRUE(contains(read_error("truncv.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n"), "declares 3 vertices, more than its remaining"));
  EXPECT_TRUE(contains(read_error("truncf.off", "OFF\n3 2 0\n" + tri + "3 0 1 2\n"), "expected 2 faces, found 1"));
  EXPECT_TRUE(contains(read_error("badcoord.off", "OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n"), "line 4: vertex 1"));
  EXPECT_TRUE(contains(read_error("range.off", "OFF\n3 1 0\n" + tri + "3 0 1 7\n"), "vertex index 7 out of range"));
  EXPECT_TRUE(contains(read_error("nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"), "vertex 1 has a non-finite"));
  EXPECT_TRUE(contains(read_error("inf.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n"), "vertex 2 has a non-finite"));
  // Defects of real meshes are read and counted (their processing is tested in intrinsic_test).
  EXPECT_EQ(read_error("zero.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n"), "");
  EXPECT_EQ(read_error("isolated.off", "OFF\n4 1 0\n" + tri + "5 5 5\n3 0 1 2\n"), "");
  EXPECT_EQ(read_error("repeat_and_good.off", "OFF\n3 2 0\n" + tri + "3 0 1 1\n3 0 1 2\n"), "");
  // a face that uses a vertex twice is left out; none left is an error
  EXPECT_TRUE(contains(read_error("repeat.off", "OFF\n3 1 0\n" + tri + "3 0 1 1\n"), "no faces (its 1 face(s) each use a vertex twice)"));
  EXPECT_TRUE(contains(read_error("nofaces.off", "OFF\n3 0 0\n" + tri), "no faces"));
  EXPECT_TRUE(contains(read_error("twoverts.off", "OFF\n3 1 0\n" + tri + "2 0 1\n"), "fewer than 3"));
  // three triangles on the edge (0, 1): read with the faces stored apart
  EXPECT_EQ(read_error("nonmanifold.off", "OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n3 0 1 2\n3 1 0 3\n3 0 1 4\n"), "");
  // two fans touching at vertex 0 (a non-manifold vertex): accepted, the operators are
  // defined face by face and Surface_mesh represents it
  EXPECT_EQ(read_error("bowtie.off", "OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n-1 0 0\n-1 -1 0\n3 0 1 2\n3 0 3 4\n"), "");
  // a Moebius strip is not orientable
  {
    std::string moebius = "OFF\n8 8 0\n";
    const int k = 4;
    for(int i = 0; i < k; ++i) {
      const double t = 2 * M_PI * i / k, w = 0.3;
      for(int s : {-1, 1}) {
        const double r = 1 + s * w * std::cos(t / 2);
        moebius += std::to_string(r * std::cos(t)) + " " + std::to_string(r * std::sin(t)) + " " +
                   std::to_string(s * w * std::sin(t / 2)) + "\n";
      }
    }
    for(int i = 0; i < k; ++i) {
      const int a = 2 * i, b = 2 * i + 1;
      const int c = i + 1 < k ? 2 * (i + 1) : 1, d = i + 1 < k ? 2 * (i + 1) + 1 : 0;  // the half twist
      moebius += "3 " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(d) + "\n";
      moebius += "3 " + std::to_string(a) + " " + std::to_string(d) + " " + std::to_string(c) + "\n";
    }
    Mesh m;
    const auto r = lapmesh::io::read_triangle_mesh(write_text("moebius.off", moebius), m);
    EXPECT_TRUE(r.non_orientable);
    EXPECT_EQ(r.input_vertex.size(), num_vertices(m));  // stored apart: one orientation per face
    EXPECT_EQ(num_vertices(m), 24u);
  }
  Mesh m;
  try {
    lapmesh::io::read_triangle_mesh(tmp_path("does_not_exist.off"), m);
    FAIL();
  } catch(const lapmesh::Io_error& e) {
    EXPECT_TRUE(contains(e.what(), "no such file"));
  }
  EXPECT_THROW(lapmesh::io::read_triangle_mesh(write_text("mesh.xyz", "1 2 3\n"), m), lapmesh::Io_error);
  EXPECT_TRUE(contains(read_error("bad.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"), "PLY"));
  EXPECT_TRUE(contains(read_error("objrange.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n"), "not defined before"));
}

TEST(Io, BinaryStlMergesVerticesInOrderOfFirstAppearance)
{
  // Two triangles sharing an edge, binary STL written by hand.
  const float tri[2][3][3] = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {0, 1, 0}}};
  std::string data(80, ' ');
  const std::uint32_t count = 2;
  data.append(reinterpret_cast<const char*>(&count), 4);
  for(const auto& t : tri) {
    const float normal[3] = {0, 0, 1};
    data.append(reinterpret_cast<const char*>(normal), 12);
    data.append(reinterpret_cast<const char*>(t), 36);
    data.append(2, '\0');
  }
  Mesh m;
  lapmesh::io::read_triangle_mesh(write_text("binary.stl", data), m);
  ASSERT_EQ(num_vertices(m), 4u);
  EXPECT_EQ(m.point(Mesh::Vertex_index(3)), Point(1, 1, 0));  // the only new vertex of the 2nd face
}

TEST(IoHostile, StlMergingLooksAtFewSlotsForFloatGridsAndNoneForNaN)
{
  using lapmesh::io::internal::Stl_vertex_merger;
  // A grid of floats: as doubles their low 29 bits are zero, which a hash that does not mix
  // them down piles into a few slots of a power-of-two table.
  lapmesh::io::Polygon_soup soup;
  Stl_vertex_merger merge(soup);
  const int side = 64;
  std::size_t lookups = 0;
  for(int pass = 0; pass < 2; ++pass)
    for(int i = 0; i < side; ++i)
      for(int j = 0; j < side; ++j)
        for(int k = 0; k < 8; ++k) {
          const std::array<double, 3> p = {double(0.25f * float(i)), double(float(j) * 1024.f), double(float(k) - 3.f)};
          const std::size_t expected = std::size_t((i * side + j) * 8 + k);  // first appearance
          ASSERT_EQ(merge.index_of(p), expected) << pass << " " << i << " " << j << " " << k;
          ++lookups;
        }
  EXPECT_EQ(soup.points.size(), std::size_t(side * side * 8));
  EXPECT_LT(double(merge.probes()) / double(lookups), 2.0);

  // -0 and 0 are one position, kept as it first came.
  const std::size_t zero = merge.index_of({-0.0, 0.0, 0.5});
  EXPECT_EQ(zero, std::size_t(side * side * 8));  // not on the grid
  EXPECT_EQ(merge.index_of({0.0, -0.0, 0.5}), zero);
  EXPECT_TRUE(std::signbit(soup.points[zero][0]));

  // A NaN equals nothing, not even itself, and takes no look-up at all: a file of them was
  // quadratic.
  const std::size_t before = merge.probes(), first = soup.points.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for(std::size_t i = 0; i < 100000; ++i) EXPECT_EQ(merge.index_of({double(i % 3), nan, 1.0}), first + i);
  EXPECT_EQ(merge.probes(), before);
  EXPECT_EQ(merge.index_of({0.25, 1024.0, -3.0}), std::size_t((1 * side + 1) * 8));  // the table is intact
}

TEST(Io, AtomicWritesLeaveNothingBehindOnFailure)
{
  const std::string target = tmp_path("atomic.csv");
  std::ofstream(target) << "precious\n";
  EXPECT_THROW(lapmesh::io::write_atomically(target, [](std::ostream& os) {
                 os << "half written";
                 throw std::runtime_error("computation failed");
               }),
               std::runtime_error);
  std::ifstream in(target);
  std::string content;
  std::getline(in, content);
  EXPECT_EQ(content, "precious");  // untouched
  for(const auto& entry : fs::directory_iterator(lapmesh_test::scratch_dir()))
    EXPECT_EQ(entry.path().filename().string().find(".atomic.csv.tmp"), std::string::npos);
  EXPECT_THROW(lapmesh::io::write_atomically(tmp_path("no_such_dir/x.off"), [](std::ostream&) {}), lapmesh::Io_error);
  // a colour per vertex and a PLY with scalar properties
  const Mesh m = to_mesh(lapmesh::icosphere(1));
  const auto [P, tris] = lapmesh::io::mesh_arrays(m);
  lapmesh::io::Vertex_attributes attributes;
  attributes.scalars = {{"mean", std::vector<double>(std::size_t(P.rows()), 0.25)}};
  attributes.colors.assign(std::size_t(P.rows()), lapmesh::Rgb{1, 2, 3});
  lapmesh::io::write_mesh(tmp_path("scalars.ply"), P, tris, attributes);
  std::ifstream ply(tmp_path("scalars.ply"));
  const std::string text((std::istreambuf_iterator<char>(ply)), std::istreambuf_iterator<char>());
  EXPECT_TRUE(contains(text, "property double mean\n"));
  EXPECT_TRUE(contains(text, "property uchar red\n"));
  EXPECT_TRUE(contains(text, " 0.25 1 2 3\n"));
}

TEST(Io, ReadsCgalDataSetMeshes)
{
  using Case = std::pair<std::string, std::size_t>;  // a mesh file and its number of faces
  run_test_cases(std::vector<Case>{{"cow.off", 5804}, {"elephant.off", 5558}, {"colored_tetra.ply", 4}}, [](const Case& c) {
    const auto& [name, faces] = c;
    Mesh m;
    ASSERT_NO_THROW(lapmesh::io::read_triangle_mesh(cgal_mesh(name), m)) << name;
    EXPECT_EQ(num_faces(m), faces) << name;
  });
  Mesh cloud;  // b9.ply is a point cloud: no faces
  EXPECT_THROW(lapmesh::io::read_triangle_mesh(cgal_mesh("b9.ply"), cloud), lapmesh::Mesh_error);
}

TEST(Data, HandWrittenMeshes)
{
  // The meshes of data/ (see data/README.md): each checks what its comment claims.
  const std::string data = LAPMESH_DATA_DIR;
  auto read = [&](const std::string& name, Mesh& m) { return lapmesh::io::read_triangle_mesh(data + "/" + name, m); };
  auto gauss_bonnet = [](const Mesh& m) {
    const lapmesh::Vertex_curvatures c = lapmesh::vertex_curvatures(m);
    return c.gaussian.dot(c.area);
  };
  {
    Mesh m;
    read("tetrahedron.off", m);
    EXPECT_EQ(num_vertices(m), 4u);
    EXPECT_NEAR(gauss_bonnet(m), 4 * CGAL_PI, 1e-12);
    EXPECT_GT(CGAL::Polygon_mesh_processing::volume(m), 0);  // outward
  }
  {
    Mesh m;
    const lapmesh::io::Soup_report r = read("square_pyramid.obj", m);
    EXPECT_EQ(r.triangulated_polygons, 1u);
    EXPECT_EQ(num_faces(m), 6u);
    EXPECT_NEAR(gauss_bonnet(m), 4 * CGAL_PI, 1e-12);
    EXPECT_NEAR(CGAL::Polygon_mesh_processing::volume(m), 4.0 / 3.0, 1e-14);  // base 4, height 1
  }
  {
    Mesh m;
    read("flat_hexagon.off", m);
    const lapmesh::Vertex_curvatures c = lapmesh::vertex_curvatures(m);
    EXPECT_NEAR(c.mean[0], 0, 1e-12);
    EXPECT_NEAR(c.gaussian[0], 0, 1e-12);
    // Boundary vertices: K A = pi - (interior angle 2 pi / 3 split over two triangles) = pi / 3.
    for(int i = 1; i < 7; ++i) EXPECT_NEAR(c.gaussian[i] * c.area[i], CGAL_PI / 3, 1e-12) << i;
  }
  {
    Mesh m;
    const auto r = read("bad_nonmanifold_edge.off", m);
    EXPECT_EQ(r.non_manifold_edges, 1u);
    EXPECT_FALSE(r.input_vertex.empty());
  }
  {
    Mesh m;
    const lapmesh::io::Soup_report r = read("flipped_face.off", m);
    EXPECT_EQ(r.flipped_faces, 1u);
    EXPECT_NEAR(CGAL::Polygon_mesh_processing::area(m), 1.0, 1e-15);
  }
}

// ---------------------------------------------------------------------------------------
// Hostile and unusual input (issue 11, items 18 to 25)

namespace {

// Parses `bytes` as `format` and validates the soup, as the CLI does; the exception's message,
// or "" when the input is a valid mesh. Anything but Io_error or Mesh_error fails the test.
std::string parse_error(const std::string& bytes, const std::string& format)
{
  try {
    lapmesh::io::soup_to_triangles(lapmesh::io::internal::parse_mesh(bytes, format));
  } catch(const lapmesh::Io_error& e) {
    return e.what();
  } catch(const lapmesh::Mesh_error& e) {
    return e.what();
  }
  return "";
}

template <typename T>
void put(std::string& out, T value, bool big_endian)
{
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if(big_endian) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

const std::string ply_tri_header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                   "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

} // namespace

TEST(IoHostile, PlyHeaderAndCountsAreValidatedBeforeAnythingIsRead)
{
  // The 49-byte file that crashed CGAL's reader: a property before any element.
  const std::string crash = "ply\nformat ascii 1.0\nproperty float x\nend_header\n";
  ASSERT_EQ(crash.size(), 49u);
  EXPECT_TRUE(contains(parse_error(crash, "ply"), "line 3: 'property' before any 'element' line"));
  EXPECT_TRUE(contains(parse_error("ply\nformat ascii 1.0\nelement vertex -4\nproperty float x\nend_header\n", "ply"),
                       "element 'vertex': count '-4' out of range"));
  EXPECT_TRUE(contains(parse_error("ply\nformat ascii 1.0\nelement junk -1\nend_header\n", "ply"), "count '-1' out of range"));
  // 10^9 vertices in a few bytes: refused from the header, nothing reserved.
  EXPECT_TRUE(contains(parse_error("ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n"
                                   "property float y\nproperty float z\nend_header\n\1\2\3",
                                   "ply"),
                       "declares 1000000000 'vertex' elements, more than its remaining"));
  // A list length of 0xFFFFFFFF (CGAL's reader grew to 8.4 GB on it).
  std::string list = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n";
  for(float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put(list, c, false);
  put(list, std::uint32_t(0xFFFFFFFF), false);
  for(int i : {0, 1, 2}) put(list, i, false);
  const double before = peak_rss_mib();
  EXPECT_TRUE(contains(parse_error(list, "ply"), "declares 4294967295 list entries in face 0"));
  EXPECT_LT(peak_rss_mib() - before, 50.0);
  // An element of no properties and a huge count is not a loop of 2^64 reads.
  EXPECT_EQ(parse_error(ply_tri_header.substr(0, ply_tri_header.size() - 11) + "element empty 4000000000\nend_header\n"
                          "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                        "ply"),
            "");
  // Item 25: a PLY index of -1 is reported as -1.
  EXPECT_TRUE(contains(parse_error(ply_tri_header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n", "ply"),
                       "face 0: vertex index -1 out of range [0, 3)"));
  EXPECT_TRUE(contains(parse_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                   "property float z\nproperty int128 w\nend_header\n",
                                   "ply"),
                       "unknown property type 'int128'"));
}

TEST(IoHostile, BinaryPlyOfBothByteOrdersAndBinaryStlGiveTheSameSoupAsAscii)
{
  // Coordinates exact in float, so that binary STL (float) and ASCII agree bitwise. GCC 12.2's
  // SLP vectoriser at -O3 rounds only the last coordinate of `c = double(float(c))` over an
  // array<double, 3>: the rounding goes through a volatile float instead.
  auto sphere = lapmesh::bumpy_sphere(2);
  for(auto& p : sphere.points)
    for(double& c : p) {
      volatile float rounded = float(c);
      c = rounded;
    }
  lapmesh::io::Polygon_soup expected;
  expected.points = sphere.points;
  for(const auto& t : sphere.triangles) expected.polygons.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
  const std::size_t n = expected.points.size(), m = expected.polygons.size();

  lapmesh::Vertex_vectors P(Eigen::Index(n), 3);
  for(std::size_t i = 0; i < n; ++i) P.row(Eigen::Index(i)) = Eigen::Vector3d(expected.points[i].data());
  std::vector<std::array<std::size_t, 3>> tris;
  for(const auto& f : expected.polygons) tris.push_back({f[0], f[1], f[2]});
  std::ostringstream ascii_ply, ascii_stl;
  lapmesh::io::write_mesh(ascii_ply, "ply", P, tris);
  lapmesh::io::write_mesh(ascii_stl, "stl", P, tris);
  const auto from_ascii = lapmesh::io::internal::parse_mesh(ascii_ply.str(), "ply");
  EXPECT_EQ(from_ascii.points, expected.points);
  EXPECT_EQ(from_ascii.polygons, expected.polygons);

  for(bool big : {false, true}) {
    // double coordinates, an extra uchar, `list uchar short` indices, a list to skip, an edge element
    std::string ply = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                      " 1.0\nelement vertex " + std::to_string(n) +
                      "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nelement face " +
                      std::to_string(m) + "\nproperty list uchar short vertex_indices\nproperty list ushort float uv\n"
                      "element edge 1\nproperty int a\nproperty int b\nend_header\n";
    for(const auto& p : expected.points) {
      for(double c : p) put(ply, c, big);
      put(ply, std::uint8_t(7), big);
    }
    for(const auto& f : expected.polygons) {
      put(ply, std::uint8_t(3), big);
      for(std::size_t v : f) put(ply, std::int16_t(v), big);
      put(ply, std::uint16_t(1), big);
      put(ply, 0.5f, big);
    }
    put(ply, 0, big);
    put(ply, 1, big);
    const auto soup = lapmesh::io::internal::parse_mesh(ply, "ply");
    EXPECT_EQ(soup.points, expected.points) << big;
    EXPECT_EQ(soup.polygons, expected.polygons) << big;
    EXPECT_TRUE(contains(parse_error(ply + "x", "ply"), "unexpected 1 bytes after the last element: 'x'")) << big;
    EXPECT_EQ(parse_error(ply + "\n", "ply"), "") << big;  // trailing whitespace is fine
  }

  std::string stl(80, ' ');
  put(stl, std::uint32_t(m), false);
  for(const auto& f : expected.polygons) {
    for(float c : {0.f, 0.f, 1.f}) put(stl, c, false);
    for(std::size_t v : f)
      for(double c : expected.points[v]) put(stl, float(c), false);
    stl.append(2, '\0');
  }
  const auto from_binary = lapmesh::io::internal::parse_mesh(stl, "stl");
  const auto from_ascii_stl = lapmesh::io::internal::parse_mesh(ascii_stl.str(), "stl");
  EXPECT_EQ(from_binary.points, from_ascii_stl.points);
  EXPECT_EQ(from_binary.polygons, from_ascii_stl.polygons);
  EXPECT_EQ(from_binary.points.size(), n);  // merged by position: one point per vertex
  EXPECT_TRUE(contains(parse_error(stl + "xy", "stl"), "declares " + std::to_string(m) + " triangles"));
}

TEST(IoHostile, OffCountsAndValencesAreCheckedAgainstTheFileSize)
{
  const std::string claim = "OFF\n100000000 1 0\n";
  ASSERT_EQ(claim.size(), 18u);
  Mesh m;
  const double before = peak_rss_mib();
  // CPU time, with a wide margin (the old reader spent about a minute growing its arrays): a
  // loaded machine or a sanitizer build must not make this fail.
  const std::clock_t start = std::clock();
  const std::string e = read_error("claims.off", claim);
  const double seconds = double(std::clock() - start) / CLOCKS_PER_SEC;
  EXPECT_TRUE(contains(e, "declares 100000000 vertices, more than its remaining")) << e;
  EXPECT_LT(seconds, 2.0);
  EXPECT_LT(peak_rss_mib() - before, 50.0);
  EXPECT_TRUE(contains(read_error("claims2.off", "OFF 2000000000 1 0\n"), "declares 2000000000 vertices"));
  EXPECT_TRUE(contains(read_error("valence.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2000000000 0 1 2\n"),
                       "declares 2000000000 vertices in face 0"));
  EXPECT_LT(peak_rss_mib() - before, 50.0);
  // Item 25: an index of 2^64 is out of range, not a missing index.
  EXPECT_TRUE(contains(read_error("big_index.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 18446744073709551616\n"),
                       "face 0: vertex index '18446744073709551616' out of range [0, 3)"));
  EXPECT_TRUE(contains(read_error("few_indices.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n"),
                       "expected 3 vertex indices, found 2"));
}

TEST(IoHostile, TrailingContentIsRefusedButWhitespaceAndCommentsAreNot)
{
  const std::string off = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  EXPECT_EQ(read_error("ok.off", off + "\n  \n# the end\n"), "");
  EXPECT_TRUE(contains(read_error("junk.off", off + "3 0 1 2\n"), "line 7: unexpected content after the last face: '3 0 1 2\\x0a'"));
  EXPECT_TRUE(contains(read_error("nuls.off", off + std::string(100000, '\0')), "unexpected content after the last face: '\\x00"));
  EXPECT_TRUE(contains(read_error("junk_on_line.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 junk\n"), "face 0: unexpected 'junk'"));
  const std::string ply = ply_tri_header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  EXPECT_EQ(read_error("ok.ply", ply + " \n"), "");
  EXPECT_TRUE(contains(read_error("junk.ply", ply + "7\n"), "unexpected content after the last element: '7'"));
  const std::string stl = "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
                          "endfacet\nendsolid a\n";
  EXPECT_EQ(read_error("ok.stl", stl + "\n"), "");
  EXPECT_EQ(read_error("two_solids.stl", stl + stl), "");  // several solids in one file
  EXPECT_TRUE(contains(read_error("junk.stl", stl + std::string(10, '\0')), "unexpected content after 'endsolid': '\\x00"));
}

TEST(IoHostile, OnlyRegularFilesAreRead)
{
  // Each would block or read forever if opened as a file: alarm() makes a hang a failure.
  alarm(20);
  const std::string fifo = tmp_path("fifo.off");
  fs::remove(fifo);
  fs::remove(tmp_path("zero.off"));
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  Mesh m;
  auto message = [&m](const std::string& path) {
    try {
      lapmesh::io::read_triangle_mesh(path, m);
    } catch(const lapmesh::Io_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_TRUE(contains(message(fifo), "is a FIFO (named pipe), not a regular mesh file"));
  const std::string zero = tmp_path("zero.off");
  fs::create_symlink("/dev/zero", zero);
  EXPECT_TRUE(contains(message(zero), "is a character device, not a regular mesh file"));
  fs::create_directories(tmp_path("dir.ply"));
  EXPECT_TRUE(contains(message(tmp_path("dir.ply")), "is a directory"));
  alarm(0);
  // Item 25: a file without an extension.
  EXPECT_EQ(message(write_text("noext", "OFF\n")), "no file extension (expected .off, .obj, .ply or .stl)");
}

TEST(IoHostile, MessagesQuoteABoundedEscapedExcerpt)
{
  // A 20 MB first token: a short message, read no further than the token bound.
  const std::string e = read_error("long_token.off", std::string(20'000'000, 'A') + "\n");
  EXPECT_TRUE(contains(e, "a token longer than 1024 characters: 'AAAA")) << e.substr(0, 200);
  EXPECT_LT(e.size(), 200u);
  // NUL and other bytes are escaped, so nothing cuts or garbles the message.
  const std::string nul = read_error("nul.off", std::string("OFF\n3 1 0\n0 0 0\n1 \0\x01\xff 0\n0 1 0\n3 0 1 2\n", 38));
  EXPECT_TRUE(contains(nul, "line 4: vertex 1: bad coordinate '\\x00\\x01\\xff'")) << nul;
  EXPECT_EQ(std::strlen(nul.c_str()), nul.size());
  std::mt19937 rng(11);
  std::string random(4096, '\0');
  for(char& c : random) c = char(rng());
  for(const char* format : {"off", "obj", "ply", "stl"}) {
    const std::string r = parse_error(random, format);
    EXPECT_FALSE(r.empty()) << format;
    EXPECT_LT(r.size(), 300u) << format;
    for(char c : r) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << format << ": " << r;
  }
  EXPECT_EQ(lapmesh::io::internal::excerpt(std::string(100, 'x')).size(), 2 + 40 + 3u);  // quotes, 40, "..."
}

TEST(IoHostile, ScaledTetrahedraWorkOrAreRefusedAsOutOfRange)
{
  const Mesh unit = [] {
    Mesh m;
    lapmesh::io::read_triangle_mesh(std::string(LAPMESH_DATA_DIR) + "/tetrahedron.off", m);
    return m;
  }();
  const lapmesh::Vertex_curvatures c1 = lapmesh::vertex_curvatures(unit);
  // Inside the representable range (edge lengths 1e-145 .. 1e145): the curvatures scale as
  // they must, H by 1/s and K by 1/s^2 (before, 1e100 gave wrong weights: |cross|^2 overflowed).
  for(double s : {1e-140, 1e-80, 1e-10, 1e10, 1e80, 1e100, 1e140}) {
    Mesh m;
    ASSERT_EQ(read_error("scaled.off", scaled_tetrahedron(s)), "") << s;
    lapmesh::io::read_triangle_mesh(tmp_path("scaled.off"), m);
    const lapmesh::Vertex_curvatures c = lapmesh::vertex_curvatures(m);
    for(int i = 0; i < 4; ++i) {
      EXPECT_NEAR(c.mean[i] * s, c1.mean[i], 1e-12 * std::abs(c1.mean[i])) << s;
      EXPECT_NEAR(c.gaussian[i] * s * s, c1.gaussian[i], 1e-12 * std::abs(c1.gaussian[i])) << s;
    }
  }
  // Outside: a clear refusal at both ends, never "zero area".
  for(double s : {1e150, 1e160, 1e200, 1e300, 1e308, 1e-150, 1e-200, 1e-300}) {
    const std::string e = read_error("scaled.off", scaled_tetrahedron(s));
    EXPECT_TRUE(contains(e, "face 0 has coordinates out of the representable range")) << s << ": " << e;
    // The same refusal from the operators for a mesh built without the reader.
    Mesh m;
    lapmesh::Triangle_soup soup;
    for(const auto& p : {std::array<double, 3>{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}})
      soup.points.push_back({p[0] * s, p[1] * s, p[2] * s});
    soup.triangles = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
    m = to_mesh(soup);
    try {
      lapmesh::vertex_curvatures(m);
      ADD_FAILURE() << s << ": accepted";
    } catch(const lapmesh::Mesh_error& err) {
      EXPECT_TRUE(contains(err.what(), "out of the representable range")) << s << ": " << err.what();
    }
  }
  // End to end through the CLI: curvature and smoothing at both ends of the range.
  for(double s : {1e-140, 1e140}) {
    const std::string in = write_text("cli_scaled.off", scaled_tetrahedron(s));
    const auto [rc, err] = run_cli("curvature " + in + " -o " + tmp_path("scaled.csv"));
    EXPECT_EQ(rc, 0) << s << ": " << err;
    const std::string csv = read_file(tmp_path("scaled.csv"));
    EXPECT_FALSE(contains(csv, "nan") || contains(csv, "inf")) << s;
  }
  // The implicit smoothing's system is scaled by the mass, so its right-hand side M P stays
  // representable at both ends of the range too.
  for(double s : {1e-140, 1e-100, 1e100, 1e140}) {
    const std::string in = write_text("cli_scaled.off", scaled_tetrahedron(s));
    const auto [rc2, err2] =
      run_cli("smooth " + in + " -o " + tmp_path("smoothed.off") + " --scheme implicit --lambda 1e-3 --iterations 1 --lambda-unit edge2");
    EXPECT_EQ(rc2, 0) << s << ": " << err2;
  }
  const auto [rc, err] = run_cli("curvature " + write_text("cli_huge.off", scaled_tetrahedron(1e160)) + " -o " + tmp_path("huge.csv"));
  EXPECT_EQ(rc, 1);
  EXPECT_TRUE(contains(err, "cli_huge.off: face 0 has coordinates out of the representable range")) << err;
  EXPECT_FALSE(fs::exists(tmp_path("huge.csv")));
}

TEST(IoHostile, StaleTemporaryFilesOfKilledWritersAreRemovedByTheNextWrite)
{
  const std::string dir = lapmesh_test::scratch_dir() + "/stale";
  fs::create_directories(dir);
  const Mesh tet = to_mesh(lapmesh::icosphere(0));
  const auto [P, tris] = lapmesh::io::mesh_arrays(tet);
  // A writer killed with SIGKILL during its write, as kill -9 does to `lapmesh`.
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if(child == 0) {
    try {
      lapmesh::io::write_atomically(dir + "/out.ply", [](std::ostream& os) {
        os << std::string(1 << 20, 'x') << std::flush;
        pause();  // killed here, mid-write
      });
    } catch(...) {
    }
    _exit(0);
  }
  const std::string temporary = dir + "/.out.ply.lapmesh-tmp." + std::to_string(child);
  for(int i = 0; i < 200 && !(fs::exists(temporary) && fs::file_size(temporary) > 0); ++i) usleep(20000);
  ASSERT_TRUE(fs::exists(temporary));
  kill(child, SIGKILL);
  waitpid(child, nullptr, 0);
  EXPECT_TRUE(fs::exists(temporary));  // the litter of issue 11, item 23
  EXPECT_FALSE(fs::exists(dir + "/out.ply"));
  // Files that must stay: a live process's temporary, a look-alike that is not lapmesh's,
  // and a directory with a lapmesh name.
  const std::string live = dir + "/.other.off.lapmesh-tmp." + std::to_string(getppid());
  const std::string foreign = dir + "/.other.off.tmp.999999";
  std::ofstream(live) << "being written";
  std::ofstream(foreign) << "someone else's";
  fs::create_directory(dir + "/.d.lapmesh-tmp.999998");
  lapmesh::io::write_mesh(dir + "/next.off", P, tris);
  EXPECT_FALSE(fs::exists(temporary));
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(fs::exists(foreign));
  EXPECT_TRUE(fs::exists(dir + "/.d.lapmesh-tmp.999998"));
  EXPECT_TRUE(fs::exists(dir + "/next.off"));
  std::size_t entries = 0;
  for([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 4u);  // live, foreign, the directory, next.off
}

TEST(IoHostile, EarClippingIsFastOnLargePolygons)
{
  const std::size_t n = 20000;
  auto shoelace = [](const std::vector<std::array<double, 3>>& pts) {
    double a = 0;
    for(std::size_t i = 0; i < pts.size(); ++i) {
      const auto& p = pts[i];
      const auto& q = pts[(i + 1) % pts.size()];
      a += p[0] * q[1] - q[0] * p[1];
    }
    return 0.5 * a;
  };
  std::vector<std::pair<std::string, std::vector<std::array<double, 3>>>> shapes(3);
  shapes[0].first = "convex";
  shapes[1].first = "star";
  shapes[2].first = "comb";
  for(std::size_t i = 0; i < n; ++i) {
    const double t = 2 * M_PI * double(i) / double(n);
    shapes[0].second.push_back({std::cos(t), std::sin(t), 0});
    const double r = i % 2 ? 0.5 : 1.0;
    shapes[1].second.push_back({r * std::cos(t), r * std::sin(t), 0});
  }
  // A comb: teeth of height 1 along y = 0, closed by a spine below.
  const std::size_t teeth = (n - 2) / 4;
  for(std::size_t k = 0; k < teeth; ++k) {
    const double x = double(k);
    shapes[2].second.push_back({x, 0, 0});
    shapes[2].second.push_back({x + 0.25, 1, 0});
    shapes[2].second.push_back({x + 0.5, 1, 0});
    shapes[2].second.push_back({x + 0.75, 0, 0});
  }
  shapes[2].second.push_back({double(teeth), -1, 0});
  shapes[2].second.push_back({0, -1, 0});
  for(const auto& [name, pts] : shapes) {
    std::vector<std::size_t> poly(pts.size());
    for(std::size_t i = 0; i < poly.size(); ++i) poly[i] = i;
    std::vector<std::array<std::size_t, 3>> out;
    // CPU time, not wall time: the test machine may be shared.
    const std::clock_t start = std::clock();
    ASSERT_TRUE(lapmesh::io::internal::triangulate_polygon(poly, pts, out)) << name;
    const double seconds = double(std::clock() - start) / CLOCKS_PER_SEC;
    EXPECT_EQ(out.size(), pts.size() - 2) << name;
    double area = 0;
    for(const auto& t : out) {
      const auto &a = pts[t[0]], &b = pts[t[1]], &c = pts[t[2]];
      const double signed_area = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
      EXPECT_GT(signed_area * shoelace(pts), 0) << name;  // the polygon's orientation, none flipped
      area += signed_area;
    }
    EXPECT_NEAR(area, shoelace(pts), 1e-9 * std::abs(shoelace(pts))) << name;  // a tiling, no overlap
    EXPECT_LT(seconds, 2.0) << name << " (the quadratic clipping took 8.5 s)";
    std::cout << name << ": " << pts.size() << " vertices in " << seconds << " s of CPU time\n";
  }
  // A convex polygon is the fan of its last vertex, as before the rewrite.
  std::vector<std::array<std::size_t, 3>> fan;
  lapmesh::io::internal::triangulate_polygon({0, 1, 2, 3, 4}, shapes[0].second, fan);
  EXPECT_EQ(fan, (std::vector<std::array<std::size_t, 3>>{{4, 0, 1}, {4, 1, 2}, {2, 3, 4}}));
}

TEST(IoHostile, OutputEqualToInputOrReadOnlyIsRefusedUnlessForced)
{
  const std::string in = tmp_path("in.off");
  fs::copy_file(std::string(LAPMESH_DATA_DIR) + "/tetrahedron.off", in, fs::copy_options::overwrite_existing);
  fs::remove(tmp_path("link.off"));
  fs::remove(tmp_path("hard.off"));
  const std::string original = read_file(in);
  fs::create_symlink(in, tmp_path("link.off"));
  fs::create_hard_link(in, tmp_path("hard.off"));
  for(const std::string& out : {in, tmp_path("link.off"), tmp_path("hard.off"), lapmesh_test::scratch_dir() + "/./io_in.off"}) {
    const auto [rc, err] = run_cli("smooth " + in + " -o " + out + " --scheme implicit --lambda 1e-3 --iterations 1");
    EXPECT_EQ(rc, 1) << out;
    EXPECT_TRUE(contains(err, "is the input file") && contains(err, "--force")) << err;
    EXPECT_EQ(read_file(in), original);
  }
  auto [rc, err] = run_cli("smooth " + in + " -o " + in + " --scheme implicit --lambda 1e-3 --iterations 1 --force");
  EXPECT_EQ(rc, 0) << err;
  EXPECT_NE(read_file(in), original);
  // A read-only target is refused as cp refuses it, and replaced with --force.
  const std::string ro = tmp_path("readonly.csv");
  std::ofstream(ro) << "keep\n";
  fs::permissions(ro, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  std::tie(rc, err) = run_cli("curvature " + in + " -o " + ro);
  EXPECT_EQ(rc, 1);
  EXPECT_TRUE(contains(err, "readonly.csv: the file is read-only; refusing to replace it (use --force")) << err;
  EXPECT_EQ(read_file(ro), "keep\n");
  std::tie(rc, err) = run_cli("curvature " + in + " -o " + ro + " --force");
  EXPECT_EQ(rc, 0) << err;
  EXPECT_NE(read_file(ro), "keep\n");
  // CLI messages for files without extension and for hostile content stay one bounded line.
  std::tie(rc, err) = run_cli("curvature " + write_text("noext", "OFF\n") + " -o " + tmp_path("x.csv"));
  EXPECT_EQ(rc, 1);
  EXPECT_TRUE(contains(err, "noext: no file extension (expected .off, .obj, .ply or .stl)")) << err;
  std::tie(rc, err) = run_cli("curvature " + write_text("crash.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n") +
                              " -o " + tmp_path("x.csv"));
  EXPECT_EQ(rc, 1);
  EXPECT_TRUE(contains(err, "crash.ply: line 3: 'property' before any 'element' line")) << err;
}

TEST(IoHostile, FuzzRegressionsEndInACleanErrorAndSeedsRead)
{
  // Every input a fuzzer (or issue 11) found is replayed here, in the ordinary suite.
  const fs::path fuzz = fs::path(LAPMESH_DATA_DIR) / ".." / "test" / "fuzz";
  std::size_t regressions = 0, seeds = 0;
  for(const auto& format : fs::directory_iterator(fuzz / "regressions"))
    for(const auto& file : fs::directory_iterator(format.path())) {
      const std::string e = parse_error(read_file(file.path().string()), format.path().filename().string());
      EXPECT_FALSE(e.empty()) << file.path() << " was accepted";
      EXPECT_LT(e.size(), 300u) << file.path();
      ++regressions;
    }
  for(const auto& format : fs::directory_iterator(fuzz / "corpus"))
    for(const auto& file : fs::directory_iterator(format.path())) {
      try {
        lapmesh::io::soup_to_triangles(lapmesh::io::internal::parse_mesh(read_file(file.path().string()),
                                                                         format.path().filename().string()));
      } catch(const lapmesh::Mesh_error&) {
        // a seed may be a valid file of an invalid mesh (bad_nonmanifold_edge.off)
      }
      ++seeds;
    }
  EXPECT_GE(regressions, 15u);
  EXPECT_GE(seeds, 15u);
}

namespace {

// The mesh that CGAL::Euler::add_face() builds from the triangles in order, vertex i = point i.
Mesh added_face_by_face(const lapmesh::io::Polygon_soup& soup, const std::vector<std::array<std::size_t, 3>>& tris)
{
  Mesh m;
  for(const auto& p : soup.points) m.add_vertex(Point(p[0], p[1], p[2]));
  for(const auto& t : tris) {
    const std::array<Mesh::Vertex_index, 3> face = {Mesh::Vertex_index(Mesh::size_type(t[0])),
                                                    Mesh::Vertex_index(Mesh::size_type(t[1])),
                                                    Mesh::Vertex_index(Mesh::size_type(t[2]))};
    EXPECT_NE(CGAL::Euler::add_face(face, m), Mesh::null_face());
  }
  return m;
}

// The number of elements whose connectivity differs between a and b (-1: different sizes).
long connectivity_differences(const Mesh& a, const Mesh& b)
{
  if(a.number_of_vertices() != b.number_of_vertices() || a.number_of_halfedges() != b.number_of_halfedges() ||
     a.number_of_faces() != b.number_of_faces())
    return -1;
  long differences = 0;
  for(Mesh::Halfedge_index h : a.halfedges())
    differences += a.target(h) != b.target(h) || a.face(h) != b.face(h) || a.next(h) != b.next(h) || a.prev(h) != b.prev(h);
  for(Mesh::Face_index f : a.faces()) differences += a.halfedge(f) != b.halfedge(f);
  for(Mesh::Vertex_index v : a.vertices()) differences += a.halfedge(v) != b.halfedge(v) || a.point(v) != b.point(v);
  return differences;
}

// A cone of `faces` triangles around vertex 0 over a ring of vertices (closed: around the
// apex; open: a fan with a border), the faces in shuffled order and each starting at a random
// corner, so that the apex's neighbours come in no particular order.
lapmesh::io::Polygon_soup shuffled_cone(std::size_t faces, bool closed, unsigned seed)
{
  lapmesh::io::Polygon_soup soup;
  soup.points.push_back({0, 0, 1});
  const std::size_t ring = closed ? faces : faces + 1;
  for(std::size_t i = 0; i < ring; ++i) {
    const double angle = 2 * M_PI * double(i) / double(faces + (closed ? 0 : 1));
    soup.points.push_back({std::cos(angle), std::sin(angle), 0});
  }
  for(std::size_t i = 0; i < faces; ++i) soup.polygons.push_back({0, 1 + i, 1 + (i + 1) % ring});
  std::mt19937 random(seed);
  std::shuffle(soup.polygons.begin(), soup.polygons.end(), random);
  for(auto& p : soup.polygons) std::rotate(p.begin(), p.begin() + random() % 3, p.end());
  return soup;
}

} // namespace

TEST(Io, AManifoldSurfaceMeshIsBuiltExactlyAsFaceByFace)
{
  // Closed, with boundaries, several components, faces in shuffled order, a vertex in no face.
  const lapmesh::Triangle_soup sphere = lapmesh::bumpy_sphere(1);
  lapmesh::io::Polygon_soup with_isolated;
  with_isolated.points.assign(sphere.points.begin(), sphere.points.end());
  for(const auto& t : sphere.triangles)
    with_isolated.polygons.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
  with_isolated.points.push_back({5, 5, 5});
  std::vector<std::pair<std::string, lapmesh::io::Polygon_soup>> cases = {
    {"bumpy sphere with a vertex in no face", with_isolated},
    {"a closed cone of 3000 faces around a vertex, shuffled", shuffled_cone(3000, true, 1)},
    {"an open fan of 3000 faces around a vertex, shuffled", shuffled_cone(3000, false, 2)}};
  for(const char* name : {"cube-ouvert.off", "blobby_3cc.off", "blobby-shuffled.off", "double-torus-3-holes.off",
                          "elephant.off"})
    cases.emplace_back(name, lapmesh::io::read_polygon_soup(cgal_mesh(name)));
  for(const auto& [name, soup] : cases) {
    SCOPED_TRACE(name);
    const auto tris = lapmesh::io::soup_to_triangles(soup);
    Mesh fast;
    ASSERT_TRUE(lapmesh::internal::build_manifold_surface_mesh(soup.points, tris, fast));
    EXPECT_TRUE(fast.is_valid(false));
    EXPECT_EQ(connectivity_differences(fast, added_face_by_face(soup, tris)), 0);
    Mesh read;  // what the reader builds from the same triangles
    std::vector<std::size_t> input_vertex;
    lapmesh::io::triangles_to_mesh(soup, tris, read, &input_vertex);
    EXPECT_TRUE(input_vertex.empty());
    EXPECT_EQ(connectivity_differences(read, fast), 0);
  }
}

TEST(Io, SurfacesThatAreNotManifoldAreLeftToFaceByFace)
{
  lapmesh::io::Polygon_soup soup;
  soup.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  using Tris = std::vector<std::array<std::size_t, 3>>;
  const std::vector<std::pair<std::string, Tris>> refused = {
    {"two faces meeting at a vertex only", {{0, 1, 2}, {0, 3, 4}}},
    {"two closed fans meeting at a vertex", {{0, 2, 1}, {0, 1, 5}, {0, 5, 2}, {1, 2, 5}, {0, 4, 3}, {0, 3, 6}, {0, 6, 4}, {3, 4, 6}}},
    {"three faces on an edge", {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}}},
    {"neighbours of opposite orientations", {{0, 1, 2}, {0, 1, 3}}}};
  for(const auto& [name, tris] : refused) {
    Mesh m;
    EXPECT_FALSE(lapmesh::internal::build_manifold_surface_mesh(soup.points, tris, m)) << name;
    EXPECT_EQ(m.number_of_vertices(), 0u) << name;
  }
  // The same at a vertex of many faces: two open fans of 500 faces around it, and one of
  // them turned over (as given: soup_to_triangles() would turn it back).
  const auto as_given = [](const lapmesh::io::Polygon_soup& s) {
    Tris tris;
    for(const auto& p : s.polygons) tris.push_back({p[0], p[1], p[2]});
    return tris;
  };
  {
    lapmesh::io::Polygon_soup two_fans = shuffled_cone(1000, false, 3);
    two_fans.polygons.erase(std::remove_if(two_fans.polygons.begin(), two_fans.polygons.end(),
                                           [](const std::vector<std::size_t>& p) {
                                             return *std::max_element(p.begin(), p.end()) == 501;
                                           }),
                            two_fans.polygons.end());
    Mesh m;
    EXPECT_FALSE(lapmesh::internal::build_manifold_surface_mesh(two_fans.points, as_given(two_fans), m));
    lapmesh::io::Polygon_soup turned = shuffled_cone(1000, false, 4);
    for(auto& p : turned.polygons)
      if(*std::max_element(p.begin(), p.end()) <= 500) std::swap(p[0], p[1]);
    EXPECT_FALSE(lapmesh::internal::build_manifold_surface_mesh(turned.points, as_given(turned), m));
    EXPECT_TRUE(lapmesh::internal::build_manifold_surface_mesh(turned.points, lapmesh::io::soup_to_triangles(turned), m));
  }
  // Two cones of 3000 faces meeting at their apex: add_face() would turn around the apex for
  // each face, so they are stored apart (and welded back by input_vertex).
  {
    lapmesh::io::Polygon_soup two_cones = shuffled_cone(3000, true, 5);
    const std::size_t second = two_cones.points.size();
    for(std::size_t i = 1; i < second; ++i)
      two_cones.points.push_back({two_cones.points[i][0], two_cones.points[i][1], 2.0});
    const std::size_t faces = two_cones.polygons.size();
    for(std::size_t f = 0; f < faces; ++f) {
      std::vector<std::size_t> p = two_cones.polygons[f];
      for(std::size_t& v : p)
        if(v != 0) v += second - 1;
      two_cones.polygons.push_back(p);
    }
    const auto tris = lapmesh::io::soup_to_triangles(two_cones);
    EXPECT_FALSE(lapmesh::internal::face_by_face_is_affordable(two_cones.points.size(), tris));
    Mesh m;
    std::vector<std::size_t> input_vertex;
    lapmesh::io::triangles_to_mesh(two_cones, tris, m, &input_vertex);
    EXPECT_EQ(m.number_of_faces(), tris.size());
    ASSERT_EQ(input_vertex.size(), 3 * tris.size());
    for(std::size_t c = 0; c < input_vertex.size(); ++c) EXPECT_EQ(input_vertex[c], tris[c / 3][c % 3]);
  }
  EXPECT_TRUE(lapmesh::internal::face_by_face_is_affordable(soup.points.size(), refused[0].second));
  // Faces meeting at a vertex only: add_face() holds them, as it did before the fast path.
  Mesh bowtie;
  std::vector<std::size_t> input_vertex;
  lapmesh::io::triangles_to_mesh(soup, refused[0].second, bowtie, &input_vertex);
  EXPECT_TRUE(input_vertex.empty());
  EXPECT_EQ(connectivity_differences(bowtie, added_face_by_face(soup, refused[0].second)), 0);
  // An open fan, a closed one: built.
  for(const Tris& tris : {Tris{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}}, Tris{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}}}) {
    Mesh m;
    EXPECT_TRUE(lapmesh::internal::build_manifold_surface_mesh(soup.points, tris, m));
    EXPECT_EQ(connectivity_differences(m, added_face_by_face(soup, tris)), 0);
  }
}

TEST(Io, NumbersAreWrittenAsPrintfWrites17Digits)
{
  // Written by the mesh writer and by printf, independently, for numbers of every kind.
  const std::vector<double> values = {0.0, -0.0, 1.0, -1.5, 0.1, 1.0 / 3.0, 123456789012345678.0, 1e-5, 1e16,
                                      -2.5e-308, 4.9406564584124654e-324, 1.7976931348623157e308,
                                      std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                                      std::numeric_limits<double>::quiet_NaN()};
  std::mt19937_64 bits_source(7);
  std::vector<double> all = values;
  for(int i = 0; i < 3000; ++i) {
    std::uint64_t bits = bits_source();
    double x;
    std::memcpy(&x, &bits, sizeof x);
    all.push_back(x);
  }
  while(all.size() % 3 != 0) all.push_back(0.5);
  lapmesh::Vertex_vectors P(Eigen::Index(all.size() / 3), 3);
  for(std::size_t i = 0; i < all.size(); ++i) P(Eigen::Index(i / 3), Eigen::Index(i % 3)) = all[i];
  std::ostringstream written;
  lapmesh::io::write_mesh(written, "obj", P, {{0, 1, 2}});
  std::string expected;
  char buf[128];
  for(Eigen::Index i = 0; i < P.rows(); ++i) {
    std::snprintf(buf, sizeof buf, "v %.17g %.17g %.17g\n", P(i, 0), P(i, 1), P(i, 2));
    expected += buf;
  }
  expected += "f 1 2 3\n";
  EXPECT_EQ(written.str(), expected);
  std::ostringstream one;
  lapmesh::io::put_double(one, 1.0 / 3.0);
  EXPECT_EQ(one.str(), "0.33333333333333331");
}

TEST(Io, TextOutputIsTheSameAcrossItsBlocks)
{
  // Blocks of 16 bytes: every kind of item crosses a block boundary somewhere.
  std::ostringstream blocked, direct;
  {
    lapmesh::io::internal::Text_output out(blocked, 16);
    for(int i = 0; i < 500; ++i) {
      out.put(std::size_t(i) * 7919u);
      out.put(' ');
      out.put(-i);
      out.put(" x ");
      out.put(i * 0.1);
      out.put(std::string(i % 80, 'a'));
      out.put('\n');
      direct << std::size_t(i) * 7919u << ' ' << -i << " x ";
      lapmesh::io::put_double(direct, i * 0.1);
      direct << std::string(i % 80, 'a') << '\n';
    }
    out.flush();
  }
  EXPECT_EQ(blocked.str(), direct.str());
}
