// lapmesh — reading and writing triangle meshes, with diagnostics a user can act on.
//
// Reading. OFF, OBJ, PLY (ASCII, binary little and big endian) and STL (ASCII and binary)
// are parsed by lapmesh itself (internal/io_parsers.h), from the file mapped in memory:
// only regular files are read, no count in a file is trusted before it is checked against
// the file's size, content after a complete OFF, PLY or STL is refused, and messages quote
// at most a short escaped excerpt of the file. STL has no shared vertices: they are merged
// by exact position in order of first appearance. The soup is then validated
// (internal/io_soup.h: finite coordinates, index ranges, coordinates in the representable
// range; zero-area faces, vertices in no face and non-manifold edges are counted, not
// refused), polygons with more than three vertices are triangulated by ear clipping, faces
// are re-oriented consistently where the surface allows it, and the mesh is built with the
// input vertex order (a Surface_mesh of a manifold surface at once, as CGAL's add_face() would
// build it; otherwise face by face, with the input numbering to weld it, when a FaceGraph
// cannot hold it as it is).
//
// Writing. OFF (COFF with colours), PLY (ASCII, with per-vertex double properties and
// colours), OBJ and STL, every number with 17 significant digits (printf's "%.17g", formatted
// by std::to_chars into large blocks: internal/io_text_output.h). Writes are atomic: the
// data goes to a temporary file in the destination directory, renamed over the target only
// when complete, so a failure never leaves a partial file; temporary files that a killed
// lapmesh left behind are removed by the next write to that directory.
#ifndef LAPMESH_IO_H
#define LAPMESH_IO_H

#include <lapmesh/colormap.h>
#include <lapmesh/errors.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/shapes.h>

#include <lapmesh/internal/atomic_file.h>
#include <lapmesh/internal/io_input.h>
#include <lapmesh/internal/io_parsers.h>
#include <lapmesh/internal/io_soup.h>
#include <lapmesh/internal/io_text_output.h>
#include <lapmesh/internal/surface_mesh_builder.h>

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

#include <cerrno>
#include <csignal>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

