// Per-vertex mean and Gaussian curvature of a mesh, written through property maps.
// Usage: curvature_example [mesh.off|obj|ply|stl]   (default: a generated bumpy sphere)
#include <lapmesh/curvature.h>
#include <lapmesh/io.h>
#include <lapmesh/shapes.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <iostream>

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace LP = lapmesh::parameters;

int main(int argc, char** argv)
{
  Mesh mesh;
  try {
    if(argc > 1) lapmesh::io::read_triangle_mesh(argv[1], mesh);
    else lapmesh::make_mesh(lapmesh::bumpy_sphere(4), mesh);

    auto H = mesh.add_property_map<Mesh::Vertex_index, double>("v:mean_curvature").first;
    auto K = mesh.add_property_map<Mesh::Vertex_index, double>("v:gaussian_curvature").first;
    // Cotangent Laplacian with mixed Voronoi areas: the accurate choice (see doc/curvature.md).
    lapmesh::compute_vertex_curvatures(
      mesh, LP::vertex_mean_curvature_map(H, LP::vertex_gaussian_curvature_map(K, LP::vertex_area(lapmesh::Vertex_area::mixed))));

    double total_K_area = 0;
    const auto areas = lapmesh::vertex_areas(mesh, LP::vertex_area(lapmesh::Vertex_area::mixed));
    for(auto v : vertices(mesh)) total_K_area += K[v] * areas[v.idx()];
    std::cout.precision(17);
    std::cout << num_vertices(mesh) << " vertices; H at vertex 0: " << H[Mesh::Vertex_index(0)]
              << "\nGauss-Bonnet: sum K A / 2 pi = " << total_K_area / (2 * M_PI) << " (the Euler characteristic)\n";
  } catch(const std::exception& e) {
    std::cerr << (argc > 1 ? argv[1] : "built-in mesh") << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
