// lapmesh — reading and writing triangle meshes, with diagnostics a user can act on.
//
// Reading. OFF and OBJ are parsed by lapmesh itself (one pass over the file in memory, with
// line numbers in every error; CGAL's generic reader goes through its repairing polygon-soup
// path, which ANCHORS.md measured at 19.8 s for a 1M-vertex OFF). PLY and STL (ASCII and
// binary) go through CGAL's soup readers. STL has no shared vertices: they are merged by
// exact position in order of first appearance. The soup is then validated (finite
// coordinates, index ranges, every vertex in a face, no zero-area face, manifold edges),
// polygons with more than three vertices are triangulated by ear clipping, faces are
// re-oriented consistently when the file mixes orientations, and the mesh is built with the
// input vertex order.
//
// Writing. OFF (COFF with colours), PLY (ASCII, with per-vertex double properties and
// colours), OBJ and STL, every number with 17 significant digits. Writes are atomic: the
// data goes to a temporary file in the destination directory, renamed over the target only
// when complete, so a failure never leaves a partial file.
#ifndef LAPMESH_IO_H
#define LAPMESH_IO_H

#include <lapmesh/colormap.h>
#include <lapmesh/errors.h>
#include <lapmesh/laplacian.h>

#include <CGAL/IO/PLY.h>
#include <CGAL/IO/STL.h>
#include <CGAL/boost/graph/Euler_operations.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <queue>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <unistd.h>

namespace lapmesh {

/// A file cannot be read or written, or its content is malformed. what() does not repeat
/// the file name: callers prefix it ("cow.off: line 12: ...").
class Io_error : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

namespace io {

/// A mesh as read from a file, before triangulation and validation.
struct Polygon_soup
{
  std::vector<std::array<double, 3>> points;       ///< vertex positions, in file order
  std::vector<std::vector<std::size_t>> polygons;  ///< faces as indices into `points`
};

/// The lower-case extension of a path without the dot ("off", "ply", ...).
inline std::string extension_of(const std::string& path)
{
  std::string e = std::filesystem::path(path).extension().string();
  if(!e.empty() && e[0] == '.') e.erase(0, 1);
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

/// @brief tells whether `ext` (lower case, without the dot, as from extension_of()) is a format lapmesh reads and writes.
inline bool is_supported_mesh_extension(const std::string& ext)
{
  return ext == "off" || ext == "obj" || ext == "ply" || ext == "stl";
}

namespace internal {

inline std::string read_whole_file(const std::string& path)
{
  std::error_code ec;
  if(!std::filesystem::exists(path, ec)) throw Io_error("no such file");
  if(std::filesystem::is_directory(path, ec)) throw Io_error("is a directory, not a mesh file");
  std::ifstream in(path, std::ios::binary);
  if(!in) throw Io_error("cannot open the file for reading");
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if(in.bad()) throw Io_error("read error");
  return data;
}

/// Line-oriented tokenizer over a buffer, skipping '#' comments and blank lines.
class Line_reader
{
public:
  explicit Line_reader(const std::string& data) : m_p(data.data()), m_end(data.data() + data.size()) {}

  /// Advances to the next non-empty line (comments stripped); false at the end of the data.
  bool next_line()
  {
    while(m_p < m_end) {
      const char* eol = static_cast<const char*>(std::memchr(m_p, '\n', std::size_t(m_end - m_p)));
      if(!eol) eol = m_end;
      ++m_line;
      m_cur = m_p;
      m_cur_end = eol;
      m_p = eol < m_end ? eol + 1 : m_end;
      const char* hash = static_cast<const char*>(std::memchr(m_cur, '#', std::size_t(m_cur_end - m_cur)));
      if(hash) m_cur_end = hash;
      skip_space();
      if(m_cur < m_cur_end) return true;
    }
    return false;
  }
  bool at_line_end()
  {
    skip_space();
    return m_cur >= m_cur_end;
  }
  /// The next whitespace-separated token of the current line (empty at its end).
  std::string_view token()
  {
    skip_space();
    const char* b = m_cur;
    while(m_cur < m_cur_end && !is_space(*m_cur)) ++m_cur;
    return std::string_view(b, std::size_t(m_cur - b));
  }
  bool read_double(double& x)
  {
    const std::string_view t = token();
    if(t.empty()) return false;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), x);
    if(r.ec == std::errc() && r.ptr == t.data() + t.size()) return true;
    // from_chars rejects "+1.0" and some spellings of inf/nan; accept them as strtod does.
    std::string s(t);
    char* e = nullptr;
    x = std::strtod(s.c_str(), &e);
    return e && *e == '\0' && e != s.c_str();
  }
  template <typename Integer>
  bool read_integer(Integer& x)
  {
    const std::string_view t = token();
    if(t.empty()) return false;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), x);
    return r.ec == std::errc() && r.ptr == t.data() + t.size();
  }
  std::size_t line() const { return m_line; }
  [[noreturn]] void fail(const std::string& what) const
  {
    throw Io_error("line " + std::to_string(m_line) + ": " + what);
  }

private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
  void skip_space()
  {
    while(m_cur < m_cur_end && is_space(*m_cur)) ++m_cur;
  }
  const char* m_p;
  const char* m_end;
  const char* m_cur = nullptr;
  const char* m_cur_end = nullptr;
  std::size_t m_line = 0;
};

