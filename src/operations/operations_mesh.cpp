// Operations on meshes as files and arrays, and the curvature operation.
#include "operations.h"
#include "numbering.h"

#include <lapmesh/curvature.h>
#include <lapmesh/io.h>

namespace lapmesh_ops {

namespace {
void add_notes(const lapmesh::io::Soup_report& report, Loaded_mesh& loaded)
{
  auto note = [&](std::size_t count, const std::string& what) {
    if(count > 0) loaded.notes.push_back(std::to_string(count) + " " + what);
  };
  if(report.triangulated_polygons > 0)
    loaded.notes.push_back("triangulated " + std::to_string(report.triangulated_polygons) + " polygon(s)");
  if(report.flipped_faces > 0)
    loaded.notes.push_back("re-oriented " + std::to_string(report.flipped_faces) + " face(s) consistently");
  note(report.dropped_faces, "face(s) that use a vertex twice left out");
  note(report.zero_area_faces, "zero-area face(s)");
  note(report.isolated_vertices, "vertex(es) in no face (they keep their position; no curvature)");
  note(report.non_manifold_edges, "non-manifold edge(s)");
  if(report.non_orientable) loaded.notes.push_back("no consistent face orientation");
  if(!report.input_vertex.empty())
    loaded.notes.push_back("non-manifold: faces stored apart and welded by vertex number");
}

void attach_numbering(const std::vector<std::size_t>& input_vertex, Mesh& mesh)
{
  if(input_vertex.empty()) return;
  auto map = mesh.add_property_map<Mesh::Vertex_index, int>(input_vertex_property(), -1).first;
  for(Mesh::Vertex_index v : mesh.vertices()) map[v] = int(input_vertex[std::size_t(v)]);
}
} // namespace

Loaded_mesh load_mesh(const std::string& path)
{
  Loaded_mesh loaded;
  const lapmesh::io::Soup_report report = lapmesh::io::read_triangle_mesh(path, loaded.mesh);
  attach_numbering(report.input_vertex, loaded.mesh);
  add_notes(report, loaded);
  return loaded;
}

Loaded_mesh mesh_from_soup(const lapmesh::io::Polygon_soup& soup)
{
  Loaded_mesh loaded;
  lapmesh::io::Soup_report report;
  const auto triangles = lapmesh::io::soup_to_triangles(soup, &report);
  lapmesh::io::triangles_to_mesh(soup, triangles, loaded.mesh, &report.input_vertex);
  attach_numbering(report.input_vertex, loaded.mesh);
  add_notes(report, loaded);
  return loaded;
}

const std::vector<std::string>& mesh_output_formats()
{
  static const std::vector<std::string> formats = {"off", "obj", "ply", "stl"};
  return formats;
}

void write_mesh(const std::string& path, const Mesh& mesh,
                const std::vector<std::pair<std::string, std::vector<double>>>& scalars,
                const std::vector<lapmesh::Rgb>& colors)
{
  const auto [P, tris] = with_numbering(mesh, [&](const auto& np) { return lapmesh::io::mesh_arrays(mesh, np); });
  lapmesh::io::Vertex_attributes attributes;
  attributes.scalars = scalars;
  attributes.colors = colors;
  lapmesh::io::write_mesh(path, P, tris, attributes);
}

void write_text(const std::string& path, const std::function<void(std::ostream&)>& write)
{
  lapmesh::io::write_atomically(path, write);
}

void put_double(std::ostream& os, double x) { lapmesh::io::put_double(os, x); }

std::string extension_of(const std::string& path) { return lapmesh::io::extension_of(path); }

lapmesh::Vertex_vectors positions(const Mesh& mesh)
{
  return with_numbering(mesh, [&](const auto& np) { return lapmesh::io::mesh_arrays(mesh, np).first; });
}

void set_positions(Mesh& mesh, const lapmesh::Vertex_vectors& P)
{
  const auto [map, welded] = mesh.property_map<Mesh::Vertex_index, int>(input_vertex_property());
  for(Mesh::Vertex_index v : mesh.vertices()) {
    const Eigen::Index i = welded ? Eigen::Index(map[v]) : Eigen::Index(std::size_t(v));
    mesh.point(v) = Kernel::Point_3(P(i, 0), P(i, 1), P(i, 2));
  }
}

Triangles triangles(const Mesh& mesh)
{
  return with_numbering(mesh, [&](const auto& np) { return lapmesh::io::mesh_arrays(mesh, np).second; });
}

std::size_t vertex_count(const Mesh& mesh)
{
  const auto [map, welded] = mesh.property_map<Mesh::Vertex_index, int>(input_vertex_property());
  if(!welded) return num_vertices(mesh);
  int n = 0;
  for(Mesh::Vertex_index v : mesh.vertices()) n = std::max(n, map[v] + 1);
  return std::size_t(n);
}

std::vector<double> displacement(const Mesh& from, const Mesh& to)
{
  const Eigen::VectorXd d = (positions(to) - positions(from)).rowwise().norm();
  return {d.data(), d.data() + d.size()};
}

lapmesh::Vertex_curvatures curvature(const Mesh& mesh, const Curvature_settings& settings)
{
  namespace LP = lapmesh::parameters;
  return with_numbering(mesh, [&](const auto& np) {
    return lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(
      mesh, LP::mollification_factor(settings.mollification,
                                     LP::vertex_area(settings.area, LP::laplacian(settings.laplacian, np))));
  });
}

} // namespace lapmesh_ops
