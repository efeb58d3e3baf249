// lapmesh — Laplace–Beltrami eigenpairs (manifold harmonics) and reconstruction of a mesh,
// or of any per-vertex signal, from its k smallest eigenvectors (doc/spectral.md).
//
//   -S phi = lambda M phi,  (S, M) = (C, diag(A_i)) cotangent, (W, D) uniform,
//   eigenvalues ascending (lambda_0 ~ 0 once per connected component), phi_i^T M phi_j = delta_ij,
//   reconstruction  x <- sum_{i<k} (x^T M phi_i) phi_i  per coordinate column.
//
// Spectral_basis computes the pairs once and serves reconstructions for every k up to the
// number it holds, projections of any signal, and a binary file to reuse it later.
// The solver (internal/spectral_solver.h) is Spectra's shift-invert Lanczos on the
// standardised pencil with a sparse Cholesky factorisation, and a Sylvester-inertia check
// that no member of a repeated eigenvalue was dropped.
#ifndef LAPMESH_SPECTRAL_RECONSTRUCTION_H
#define LAPMESH_SPECTRAL_RECONSTRUCTION_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/atomic_file.h>
#include <lapmesh/internal/spectral_solver.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/parameters.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>


namespace lapmesh {

/// Relative residual tolerance of the Lanczos iteration; default 1e-10.
LAPMESH_NAMED_PARAMETER(spectral_tolerance)
/// Sparse_cholesky: the factorisation of -S - sigma M; default CHOLMOD (supernodal) when
/// LAPMESH_HAS_CHOLMOD is defined, else Sparse_cholesky::simplicial.
LAPMESH_NAMED_PARAMETER(sparse_cholesky)
/// Krylov_method: lapmesh's block Lanczos (default) or Spectra's Lanczos.
LAPMESH_NAMED_PARAMETER(krylov_method)
/// sigma = -factor / sum(M); default 1e-2 (see internal/spectral_solver.h).
LAPMESH_NAMED_PARAMETER(spectral_shift_factor)
/// Extra eigenpairs computed for the completeness check; default max(6, k/10).
LAPMESH_NAMED_PARAMETER(spectral_extra_pairs)
/// bool: verify by an inertia count that no repeated eigenvalue was dropped; default true.
LAPMESH_NAMED_PARAMETER(check_completeness)
/// std::function<void(const Spectral_progress&)> called while solving; default none.
LAPMESH_NAMED_PARAMETER(spectral_progress)

namespace internal {

template <typename NamedParameters>
Spectral_options choose_spectral_options(const NamedParameters& np)
{
  using CGAL::parameters::choose_parameter;
  using CGAL::parameters::get_parameter;
  Spectral_options o;
  o.tolerance = choose_parameter(get_parameter(np, internal_np::spectral_tolerance), o.tolerance);
  o.max_restarts = choose_parameter(get_parameter(np, CGAL::internal_np::number_of_iterations), o.max_restarts);
  o.cholesky = choose_parameter(get_parameter(np, internal_np::sparse_cholesky), o.cholesky);
  o.method = choose_parameter(get_parameter(np, internal_np::krylov_method), o.method);
  o.shift_factor = choose_parameter(get_parameter(np, internal_np::spectral_shift_factor), o.shift_factor);
  o.extra = choose_parameter(get_parameter(np, internal_np::spectral_extra_pairs), o.extra);
  o.check_completeness = choose_parameter(get_parameter(np, internal_np::check_completeness), o.check_completeness);
  o.progress = choose_parameter(get_parameter(np, internal_np::spectral_progress),
                                std::function<void(const Spectral_progress&)>());
  return o;
}

} // namespace internal

/// \ingroup PkgLapmeshSpectral
/// @brief holds the smallest eigenpairs of a mesh Laplacian and serves reconstructions and
/// projections for any k up to size().
///
/// It holds at least the k pairs asked for, and every member of the eigenspace of
/// lambda_{k-1} (so it may hold a few more). Eigenvector i is column i of eigenvectors(),
/// row v is vertex v (vertex_index_map numbering).
class Spectral_basis
{
public:
  Spectral_basis() = default;

