// Computes a spectral basis once and reconstructs a mesh from k = 5, 10, 30, 100 eigenvectors.
// Usage: spectral_reconstruction_example [mesh.off] (default: an analytic bumpy sphere).
#include <lapmesh/io.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <iostream>

using Mesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;
namespace LP = lapmesh::parameters;

int main(int argc, char** argv)
{
  Mesh mesh;
  try {
    if(argc > 1)
      lapmesh::io::read_triangle_mesh(argv[1], mesh);
    else
      lapmesh::make_mesh(lapmesh::bumpy_sphere(4), mesh);
    // The basis: 100 smallest eigenpairs of the cotangent Laplacian with mixed areas.
    const auto basis = lapmesh::Spectral_basis::compute(
      mesh, 100, LP::vertex_area(lapmesh::Vertex_area::mixed, CGAL::parameters::number_of_iterations(2000)));
    auto [P, tris] = lapmesh::io::mesh_arrays(mesh);
    for(Eigen::Index k : {5, 10, 30, 100}) {
      const Eigen::MatrixXd R = basis.reconstruct(P, k);
      std::cout << "k = " << k << ": rms displacement " << std::sqrt((R - P).rowwise().squaredNorm().mean())
                << (basis.splits_eigenspace(k) ? " (warning: k splits an eigenspace)" : "") << '\n';
      lapmesh::io::write_mesh("reconstruction_" + std::to_string(k) + ".off", R, tris);
    }
    std::cout << "lambda_1 = " << basis.eigenvalues()[1] << ", lambda_99 = " << basis.eigenvalues()[99] << '\n';
  } catch(const std::exception& e) {
    std::cerr << (argc > 1 ? argv[1] : "bumpy sphere") << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
