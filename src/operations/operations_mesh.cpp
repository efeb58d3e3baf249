// Operations on meshes as files and arrays, and the curvature operation.
#include "operations.h"

#include <lapmesh/curvature.h>
#include <lapmesh/io.h>

namespace lapmesh_ops {

namespace {
void add_notes(const lapmesh::io::Soup_report& report, Loaded_mesh& loaded)
{
  if(report.triangulated_polygons > 0)
    loaded.notes.push_back("triangulated " + std::to_string(report.triangulated_polygons) + " polygon(s)");
  if(report.flipped_faces > 0)
    loaded.notes.push_back("re-oriented " + std::to_string(report.flipped_faces) + " face(s) consistently");
}
} // namespace

Loaded_mesh load_mesh(const std::string& path)
{
  Loaded_mesh loaded;
  add_notes(lapmesh::io::read_triangle_mesh(path, loaded.mesh), loaded);
  return loaded;
}

Loaded_mesh mesh_from_soup(const lapmesh::io::Polygon_soup& soup)
{
  Loaded_mesh loaded;
  lapmesh::io::Soup_report report;
  const auto triangles = lapmesh::io::soup_to_triangles(soup, &report);
  lapmesh::io::triangles_to_mesh(soup, triangles, loaded.mesh);
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
  const auto [P, tris] = lapmesh::io::mesh_arrays(mesh);
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

lapmesh::Vertex_vectors positions(const Mesh& mesh) { return lapmesh::io::mesh_arrays(mesh).first; }

void set_positions(Mesh& mesh, const lapmesh::Vertex_vectors& P)
{
  for(Mesh::Vertex_index v : mesh.vertices()) {
    const Eigen::Index i = Eigen::Index(std::size_t(v));
    mesh.point(v) = Kernel::Point_3(P(i, 0), P(i, 1), P(i, 2));
  }
}

Triangles triangles(const Mesh& mesh) { return lapmesh::io::mesh_arrays(mesh).second; }

std::vector<double> displacement(const Mesh& from, const Mesh& to)
{
  const Eigen::VectorXd d = (positions(to) - positions(from)).rowwise().norm();
  return {d.data(), d.data() + d.size()};
}

lapmesh::Vertex_curvatures curvature(const Mesh& mesh, const Curvature_settings& settings)
{
  namespace LP = lapmesh::parameters;
  return lapmesh::vertex_curvatures<CGAL::Parallel_if_available_tag>(
    mesh, LP::vertex_area(settings.area, LP::laplacian(settings.laplacian)));
}

} // namespace lapmesh_ops
