// How many eigenvectors a shape needs: spectral reconstruction error against k, as CSV.
// One basis (cotangent Laplacian, mixed areas) is computed for the largest k, then every k
// is a projection onto its first k vectors.
// Usage: reconstruction_error [mesh.off|obj|ply|stl] [k ...]
//        (default: lapmesh::bumpy_box(); k = 5 10 30 100 300, capped at the vertex count)
// Output: k,rms_distance,rms_over_diagonal,max_over_diagonal,eigenvalue,splits_eigenspace
//   rms_distance: RMS over vertices of |x_k - x|; the ratios divide by the bounding-box
//   diagonal, so meshes of any size compare; eigenvalue: lambda_{k-1}.
#include <lapmesh/io.h>
#include <lapmesh/shapes.h>
#include <lapmesh/spectral_reconstruction.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

using Mesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;
namespace LP = lapmesh::parameters;

int main(int argc, char** argv)
{
  const std::string name = argc > 1 ? argv[1] : "bumpy box";
  try {
    Mesh mesh;
    if(argc > 1) lapmesh::io::read_triangle_mesh(argv[1], mesh);
    else lapmesh::make_mesh(lapmesh::bumpy_box(), mesh);
    const auto [P, tris] = lapmesh::io::mesh_arrays(mesh);
    const Eigen::Index n = P.rows();

    std::vector<Eigen::Index> ks;
    for(int i = 2; i < argc; ++i) ks.push_back(std::stol(argv[i]));
    if(ks.empty()) ks = {5, 10, 30, 100, 300};
    for(auto& k : ks) k = std::clamp<Eigen::Index>(k, 1, n);
    const Eigen::Index k_max = *std::max_element(ks.begin(), ks.end());

    const auto basis = lapmesh::Spectral_basis::compute(mesh, k_max, LP::vertex_area(lapmesh::Vertex_area::mixed));
    const double diagonal = (P.colwise().maxCoeff() - P.colwise().minCoeff()).norm();

    std::printf("k,rms_distance,rms_over_diagonal,max_over_diagonal,eigenvalue,splits_eigenspace\n");
    for(Eigen::Index k : ks) {
      const Eigen::VectorXd d = (basis.reconstruct(P, k) - P).rowwise().norm();
      const double rms = std::sqrt(d.squaredNorm() / double(n));
      std::printf("%ld,%.6g,%.6g,%.6g,%.6g,%d\n", long(k), rms, rms / diagonal, d.maxCoeff() / diagonal,
                  basis.eigenvalues()[k - 1], int(basis.splits_eigenspace(k)));
    }
  } catch(const std::exception& e) {
    std::cerr << name << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