namespace lapmesh {

namespace io {

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


/// Reads a polygon soup from an OFF, OBJ, PLY or STL file (by extension, case-insensitive).
/// Throws Io_error with a message naming the line or element (not the file).
inline Polygon_soup read_polygon_soup(const std::string& path)
{
  const std::string ext = extension_of(path);
  if(ext.empty()) throw Io_error("no file extension (expected .off, .obj, .ply or .stl)");
  if(!is_supported_mesh_extension(ext))
    throw Io_error("unsupported mesh format " + internal::excerpt("." + ext) + " (expected .off, .obj, .ply or .stl)");
  const internal::Mapped_file file(path);
  return internal::parse_mesh(file.view(), ext);
}

/// Builds `g` (emptied first) from validated triangles, vertex i = point i. A mesh that `g`
/// cannot hold as it is (a non-manifold edge or vertex, faces that disagree in
/// orientation) is stored with each face on vertices of its own, and `input_vertex` (when
/// given) receives the input vertex of every vertex of `g`, to weld them back through the
/// `vertex_index_map` named parameter; it is left empty otherwise. So is, when `input_vertex`
/// is given, a mesh that a Surface_mesh cannot be built for at once (not a manifold surface,
/// or `g` of another type) and that has vertices of very many faces
/// (internal::face_by_face_is_affordable()).
template <typename MutableFaceGraph>
void triangles_to_mesh(const Polygon_soup& soup, const std::vector<std::array<std::size_t, 3>>& tris, MutableFaceGraph& g,
                       std::vector<std::size_t>* input_vertex = nullptr)
{
  using GT = boost::graph_traits<MutableFaceGraph>;
  using Point = typename boost::property_traits<
    typename boost::property_map<MutableFaceGraph, CGAL::vertex_point_t>::type>::value_type;
  if(input_vertex) input_vertex->clear();
  // A Surface_mesh of a manifold surface is built at once: the same mesh as the faces added
  // one by one below, about twice as fast at a million vertices (doc/benchmarks-history.md).
  if constexpr(lapmesh::internal::is_surface_mesh<MutableFaceGraph>::value) {
    if(lapmesh::internal::build_manifold_surface_mesh(soup.points, tris, g)) return;
  }
  // add_face() finds each edge of a face by turning around its vertex: a vertex of d faces
  // costs it d^2 steps, so that one of very many faces would keep it busy far longer than any
  // computation on the mesh. Such a mesh, when it may be stored apart, is not added face by face.
  if(!input_vertex || lapmesh::internal::face_by_face_is_affordable(soup.points.size(), tris)) {
    CGAL::clear(g);
    if(lapmesh::internal::add_face_by_face(soup.points, tris, g)) return;
  }
  if(!input_vertex)
    throw Mesh_error("the mesh has non-manifold edges or vertices, or faces that disagree in orientation: it "
                     "can only be read with its faces stored apart (give triangles_to_mesh an input_vertex)");
  // Each face on vertices of its own, then the vertices in no face, in input order.
  CGAL::clear(g);
  auto vpm = get(CGAL::vertex_point, g);
  std::vector<char> in_face(soup.points.size(), 0);
  input_vertex->reserve(3 * tris.size());
  for(const auto& t : tris) {
    std::array<typename GT::vertex_descriptor, 3> face;
    for(int a = 0; a < 3; ++a) {
      face[a] = add_vertex(g);
      put(vpm, face[a], Point(soup.points[t[a]][0], soup.points[t[a]][1], soup.points[t[a]][2]));
      input_vertex->push_back(t[a]);
      in_face[t[a]] = 1;
    }
    CGAL::Euler::add_face(face, g);
  }
  for(std::size_t i = 0; i < soup.points.size(); ++i)
    if(!in_face[i]) {
      put(vpm, add_vertex(g), Point(soup.points[i][0], soup.points[i][1], soup.points[i][2]));
      input_vertex->push_back(i);
    }
}

/// Reads a triangle mesh (any MutableFaceGraph) from OFF/OBJ/PLY/STL, validating it and
/// keeping the input vertex order; a mesh `g` cannot hold as it is comes with its faces
/// stored apart and the report's `input_vertex` to weld them (triangles_to_mesh()).
/// Throws Io_error or Mesh_error.
template <typename MutableFaceGraph>
Soup_report read_triangle_mesh(const std::string& path, MutableFaceGraph& g)
{
  const Polygon_soup soup = read_polygon_soup(path);
  Soup_report report;
  const auto tris = soup_to_triangles(soup, &report);
  triangles_to_mesh(soup, tris, g, &report.input_vertex);
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
/// `path` when `write` has succeeded; removes the temporary file on any failure. Stale
/// temporary files of dead lapmesh processes in that directory are removed first.
/// Throws Io_error.
inline void write_atomically(const std::string& path, const std::function<void(std::ostream&)>& write)
{
  lapmesh::internal::write_file_atomically(path, write);
}

/// Formats a double with 17 significant digits (round-trips exactly), as printf's "%.17g".
inline void put_double(std::ostream& os, double x)
{
  char buf[internal::formatted_double_room];
  os.write(buf, internal::format_double(buf, x) - buf);
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

  internal::Text_output out(os);
  auto put_point = [&](std::size_t i) {
    out.put(P(Eigen::Index(i), 0));
    out.put(' ');
    out.put(P(Eigen::Index(i), 1));
    out.put(' ');
    out.put(P(Eigen::Index(i), 2));
  };
  auto put_color = [&](std::size_t i) {
    const Rgb& c = attributes.colors[i];
    for(int channel : {int(c.r), int(c.g), int(c.b)}) {
      out.put(' ');
      out.put(channel);
    }
  };
  auto put_faces = [&](const char* prefix, std::size_t base) {
    for(const auto& t : tris) {
      out.put(prefix);
      out.put(t[0] + base);
      out.put(' ');
      out.put(t[1] + base);
      out.put(' ');
      out.put(t[2] + base);
      out.put('\n');
    }
  };
  if(ext == "off") {
    out.put(colors ? "COFF\n" : "OFF\n");
    out.put(n);
    out.put(' ');
    out.put(tris.size());
    out.put(" 0\n");
    for(std::size_t i = 0; i < n; ++i) {
      put_point(i);
      if(colors) {
        put_color(i);
        out.put(" 255");
      }
      out.put('\n');
    }
    put_faces("3 ", 0);
  } else if(ext == "ply") {
    out.put("ply\nformat ascii 1.0\ncomment written by lapmesh\nelement vertex ");
    out.put(n);
    out.put("\nproperty double x\nproperty double y\nproperty double z\n");
    for(const auto& s : attributes.scalars) out.put("property double " + s.first + '\n');
    if(colors) out.put("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    out.put("element face ");
    out.put(tris.size());
    out.put("\nproperty list uchar int vertex_indices\nend_header\n");
    for(std::size_t i = 0; i < n; ++i) {
      put_point(i);
      for(const auto& s : attributes.scalars) {
        out.put(' ');
        out.put(s.second[i]);
      }
      if(colors) put_color(i);
      out.put('\n');
    }
    put_faces("3 ", 0);
  } else if(ext == "obj") {
    for(std::size_t i = 0; i < n; ++i) {
      out.put("v ");
      put_point(i);
      out.put('\n');
    }
    put_faces("f ", 1);
  } else {  // stl
    out.put("solid lapmesh\n");
    for(const auto& t : tris) {
      const Eigen::Vector3d a = P.row(Eigen::Index(t[0])), b = P.row(Eigen::Index(t[1])), c = P.row(Eigen::Index(t[2]));
      Eigen::Vector3d nrm = (b - a).cross(c - a);
      if(nrm.norm() > 0) nrm.normalize();
      out.put("facet normal ");
      out.put(nrm.x());
      out.put(' ');
      out.put(nrm.y());
      out.put(' ');
      out.put(nrm.z());
      out.put("\nouter loop\n");
      for(std::size_t v : t) {
        out.put("vertex ");
        put_point(v);
        out.put('\n');
      }
      out.put("endloop\nendfacet\n");
    }
    out.put("endsolid lapmesh\n");
  }
  out.flush();
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
template <typename FaceGraph, typename NamedParameters = CGAL::parameters::Default_named_parameters>
std::pair<Vertex_vectors, std::vector<std::array<std::size_t, 3>>>
mesh_arrays(const FaceGraph& g, const NamedParameters& np = CGAL::parameters::default_values())
{
  auto arrays = lapmesh::internal::extract_arrays(g, np);
  std::vector<std::array<std::size_t, 3>> tris(arrays.triangles.size() / 3);
  for(std::size_t f = 0; f < tris.size(); ++f)
    for(std::size_t c = 0; c < 3; ++c) tris[f][c] = std::size_t(arrays.triangles[3 * f + c]);
  return {std::move(arrays.positions), std::move(tris)};
}

} // namespace io
} // namespace lapmesh

#endif