inline Polygon_soup parse_off(const std::string& data)
{
  Line_reader r(data);
  if(!r.next_line()) throw Io_error("empty file: no OFF header");
  std::string header(r.token());
  // [ST][C][N][4][n]OFF; lapmesh reads 3D positions and skips the optional per-vertex fields.
  if(header.size() < 3 || header.compare(header.size() - 3, 3, "OFF") != 0)
    r.fail("missing OFF header (found '" + header + "')");
  if(header.find('4') != std::string::npos || header.find('n') != std::string::npos)
    r.fail("only 3D OFF files are supported (header '" + header + "')");
  if(!r.at_line_end()) {
    const std::string_view t = r.token();
    if(t == "BINARY") r.fail("binary OFF is not supported; convert it to ASCII OFF or PLY");
    r = Line_reader(data);  // counts on the header line: re-read it and skip the keyword
    r.next_line();
    r.token();
  } else if(!r.next_line()) {
    r.fail("truncated file: missing the vertex, face and edge counts");
  }
  long long nv = -1, nf = -1;
  if(!r.read_integer(nv) || !r.read_integer(nf) || nv < 0 || nf < 0)
    r.fail("bad counts line: expected the number of vertices, faces and edges");
  const bool has_texture = header.find("ST") != std::string::npos;
  (void)has_texture;

  Polygon_soup soup;
  soup.points.resize(std::size_t(nv));
  for(long long i = 0; i < nv; ++i) {
    if(!r.next_line())
      throw Io_error("truncated file: expected " + std::to_string(nv) + " vertices, found " + std::to_string(i));
    auto& p = soup.points[std::size_t(i)];
    if(!r.read_double(p[0]) || !r.read_double(p[1]) || !r.read_double(p[2]))
      r.fail("vertex " + std::to_string(i) + ": expected three coordinates");
  }
  soup.polygons.resize(std::size_t(nf));
  for(long long f = 0; f < nf; ++f) {
    if(!r.next_line())
      throw Io_error("truncated file: expected " + std::to_string(nf) + " faces, found " + std::to_string(f));
    long long k = 0;
    if(!r.read_integer(k) || k < 1) r.fail("face " + std::to_string(f) + ": bad vertex count");
    auto& poly = soup.polygons[std::size_t(f)];
    poly.resize(std::size_t(k));
    for(long long a = 0; a < k; ++a) {
      long long idx = -1;
      if(!r.read_integer(idx))
        r.fail("face " + std::to_string(f) + ": expected " + std::to_string(k) + " vertex indices");
      if(idx < 0 || idx >= nv)
        r.fail("face " + std::to_string(f) + ": vertex index " + std::to_string(idx) + " out of range [0, " +
               std::to_string(nv) + ")");
      poly[std::size_t(a)] = std::size_t(idx);
    }
    // Anything after the indices is a face colour: ignored.
  }
  return soup;
}

