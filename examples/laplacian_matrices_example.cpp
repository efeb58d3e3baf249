// The Laplacian pencil (S, M) of a mesh, used for a Laplacian of a function.
// Usage: laplacian_matrices_example [mesh]   (default: a torus)
#include <lapmesh/io.h>
#include <lapmesh/laplacian.h>
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
    else lapmesh::make_mesh(lapmesh::torus(120, 48), mesh);

    // S = C (cotangent stiffness, negative semidefinite), M = diag(mixed vertex areas).
    const lapmesh::Laplacian_pencil pencil =
      lapmesh::laplacian_pencil<CGAL::Parallel_if_available_tag>(mesh, LP::vertex_area(lapmesh::Vertex_area::mixed));

    // Pointwise Laplace-Beltrami of f = z: L f = M^-1 C f. Rows follow the vertex order.
    Eigen::VectorXd f(num_vertices(mesh));
    for(auto v : vertices(mesh)) f[v.idx()] = mesh.point(v).z();
    const Eigen::VectorXd Lf = (pencil.stiffness * f).cwiseQuotient(pencil.mass);

    std::cout << "n = " << pencil.stiffness.rows() << ", non-zeros = " << pencil.stiffness.nonZeros()
              << ", surface area = " << pencil.mass.sum() << "\n|C 1| = "
              << (pencil.stiffness * Eigen::VectorXd::Ones(f.size())).norm()
              << " (constants are in the kernel), max |L z| = " << Lf.cwiseAbs().maxCoeff() << '\n';
  } catch(const std::exception& e) {
    std::cerr << (argc > 1 ? argv[1] : "built-in mesh") << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
