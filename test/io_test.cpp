// Mesh input/output: formats, exact round trips, vertex order, repairs and every bad input.
#include "test_helpers.h"

#include <lapmesh/curvature.h>
#include <lapmesh/io.h>

#include <CGAL/Polygon_mesh_processing/measure.h>

#include <fstream>

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
  EXPECT_TRUE(contains(read_error("badcounts.off", "OFF\nthree 1 0\n"), "bad counts"));
  EXPECT_TRUE(contains(read_error("truncv.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n"), "expected 3 vertices, found 2"));
  EXPECT_TRUE(contains(read_error("truncf.off", "OFF\n3 2 0\n" + tri + "3 0 1 2\n"), "expected 2 faces, found 1"));
  EXPECT_TRUE(contains(read_error("badcoord.off", "OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n"), "line 4: vertex 1"));
  EXPECT_TRUE(contains(read_error("range.off", "OFF\n3 1 0\n" + tri + "3 0 1 7\n"), "vertex index 7 out of range"));
  EXPECT_TRUE(contains(read_error("nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"), "vertex 1 has a non-finite"));
  EXPECT_TRUE(contains(read_error("inf.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n"), "vertex 2 has a non-finite"));
  EXPECT_TRUE(contains(read_error("zero.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n"), "face 0 has zero area"));
  EXPECT_TRUE(contains(read_error("repeat.off", "OFF\n3 1 0\n" + tri + "3 0 1 1\n"), "face 0 uses the same vertex twice"));
  EXPECT_TRUE(contains(read_error("isolated.off", "OFF\n4 1 0\n" + tri + "5 5 5\n3 0 1 2\n"), "vertex 3 is in no face"));
  EXPECT_TRUE(contains(read_error("nofaces.off", "OFF\n3 0 0\n" + tri), "no faces"));
  EXPECT_TRUE(contains(read_error("twoverts.off", "OFF\n3 1 0\n" + tri + "2 0 1\n"), "fewer than 3"));
  // three triangles on the edge (0, 1)
  EXPECT_TRUE(contains(read_error("nonmanifold.off", "OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n3 0 1 2\n3 1 0 3\n3 0 1 4\n"),
                       "more than two faces"));
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
    EXPECT_TRUE(contains(read_error("moebius.off", moebius), "not orientable"));
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
  for(const auto& [name, faces] : {std::pair<std::string, std::size_t>{"cow.off", 5804}, {"elephant.off", 5558},
                                    {"colored_tetra.ply", 4}}) {
    Mesh m;
    ASSERT_NO_THROW(lapmesh::io::read_triangle_mesh(cgal_mesh(name), m)) << name;
    EXPECT_EQ(num_faces(m), faces) << name;
  }
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
    try {
      read("bad_nonmanifold_edge.off", m);
      ADD_FAILURE() << "a non-manifold edge was accepted";
    } catch(const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("non-manifold"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("face 2: edge (0, 1)"), std::string::npos) << e.what();
    }
  }
  {
    Mesh m;
    const lapmesh::io::Soup_report r = read("flipped_face.off", m);
    EXPECT_EQ(r.flipped_faces, 1u);
    EXPECT_NEAR(CGAL::Polygon_mesh_processing::area(m), 1.0, 1e-15);
  }
}