inline Polygon_soup parse_obj(const std::string& data)
{
  Line_reader r(data);
  Polygon_soup soup;
  while(r.next_line()) {
    const std::string_view kw = r.token();
    if(kw == "v") {
      std::array<double, 3> p;
      if(!r.read_double(p[0]) || !r.read_double(p[1]) || !r.read_double(p[2]))
        r.fail("vertex " + std::to_string(soup.points.size()) + ": expected three coordinates");
      soup.points.push_back(p);
    } else if(kw == "f") {
      std::vector<std::size_t> poly;
      for(std::string_view t = r.token(); !t.empty(); t = r.token()) {
        const std::string_view head = t.substr(0, t.find('/'));  // "v/vt/vn": keep v
        long long idx = 0;
        const auto res = std::from_chars(head.data(), head.data() + head.size(), idx);
        if(res.ec != std::errc() || res.ptr != head.data() + head.size() || idx == 0)
          r.fail("face " + std::to_string(soup.polygons.size()) + ": bad vertex reference '" + std::string(t) + "'");
        const long long n = static_cast<long long>(soup.points.size());
        const long long zero_based = idx > 0 ? idx - 1 : n + idx;  // negative: relative to the end
        if(zero_based < 0 || zero_based >= n)
          r.fail("face " + std::to_string(soup.polygons.size()) + ": vertex " + std::to_string(idx) +
                 " refers to a vertex not defined before it");
        poly.push_back(std::size_t(zero_based));
      }
      soup.polygons.push_back(std::move(poly));
    }
    // vt, vn, g, o, s, usemtl, mtllib, l, ...: not geometry lapmesh uses.
  }
  return soup;
}

inline Polygon_soup read_with_cgal(const std::string& path, const std::string& ext)
{
  using Point = CGAL::Simple_cartesian<double>::Point_3;
  std::vector<Point> points;
  std::vector<std::vector<std::size_t>> polygons;
  std::ifstream in(path, std::ios::binary);
  if(!in) throw Io_error("cannot open the file for reading");
  bool ok = false;
  if(ext == "ply") {
    ok = CGAL::IO::read_PLY(in, points, polygons, CGAL::parameters::verbose(false));
  } else {
    std::vector<std::array<std::size_t, 3>> triangles;
    ok = CGAL::IO::read_STL(in, points, triangles, CGAL::parameters::verbose(false));
    for(const auto& t : triangles) polygons.push_back({t[0], t[1], t[2]});
  }
  if(!ok) throw Io_error("malformed or truncated " + std::string(ext == "ply" ? "PLY" : "STL") + " file");
  Polygon_soup soup;
  soup.points.reserve(points.size());
  for(const Point& p : points) soup.points.push_back({p.x(), p.y(), p.z()});
  for(auto& poly : polygons)
    for(std::size_t idx : poly)
      if(idx >= points.size())
        throw Io_error("a face refers to vertex " + std::to_string(idx) + ", out of range [0, " +
                       std::to_string(points.size()) + ")");
  soup.polygons = std::move(polygons);
  return soup;
}

/// Ear clipping of a simple polygon (possibly non-convex, roughly planar), projected on the
/// plane of its Newell normal. Appends triangles to `out`; false if no ear can be found.
inline bool triangulate_polygon(const std::vector<std::size_t>& poly,
                                const std::vector<std::array<double, 3>>& pts,
                                std::vector<std::array<std::size_t, 3>>& out)
{
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for(std::size_t a = 0; a < poly.size(); ++a) {
    const auto& p = pts[poly[a]];
    const auto& q = pts[poly[(a + 1) % poly.size()]];
    normal += Eigen::Vector3d((p[1] - q[1]) * (p[2] + q[2]), (p[2] - q[2]) * (p[0] + q[0]), (p[0] - q[0]) * (p[1] + q[1]));
  }
  if(!(normal.norm() > 0)) return false;
  normal.normalize();
  const Eigen::Vector3d u = normal.unitOrthogonal(), v = normal.cross(u);
  std::vector<Eigen::Vector2d> xy;
  for(std::size_t idx : poly) {
    const Eigen::Vector3d p(pts[idx][0], pts[idx][1], pts[idx][2]);
    xy.emplace_back(p.dot(u), p.dot(v));
  }
  auto cross2 = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
  };
  std::vector<std::size_t> ring(poly.size());
  for(std::size_t a = 0; a < ring.size(); ++a) ring[a] = a;
  while(ring.size() > 3) {
    bool clipped = false;
    for(std::size_t a = 0; a < ring.size() && !clipped; ++a) {
      const std::size_t i0 = ring[(a + ring.size() - 1) % ring.size()], i1 = ring[a], i2 = ring[(a + 1) % ring.size()];
      if(cross2(xy[i0], xy[i1], xy[i2]) <= 0) continue;  // reflex or flat corner
      bool contains = false;
      for(std::size_t k : ring) {
        if(k == i0 || k == i1 || k == i2) continue;
        if(cross2(xy[i0], xy[i1], xy[k]) >= 0 && cross2(xy[i1], xy[i2], xy[k]) >= 0 && cross2(xy[i2], xy[i0], xy[k]) >= 0) {
          contains = true;
          break;
        }
      }
      if(contains) continue;
      out.push_back({poly[i0], poly[i1], poly[i2]});
      ring.erase(ring.begin() + std::ptrdiff_t(a));
      clipped = true;
    }
    if(!clipped) return false;
  }
  out.push_back({poly[ring[0]], poly[ring[1]], poly[ring[2]]});
  return true;
}