  /// @brief computes the k smallest eigenpairs of the Laplacian of `tm`.
  /// @tparam ConcurrencyTag `CGAL::Sequential_tag` or `CGAL::Parallel_tag` (assembly only)
  /// @param tm the mesh (a `FaceListGraph` with triangle faces)
  /// @param k number of eigenpairs, 1 <= k <= num_vertices(tm)
  /// @param np optional named parameters:
  ///   - `lapmesh::parameters::laplacian` (default cotangent), `vertex_area` (default barycentric)
  ///   - `CGAL::parameters::vertex_point_map`, `vertex_index_map`
  ///   - `lapmesh::parameters::spectral_tolerance` (double, 1e-10)
  ///   - `CGAL::parameters::number_of_iterations` (Lanczos restarts, 1000)
  ///   - `lapmesh::parameters::sparse_cholesky` (Sparse_cholesky, cholmod when compiled in, else simplicial)
  ///   - `lapmesh::parameters::krylov_method` (Krylov_method, block_lanczos; or spectra)
  ///   - `lapmesh::parameters::spectral_shift_factor` (double, 1e-2), `spectral_extra_pairs` (int)
  ///   - `lapmesh::parameters::check_completeness` (bool, true), `spectral_progress` (callback)
  /// @throws Mesh_error if a vertex area is <= 0; Numerical_error if the solver fails;
  /// std::invalid_argument if k is out of range.
  template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
            typename NamedParameters = CGAL::parameters::Default_named_parameters>
  static Spectral_basis compute(const TriangleMesh& tm, Eigen::Index k,
                                const NamedParameters& np = CGAL::parameters::default_values())
  {
    const auto mesh = internal::extract_mesh(tm, np);
    const Laplacian lap = internal::choose_laplacian(np);
    const Vertex_area area = internal::choose_vertex_area(np);
    Laplacian_pencil pencil;
    internal::assemble_pencil(mesh.topology, mesh.positions, lap, area, internal::is_parallel<ConcurrencyTag>(),
                              pencil, internal::choose_mollification(np));
    Spectral_basis b =
      mesh.naming_input_vertices([&] { return from_pencil(pencil, k, internal::choose_spectral_options(np), area); });
    b.m_laplacian = lap;
    b.m_area = area;
    if(mesh.num_rows_in_no_face() > 0) {  // zero eigenvector entries and mass there
      b.m_vectors = mesh.to_rows(b.m_vectors, 0.0);
      b.m_mass = mesh.to_rows(b.m_mass, 0.0);
    }
    return b;
  }

  /// @brief computes the k smallest eigenpairs of an assembled pencil (S, M).
  static Spectral_basis from_pencil(const Laplacian_pencil& pencil, Eigen::Index k,
                                    const Spectral_options& options = {}, Vertex_area area = Vertex_area::barycentric)
  {
    internal::require_positive_mass(pencil.mass, area);
    Spectral_basis b;
    Spectral_pairs p = internal::smallest_eigenpairs(pencil.stiffness, pencil.mass, k, options);
    b.m_values = std::move(p.values);
    b.m_vectors = std::move(p.vectors);
    b.m_mass = pencil.mass;
    b.m_requested = k;
    b.m_operations = p.operations;
    return b;
  }

  /// Number of eigenpairs held (>= the k asked for).
  Eigen::Index size() const { return m_values.size(); }
  /// Number of vertices.
  Eigen::Index num_vertices() const { return m_mass.size(); }
  /// The k asked for at construction (the file keeps it).
  Eigen::Index requested() const { return m_requested; }
  /// The eigenvalues, ascending (size() of them).
  const Eigen::VectorXd& eigenvalues() const { return m_values; }
  /// n x size(), M-orthonormal columns.
  const Eigen::MatrixXd& eigenvectors() const { return m_vectors; }
  /// The diagonal of M.
  const Eigen::VectorXd& mass() const { return m_mass; }
  /// The Laplacian the basis was computed with.
  Laplacian laplacian() const { return m_laplacian; }
  /// The vertex area of its mass matrix.
  Vertex_area vertex_area() const { return m_area; }
  /// Shift-invert solves used (0 for the dense path or a loaded basis).
  long long operations() const { return m_operations; }

