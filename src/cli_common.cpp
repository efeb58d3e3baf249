#include "cli_common.h"

#include <lapmesh/io.h>

#include <iostream>

namespace lapmesh_cli {

Mesh load_mesh(const std::string& path)
{
  Mesh mesh;
  try {
    const lapmesh::io::Soup_report report = lapmesh::io::read_triangle_mesh(path, mesh);
    if(report.triangulated_polygons > 0)
      std::cerr << path << ": note: triangulated " << report.triangulated_polygons << " polygon(s)\n";
    if(report.flipped_faces > 0)
      std::cerr << path << ": note: re-oriented " << report.flipped_faces << " face(s) consistently\n";
  } catch(const std::exception& e) {
    throw Failure(path + ": " + e.what());
  }
  return mesh;
}

void check_output_path(const std::string& out, std::initializer_list<const char*> allowed)
{
  const std::string ext = lapmesh::io::extension_of(out);
  std::string list;
  for(const char* a : allowed) {
    if(ext == a) return;
    list += std::string(list.empty() ? "." : ", .") + a;
  }
  throw Failure(out + ": unsupported output format '." + ext + "' (expected " + list + ")");
}

void add_input_output(CLI::App& cmd, std::string& input, std::string& output, const std::string& output_help)
{
  cmd.add_option("IN", input, "input mesh (.off, .obj, .ply, .stl)")->required();
  cmd.add_option("-o,--output", output, output_help)->required();
}

void add_laplacian_option(CLI::App& cmd, std::string& value)
{
  cmd.add_option("--laplacian", value, "Laplacian: cotangent (Laplace-Beltrami) or uniform (graph)")
    ->check(CLI::IsMember({"uniform", "cotangent"}))
    ->capture_default_str();
}

void add_area_option(CLI::App& cmd, std::string& value)
{
  cmd.add_option("--area", value, "vertex area (mass): barycentric, voronoi or mixed")
    ->check(CLI::IsMember({"barycentric", "voronoi", "mixed"}))
    ->capture_default_str();
}

lapmesh::Laplacian laplacian_from(const std::string& value) { return *lapmesh::parse_laplacian(value); }
lapmesh::Vertex_area area_from(const std::string& value) { return *lapmesh::parse_vertex_area(value); }

} // namespace lapmesh_cli