/// Flips faces so that neighbours agree in orientation (breadth-first over each connected
/// component; the first face of a component keeps its orientation). Returns the number of
/// flipped faces; throws Mesh_error for a non-manifold edge or a non-orientable surface.
inline std::size_t orient_consistently(std::vector<std::array<std::size_t, 3>>& tris,
                                       const std::vector<std::size_t>& source_face)
{
  const std::size_t m = tris.size();
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> edge_faces;
  edge_faces.reserve(3 * m);
  auto key = [](std::size_t a, std::size_t b) { return std::uint64_t(std::min(a, b)) << 32 | std::uint64_t(std::max(a, b)); };
  for(std::size_t f = 0; f < m; ++f)
    for(int a = 0; a < 3; ++a) {
      auto& faces = edge_faces[key(tris[f][a], tris[f][(a + 1) % 3])];
      faces.push_back(f);
      if(faces.size() > 2)
        throw Mesh_error("face " + std::to_string(source_face[f]) + ": edge (" + std::to_string(tris[f][a]) + ", " +
                           std::to_string(tris[f][(a + 1) % 3]) + ") has more than two faces (non-manifold)",
                         Mesh_error::Element::face, std::int64_t(source_face[f]));
    }
  auto has_directed = [](const std::array<std::size_t, 3>& t, std::size_t a, std::size_t b) {
    return (t[0] == a && t[1] == b) || (t[1] == a && t[2] == b) || (t[2] == a && t[0] == b);
  };
  std::vector<char> state(m, 0);  // 0 unvisited, 1 visited
  std::size_t flipped = 0;
  for(std::size_t seed = 0; seed < m; ++seed) {
    if(state[seed]) continue;
    state[seed] = 1;
    std::queue<std::size_t> queue;
    queue.push(seed);
    while(!queue.empty()) {
      const std::size_t f = queue.front();
      queue.pop();
      for(int a = 0; a < 3; ++a) {
        const std::size_t p = tris[f][a], q = tris[f][(a + 1) % 3];
        for(std::size_t g : edge_faces[key(p, q)]) {
          if(g == f) continue;
          const bool agrees = has_directed(tris[g], q, p);
          if(state[g]) {
            if(!agrees)
              throw Mesh_error("face " + std::to_string(source_face[g]) +
                                 ": the surface is not orientable (no consistent face orientation exists)",
                               Mesh_error::Element::face, std::int64_t(source_face[g]));
            continue;
          }
          if(!agrees) {
            std::swap(tris[g][1], tris[g][2]);
            ++flipped;
          }
          state[g] = 1;
          queue.push(g);
        }
      }
    }
  }
  return flipped;
}

} // namespace internal

/// Reads a polygon soup from an OFF, OBJ, PLY or STL file (by extension, case-insensitive).
/// Throws Io_error with a message naming the line or element (not the file).
inline Polygon_soup read_polygon_soup(const std::string& path)
{
  const std::string ext = extension_of(path);
  if(!is_supported_mesh_extension(ext))
    throw Io_error("unsupported mesh format '." + ext + "' (expected .off, .obj, .ply or .stl)");
  if(ext == "off") return internal::parse_off(internal::read_whole_file(path));
  if(ext == "obj") return internal::parse_obj(internal::read_whole_file(path));
  {
    std::error_code ec;
    if(!std::filesystem::exists(path, ec)) throw Io_error("no such file");
    if(std::filesystem::is_directory(path, ec)) throw Io_error("is a directory, not a mesh file");
  }
  return internal::read_with_cgal(path, ext);
}

/// What soup_to_triangles() did besides copying.
struct Soup_report
{
  std::size_t triangulated_polygons = 0;  ///< input faces with more than 3 vertices
  std::size_t flipped_faces = 0;          ///< faces re-oriented for consistency
};

