// The operations that array front ends (the Python module) need besides operations.h: the
// assembled Laplacian as a CSR matrix, and a spectral basis's contents, projection and file,
// so that a binding reaches them without compiling the algorithms' headers.
#ifndef LAPMESH_SRC_OPERATIONS_ARRAYS_H
#define LAPMESH_SRC_OPERATIONS_ARRAYS_H

#include "operations.h"

#include <Eigen/SparseCore>

namespace lapmesh_ops {

/// The pencil (S, M) of a Laplacian, S compressed. S is symmetric, so its compressed columns, as
/// assembled, are also its compressed rows (scipy's CSR layout): no transposition is needed. A
/// lapmesh::Laplacian_pencil, which moves without copying its matrix.
using Csr_laplacian = lapmesh::Laplacian_pencil;

/// Assembles (S, M) for the Laplacian and vertex area of `settings`.
Csr_laplacian laplacian(const Mesh& mesh, const Curvature_settings& settings);

/// Writes vertices P and triangles to `path` (format by extension, atomically) as write_mesh()
/// does, without validating the geometry: results (a reconstruction, a smoothed mesh) may have
/// degenerate faces and are written as they are, as the command line writes them. Throws
/// lapmesh::Io_error; std::invalid_argument for a vertex index outside [0, rows of P).
void write_mesh(const std::string& path, const lapmesh::Vertex_vectors& P, const Triangles& triangles);

/// What a spectral basis holds (references into `basis`).
struct Basis_contents
{
  const Eigen::VectorXd& values;   ///< ascending, size() of them (>= the k asked for)
  const Eigen::MatrixXd& vectors;  ///< n x size(), M-orthonormal columns
  const Eigen::VectorXd& mass;     ///< the diagonal of M
  long long requested;             ///< the k asked for
  lapmesh::Laplacian laplacian;
  lapmesh::Vertex_area area;
};
Basis_contents contents(const lapmesh::Spectral_basis& basis);

/// The spectral coefficients Phi_k^T M X (k x c) of the signal X (n x c). Throws
/// Parameter_error("k") outside [1, pairs held], Parameter_error("signal") for a row count
/// other than the number of vertices.
Eigen::MatrixXd project(const lapmesh::Spectral_basis& basis, const Eigen::MatrixXd& X, long long k);

/// Spectral_basis::save and ::load. Throw lapmesh::Io_error (without the file name).
void save_basis(const lapmesh::Spectral_basis& basis, const std::string& path);
std::shared_ptr<const lapmesh::Spectral_basis> load_basis(const std::string& path);

} // namespace lapmesh_ops

#endif
