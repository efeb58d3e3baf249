// Principal curvatures on an ellipsoid, compared with the closed form at its poles.
// Usage: principal_curvatures_example [mesh]   (default: ellipsoid with semi-axes 2, 1.5, 1)
#include <lapmesh/curvature.h>
#include <lapmesh/io.h>
#include <lapmesh/shapes.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <iostream>

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;

int main(int argc, char** argv)
{
  Mesh mesh;
  try {
    if(argc > 1) lapmesh::io::read_triangle_mesh(argv[1], mesh);
    else lapmesh::make_mesh(lapmesh::ellipsoid(5, 2.0, 1.5, 1.0), mesh);

    auto k1 = mesh.add_property_map<Mesh::Vertex_index, double>("v:k1").first;
    auto k2 = mesh.add_property_map<Mesh::Vertex_index, double>("v:k2").first;
    lapmesh::compute_principal_curvatures(mesh, k1, k2, lapmesh::parameters::vertex_area(lapmesh::Vertex_area::mixed));

    // the vertex with the largest z (near the pole (0, 0, 1) of the default ellipsoid)
    Mesh::Vertex_index top = *vertices(mesh).begin();
    for(auto v : vertices(mesh))
      if(mesh.point(v).z() > mesh.point(top).z()) top = v;
    std::cout << "at " << mesh.point(top) << ": k1 = " << k1[top] << ", k2 = " << k2[top] << '\n';
    if(argc == 1) {
      const auto& p = mesh.point(top);
      const auto hk = lapmesh::ellipsoid_curvatures({p.x(), p.y(), p.z()}, 2.0, 1.5, 1.0);
      const double root = std::sqrt(hk[0] * hk[0] - hk[1]);
      std::cout << "closed form: k1 = " << hk[0] + root << ", k2 = " << hk[0] - root << '\n';
    }
  } catch(const std::exception& e) {
    std::cerr << (argc > 1 ? argv[1] : "built-in mesh") << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