/// Validates a soup and turns it into consistently oriented triangles over the same vertices.
/// Throws Mesh_error naming the vertex or face (input face index) for: a non-finite
/// coordinate, an empty mesh, a face with fewer than 3 or repeated vertices, a polygon that
/// cannot be triangulated, a zero-area face, a vertex in no face, a non-manifold edge or a
/// non-orientable surface.
inline std::vector<std::array<std::size_t, 3>> soup_to_triangles(const Polygon_soup& soup, Soup_report* report = nullptr)
{
  const std::size_t n = soup.points.size();
  for(std::size_t i = 0; i < n; ++i)
    for(double c : soup.points[i])
      if(!std::isfinite(c))
        throw Mesh_error("vertex " + std::to_string(i) + " has a non-finite coordinate", Mesh_error::Element::vertex,
                         std::int64_t(i));
  if(soup.polygons.empty()) throw Mesh_error("the mesh has no faces");

  std::vector<std::array<std::size_t, 3>> tris;
  std::vector<std::size_t> source;
  tris.reserve(soup.polygons.size());
  Soup_report rep;
  for(std::size_t f = 0; f < soup.polygons.size(); ++f) {
    const auto& poly = soup.polygons[f];
    auto fail = [f](const std::string& what) {
      throw Mesh_error("face " + std::to_string(f) + " " + what, Mesh_error::Element::face, std::int64_t(f));
    };
    if(poly.size() < 3) fail("has fewer than 3 vertices");
    for(std::size_t idx : poly)
      if(idx >= n) fail("has vertex index " + std::to_string(idx) + " out of range [0, " + std::to_string(n) + ")");
    std::vector<std::size_t> sorted = poly;
    std::sort(sorted.begin(), sorted.end());
    if(std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) fail("uses the same vertex twice");
    const std::size_t before = tris.size();
    if(poly.size() == 3) {
      tris.push_back({poly[0], poly[1], poly[2]});
    } else {
      ++rep.triangulated_polygons;
      if(!internal::triangulate_polygon(poly, soup.points, tris))
        fail("is a polygon with " + std::to_string(poly.size()) + " vertices that cannot be triangulated");
    }
    for(std::size_t k = before; k < tris.size(); ++k) {
      source.push_back(f);
      const auto& t = tris[k];
      const Eigen::Vector3d p0(soup.points[t[0]].data()), p1(soup.points[t[1]].data()), p2(soup.points[t[2]].data());
      const double longest = std::max({(p1 - p0).squaredNorm(), (p2 - p1).squaredNorm(), (p0 - p2).squaredNorm()});
      if(!((p1 - p0).cross(p2 - p0).norm() > lapmesh::internal::degenerate_face_tolerance * longest))
        fail("has zero area");
    }
  }
  std::vector<char> used(n, 0);
  for(const auto& t : tris)
    for(std::size_t v : t) used[v] = 1;
  for(std::size_t i = 0; i < n; ++i)
    if(!used[i])
      throw Mesh_error("vertex " + std::to_string(i) + " is in no face", Mesh_error::Element::vertex, std::int64_t(i));

  // Fast path: lapmesh's topology check accepts consistently oriented manifold meshes.
  std::vector<lapmesh::internal::Index> flat;
  flat.reserve(3 * tris.size());
  for(const auto& t : tris)
    for(std::size_t v : t) flat.push_back(lapmesh::internal::Index(v));
  try {
    lapmesh::internal::build_topology(lapmesh::internal::Index(n), std::move(flat));
  } catch(const Mesh_error&) {
    // Mixed orientations can be repaired without touching the vertices; a non-manifold edge
    // or a non-orientable surface cannot, and orient_consistently() says which face.
    rep.flipped_faces = internal::orient_consistently(tris, source);
  }
  if(report) *report = rep;
  return tris;
}

