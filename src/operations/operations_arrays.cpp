// The array front ends' operations (arrays.h).
#include "arrays.h"
#include "numbering.h"

#include <lapmesh/io.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/spectral_reconstruction.h>

namespace lapmesh_ops {

Csr_laplacian laplacian(const Mesh& mesh, const Curvature_settings& settings)
{
  namespace LP = lapmesh::parameters;
  Csr_laplacian pencil = with_numbering(mesh, [&](const auto& np) {
    return lapmesh::laplacian_pencil<CGAL::Parallel_if_available_tag>(
      mesh, LP::mollification_factor(settings.mollification,
                                     LP::vertex_area(settings.area, LP::laplacian(settings.laplacian, np))));
  });
  pencil.stiffness.makeCompressed();
  return pencil;
}

void write_mesh(const std::string& path, const lapmesh::Vertex_vectors& P, const Triangles& triangles)
{
  for(std::size_t f = 0; f < triangles.size(); ++f)
    for(std::size_t v : triangles[f])
      if(v >= std::size_t(P.rows()))
        throw std::invalid_argument("face " + std::to_string(f) + " has the vertex index " + std::to_string(v) +
                                    ", outside [0, " + std::to_string(P.rows()) + ")");
  lapmesh::io::write_mesh(path, P, triangles);
}

Basis_contents contents(const lapmesh::Spectral_basis& basis)
{
  return {basis.eigenvalues(), basis.eigenvectors(), basis.mass(), (long long)basis.requested(),
          basis.laplacian(), basis.vertex_area()};
}

Eigen::MatrixXd project(const lapmesh::Spectral_basis& basis, const Eigen::MatrixXd& X, long long k)
{
  if(k < 1 || k > (long long)basis.size())
    throw lapmesh::Parameter_error("k", "k = " + std::to_string(k) + " is outside [1, " +
                                          std::to_string(basis.size()) + "] (the eigenpairs held)");
  if(X.rows() != basis.num_vertices())
    throw lapmesh::Parameter_error("signal", "the signal has " + std::to_string(X.rows()) + " rows, the basis " +
                                               std::to_string(basis.num_vertices()) + " vertices");
  return basis.project(X, Eigen::Index(k));
}

void save_basis(const lapmesh::Spectral_basis& basis, const std::string& path) { basis.save(path); }

std::shared_ptr<const lapmesh::Spectral_basis> load_basis(const std::string& path)
{
  return std::make_shared<const lapmesh::Spectral_basis>(lapmesh::Spectral_basis::load(path));
}

} // namespace lapmesh_ops
