// A downstream project: installed headers, find_package(lapmesh), a curvature on a sphere and,
// through lapmesh::cholmod, the first non-zero eigenvalue of the sphere (2 / r^2, three times).
#include <lapmesh/curvature.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>
#include <iostream>

int main()
{
  CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3> mesh;
  lapmesh::make_mesh(lapmesh::icosphere(3, 2.0), mesh);
  const auto c = lapmesh::vertex_curvatures(mesh, lapmesh::parameters::vertex_area(lapmesh::Vertex_area::mixed));
  const double mean_H = c.mean.mean();
  std::cout << "mean curvature of a radius-2 sphere: " << mean_H << '\n';
  if(std::abs(mean_H - 0.5) >= 0.01) return 1;
#ifdef CONSUMER_EXPECTS_CHOLMOD
  if(lapmesh::default_sparse_cholesky != lapmesh::Sparse_cholesky::cholmod) {
    std::cout << "lapmesh::cholmod did not enable CHOLMOD\n";
    return 1;
  }
#endif
  const auto basis = lapmesh::Spectral_basis::compute(mesh, 4);
  std::cout << "sphere eigenvalues 1-3 (expected 0.5): " << basis.eigenvalues().segment(1, 3).transpose() << '\n';
  return (basis.eigenvalues().segment(1, 3).array() - 0.5).abs().maxCoeff() < 0.01 ? 0 : 1;
}