/// Builds `g` (emptied first) from validated triangles, vertex i = point i.
/// Throws Mesh_error if a face cannot be added (a non-manifold vertex).
template <typename MutableFaceGraph>
void triangles_to_mesh(const Polygon_soup& soup, const std::vector<std::array<std::size_t, 3>>& tris, MutableFaceGraph& g)
{
  using GT = boost::graph_traits<MutableFaceGraph>;
  using Point = typename boost::property_traits<
    typename boost::property_map<MutableFaceGraph, CGAL::vertex_point_t>::type>::value_type;
  CGAL::clear(g);
  auto vpm = get(CGAL::vertex_point, g);
  std::vector<typename GT::vertex_descriptor> vs;
  vs.reserve(soup.points.size());
  for(const auto& p : soup.points) {
    vs.push_back(add_vertex(g));
    put(vpm, vs.back(), Point(p[0], p[1], p[2]));
  }
  for(std::size_t f = 0; f < tris.size(); ++f) {
    const std::array<typename GT::vertex_descriptor, 3> face = {vs[tris[f][0]], vs[tris[f][1]], vs[tris[f][2]]};
    if(CGAL::Euler::add_face(face, g) == GT::null_face())
      throw Mesh_error("triangle " + std::to_string(f) + " (" + std::to_string(tris[f][0]) + ", " +
                         std::to_string(tris[f][1]) + ", " + std::to_string(tris[f][2]) +
                         ") makes a vertex non-manifold (two fans of faces touching at one vertex)",
                       Mesh_error::Element::face, std::int64_t(f));
  }
}

/// Reads a triangle mesh (any MutableFaceGraph) from OFF/OBJ/PLY/STL, validating it and
/// keeping the input vertex order. Throws Io_error or Mesh_error.
template <typename MutableFaceGraph>
Soup_report read_triangle_mesh(const std::string& path, MutableFaceGraph& g)
{
  const Polygon_soup soup = read_polygon_soup(path);
  Soup_report report;
  const auto tris = soup_to_triangles(soup, &report);
  triangles_to_mesh(soup, tris, g);
  return report;
}

// ---------------------------------------------------------------------------------------
// Writing

/// Per-vertex data written with a mesh: named double properties (PLY only) and colours
/// (PLY, COFF).
struct Vertex_attributes
{
  std::vector<std::pair<std::string, std::vector<double>>> scalars;  ///< (property name, one value per vertex)
  std::vector<Rgb> colors;  ///< one colour per vertex, or empty for none
};

/// Writes through a temporary file in the destination directory and renames it over
/// `path` when `write` has succeeded; removes the temporary file on any failure.
inline void write_atomically(const std::string& path, const std::function<void(std::ostream&)>& write)
{
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if(!fs::is_directory(dir, ec)) throw Io_error("cannot write: directory '" + dir.string() + "' does not exist");
  if(fs::is_directory(target, ec)) throw Io_error("cannot write: it is a directory");
  const fs::path tmp = dir / ("." + target.filename().string() + ".tmp." + std::to_string(::getpid()));
  try {
    {
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      if(!out) throw Io_error("cannot write: permission denied or read-only location");
      write(out);
      out.flush();
      if(!out) throw Io_error("write error (disk full?)");
    }
    fs::rename(tmp, target, ec);
    if(ec) throw Io_error("cannot replace the file: " + ec.message());
  } catch(...) {
    fs::remove(tmp, ec);
    throw;
  }
}

/// Formats a double with 17 significant digits (round-trips exactly).
inline void put_double(std::ostream& os, double x)
{
  char buf[32];
  const int len = std::snprintf(buf, sizeof buf, "%.17g", x);
  os.write(buf, len);
}