  /// @brief the spectral coefficients Phi_k^T M X (k x c) of the per-vertex signal X (n x c).
  Eigen::MatrixXd project(const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::Index k) const
  {
    check_k(k);
    if(X.rows() != num_vertices())
      throw std::invalid_argument("the signal has " + std::to_string(X.rows()) + " rows, the basis " +
                                  std::to_string(num_vertices()) + " vertices");
    return m_vectors.leftCols(k).transpose() * (m_mass.asDiagonal() * X);
  }

  /// @brief the signal rebuilt from spectral coefficients (k x c): Phi_k C.
  Eigen::MatrixXd synthesize(const Eigen::Ref<const Eigen::MatrixXd>& coefficients) const
  {
    check_k(coefficients.rows());
    return m_vectors.leftCols(coefficients.rows()) * coefficients;
  }

  /// @brief x <- sum_{i<k} (x^T M phi_i) phi_i for each column of X (n x c), e.g. positions.
  /// Rows of zero mass (vertices in no face, outside the operator) keep their values.
  Eigen::MatrixXd reconstruct(const Eigen::Ref<const Eigen::MatrixXd>& X, Eigen::Index k) const
  {
    Eigen::MatrixXd out = synthesize(project(X, k));
    for(Eigen::Index i = 0; i < out.rows(); ++i)
      if(m_mass[i] == 0) out.row(i) = X.row(i);
    return out;
  }

  /// @brief true when lambda_{k-1} and lambda_k agree to 1e-8 relative: the reconstruction
  /// from k vectors then depends on the basis chosen inside that eigenspace.
  ///
  /// The solver ends the held set at a spectral gap, or, when the eigenspace of lambda_{k-1}
  /// for the k asked for reaches past what a run computed (a value repeated very often, as on
  /// a mesh of many identical parts), one value past lambda_{k-1}. k = size() is then taken
  /// to end at a gap.
  bool splits_eigenspace(Eigen::Index k) const
  {
    check_k(k);
    if(k >= size()) return false;
    const double a = m_values[k - 1], b = m_values[k];
    const double floor = 1e-10 * std::abs(m_values[size() - 1]);
    return std::abs(b - a) <= 1e-8 * std::max(std::abs(a), std::abs(b)) + floor;
  }

  /// @brief writes the basis to a binary file (atomically: temporary file, then rename).
  ///
  /// Format (little-endian, as written by this machine): 8 bytes "LAPMSB01", int64 n,
  /// int64 m (pairs held), int64 k requested, int32 laplacian (0 uniform, 1 cotangent, 2 intrinsic Delaunay),
  /// int32 area (0 barycentric, 1 voronoi, 2 mixed), double mass[n], double eigenvalues[m],
  /// double eigenvectors[n*m] column by column.
  void save(const std::string& path) const
  {
    internal::write_file_atomically(path, [&](std::ostream& os) {
      os.write("LAPMSB01", 8);
      const std::int64_t hdr[3] = {num_vertices(), size(), m_requested};
      os.write(reinterpret_cast<const char*>(hdr), sizeof hdr);
      const std::int32_t kinds[2] = {std::int32_t(m_laplacian), std::int32_t(m_area)};
      os.write(reinterpret_cast<const char*>(kinds), sizeof kinds);
      os.write(reinterpret_cast<const char*>(m_mass.data()), std::streamsize(sizeof(double) * m_mass.size()));
      os.write(reinterpret_cast<const char*>(m_values.data()), std::streamsize(sizeof(double) * m_values.size()));
      os.write(reinterpret_cast<const char*>(m_vectors.data()), std::streamsize(sizeof(double) * m_vectors.size()));
    });
  }