/// Writes vertices P (n x 3) and triangles to the stream `os` in `format` ("off", "ply",
/// "obj" or "stl", lower-case), exactly as write_mesh() writes a file of that extension.
inline void write_mesh(std::ostream& os, const std::string& format, const Vertex_vectors& P,
                       const std::vector<std::array<std::size_t, 3>>& tris, const Vertex_attributes& attributes = {})
{
  const std::string& ext = format;
  if(!is_supported_mesh_extension(ext))
    throw Io_error("unsupported output format '." + ext + "' (expected .off, .obj, .ply or .stl)");
  const std::size_t n = std::size_t(P.rows());
  const bool colors = !attributes.colors.empty();
  if(colors && attributes.colors.size() != n) throw std::invalid_argument("one colour per vertex expected");
  for(const auto& s : attributes.scalars)
    if(s.second.size() != n) throw std::invalid_argument("one value per vertex expected for " + s.first);

  {
    auto put_point = [&](std::size_t i) {
      put_double(os, P(Eigen::Index(i), 0)); os << ' ';
      put_double(os, P(Eigen::Index(i), 1)); os << ' ';
      put_double(os, P(Eigen::Index(i), 2));
    };
    if(ext == "off") {
      os << (colors ? "COFF\n" : "OFF\n") << n << ' ' << tris.size() << " 0\n";
      for(std::size_t i = 0; i < n; ++i) {
        put_point(i);
        if(colors) {
          const Rgb& c = attributes.colors[i];
          os << ' ' << int(c.r) << ' ' << int(c.g) << ' ' << int(c.b) << " 255";
        }
        os << '\n';
      }
      for(const auto& t : tris) os << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
    } else if(ext == "ply") {
      os << "ply\nformat ascii 1.0\ncomment written by lapmesh\nelement vertex " << n
         << "\nproperty double x\nproperty double y\nproperty double z\n";
      for(const auto& s : attributes.scalars) os << "property double " << s.first << '\n';
      if(colors) os << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
      os << "element face " << tris.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
      for(std::size_t i = 0; i < n; ++i) {
        put_point(i);
        for(const auto& s : attributes.scalars) {
          os << ' ';
          put_double(os, s.second[i]);
        }
        if(colors) {
          const Rgb& c = attributes.colors[i];
          os << ' ' << int(c.r) << ' ' << int(c.g) << ' ' << int(c.b);
        }
        os << '\n';
      }
      for(const auto& t : tris) os << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
    } else if(ext == "obj") {
      for(std::size_t i = 0; i < n; ++i) {
        os << "v ";
        put_point(i);
        os << '\n';
      }
      for(const auto& t : tris) os << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
    } else {  // stl
      os << "solid lapmesh\n";
      for(const auto& t : tris) {
        const Eigen::Vector3d a = P.row(Eigen::Index(t[0])), b = P.row(Eigen::Index(t[1])), c = P.row(Eigen::Index(t[2]));
        Eigen::Vector3d nrm = (b - a).cross(c - a);
        if(nrm.norm() > 0) nrm.normalize();
        os << "facet normal ";
        put_double(os, nrm.x()); os << ' '; put_double(os, nrm.y()); os << ' '; put_double(os, nrm.z());
        os << "\nouter loop\n";
        for(std::size_t v : t) {
          os << "vertex ";
          put_point(v);
          os << '\n';
        }
        os << "endloop\nendfacet\n";
      }
      os << "endsolid lapmesh\n";
    }
  }
}

/// Writes vertices P (n x 3) and triangles to `path` in the format of its extension
/// (atomically: a failure leaves no partial file).
inline void write_mesh(const std::string& path, const Vertex_vectors& P,
                       const std::vector<std::array<std::size_t, 3>>& tris, const Vertex_attributes& attributes = {})
{
  const std::string ext = extension_of(path);
  if(!is_supported_mesh_extension(ext))
    throw Io_error("unsupported output format '." + ext + "' (expected .off, .obj, .ply or .stl)");
  const std::size_t n = std::size_t(P.rows());
  if(!attributes.colors.empty() && attributes.colors.size() != n) throw std::invalid_argument("one colour per vertex expected");
  for(const auto& s : attributes.scalars)
    if(s.second.size() != n) throw std::invalid_argument("one value per vertex expected for " + s.first);
  write_atomically(path, [&](std::ostream& os) { write_mesh(os, ext, P, tris, attributes); });
}

/// The triangles of an extracted mesh, in face order, as the writers take them.
inline std::vector<std::array<std::size_t, 3>> triangle_list(const lapmesh::internal::Mesh_topology& t)
{
  std::vector<std::array<std::size_t, 3>> tris(std::size_t(t.num_faces));
  for(std::size_t f = 0; f < tris.size(); ++f)
    for(int a = 0; a < 3; ++a) tris[f][a] = std::size_t(t.triangles[3 * f + a]);
  return tris;
}

/// Positions and triangles of a face graph in vertex-index order (the order in which
/// triangles_to_mesh() added the vertices, for meshes it built). Reads the arrays only: no
/// topology is built (writing a mesh does not need one).
template <typename FaceGraph>
std::pair<Vertex_vectors, std::vector<std::array<std::size_t, 3>>> mesh_arrays(const FaceGraph& g)
{
  auto arrays = lapmesh::internal::extract_arrays(g, CGAL::parameters::default_values());
  std::vector<std::array<std::size_t, 3>> tris(arrays.triangles.size() / 3);
  for(std::size_t f = 0; f < tris.size(); ++f)
    for(std::size_t c = 0; c < 3; ++c) tris[f][c] = std::size_t(arrays.triangles[3 * f + c]);
  return {std::move(arrays.positions), std::move(tris)};
}

} // namespace io
} // namespace lapmesh

#endif