  /// @brief reads a basis written by save(). Throws Io_error on a file that cannot be read,
  /// or whose header or size is not that of a basis file; nothing is allocated before the
  /// header's counts are checked against the file's size.
  static Spectral_basis load(const std::string& path)
  {
    std::ifstream is(path, std::ios::binary);
    if(!is) throw Io_error("cannot open the file for reading");
    char magic[8];
    if(!is.read(magic, 8) || std::memcmp(magic, "LAPMSB01", 8) != 0)
      throw Io_error("not a lapmesh spectral basis file (bad magic)");
    std::int64_t hdr[3];
    std::int32_t kinds[2];
    if(!is.read(reinterpret_cast<char*>(hdr), sizeof hdr) || !is.read(reinterpret_cast<char*>(kinds), sizeof kinds))
      throw Io_error("truncated spectral basis file");
    const std::int64_t n = hdr[0], m = hdr[1];
    if(n < 1 || m < 1 || m > n || hdr[2] < 1 || hdr[2] > m || kinds[0] < 0 || kinds[0] > 2 || kinds[1] < 0 ||
       kinds[1] > 2)
      throw Io_error("malformed spectral basis file header");
    // n + m + n m doubles must be exactly what follows the header (checked without overflow).
    const std::streamoff header_bytes = 8 + sizeof hdr + sizeof kinds;
    is.seekg(0, std::ios::end);
    const std::streamoff file_bytes = is.tellg();
    is.seekg(header_bytes);
    const std::uint64_t payload = std::uint64_t(file_bytes - header_bytes) / sizeof(double);
    if(file_bytes < header_bytes || (file_bytes - header_bytes) % std::streamoff(sizeof(double)) != 0 ||
       std::uint64_t(n) > payload || std::uint64_t(m) > payload / std::uint64_t(n + 1) ||
       std::uint64_t(n) + std::uint64_t(m) * std::uint64_t(n + 1) != payload)
      throw Io_error("truncated or oversized spectral basis file (the header declares " + std::to_string(n) +
                     " vertices and " + std::to_string(m) + " pairs)");
    Spectral_basis b;
    b.m_requested = hdr[2];
    b.m_laplacian = Laplacian(kinds[0]);
    b.m_area = Vertex_area(kinds[1]);
    b.m_mass.resize(n);
    b.m_values.resize(m);
    b.m_vectors.resize(n, m);
    is.read(reinterpret_cast<char*>(b.m_mass.data()), std::streamsize(sizeof(double) * n));
    is.read(reinterpret_cast<char*>(b.m_values.data()), std::streamsize(sizeof(double) * m));
    is.read(reinterpret_cast<char*>(b.m_vectors.data()), std::streamsize(sizeof(double) * n * m));
    if(!is) throw Io_error("truncated spectral basis file");
    return b;
  }

private:
  void check_k(Eigen::Index k) const
  {
    if(k < 1 || k > size())
      throw std::invalid_argument("k = " + std::to_string(k) + " is outside [1, " + std::to_string(size()) +
                                  "] (the eigenpairs held)");
  }

  Eigen::VectorXd m_values;
  Eigen::MatrixXd m_vectors;
  Eigen::VectorXd m_mass;
  Eigen::Index m_requested = 0;
  long long m_operations = 0;
  Laplacian m_laplacian = Laplacian::cotangent;
  Vertex_area m_area = Vertex_area::barycentric;
};

/// @brief returns the k smallest eigenvalues, ascending (named parameters as Spectral_basis::compute).
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Eigen::VectorXd laplacian_eigenvalues(const TriangleMesh& tm, Eigen::Index k,
                                      const NamedParameters& np = CGAL::parameters::default_values())
{
  return Spectral_basis::compute<ConcurrencyTag>(tm, k, np).eigenvalues().head(k);
}

/// @brief reconstructs the positions of `tm` from its k smallest eigenvectors and writes them
/// into the vertex point map (named parameters as Spectral_basis::compute).
/// @return true when lambda_{k-1} and lambda_k agree to 1e-8 relative (see splits_eigenspace()).
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
bool spectral_reconstruction(TriangleMesh& tm, Eigen::Index k,
                             const NamedParameters& np = CGAL::parameters::default_values())
{
  const auto mesh = internal::extract_mesh(tm, np);
  const Spectral_basis b = Spectral_basis::compute<ConcurrencyTag>(tm, k, np);
  const Eigen::MatrixXd P = b.reconstruct(mesh.to_rows(mesh.positions, 0.0), k);
  auto vpm = CGAL::parameters::choose_parameter(CGAL::parameters::get_parameter(np, CGAL::internal_np::vertex_point),
                                                get_property_map(CGAL::vertex_point, tm));
  using Point = typename boost::property_traits<decltype(vpm)>::value_type;
  const bool all_rows = mesh.num_rows_in_no_face() == 0;
  mesh.for_each_vertex([&](auto v, internal::Index i) {
    const Eigen::Index r = all_rows ? i : mesh.row[i];
    put(vpm, v, Point(P(r, 0), P(r, 1), P(r, 2)));
  });
  return b.splits_eigenspace(k);
}

} // namespace lapmesh

#endif
