// The spectral operations: eigenpairs, the basis cache, reconstruction.
#include "operations.h"
#include "numbering.h"

#include <lapmesh/io.h>
#include <lapmesh/spectral_reconstruction.h>

#include <cmath>

namespace lapmesh_ops {

namespace {

void check_k(long long k, long long n, const char* parameter)
{
  if(k < 1 || k > n)
    throw lapmesh::Parameter_error(parameter, "k = " + std::to_string(k) + " is out of range (expected 1 <= k <= " +
                                                std::to_string(n) + ", the number of vertices)");
}

} // namespace

std::shared_ptr<const lapmesh::Spectral_basis> spectral_basis(const Mesh& mesh, const Spectral_settings& settings)
{
  namespace LP = lapmesh::parameters;
  check_k(settings.k, (long long)vertex_count(mesh), "k");
  return with_numbering(mesh, [&](const auto& np) {
    return std::make_shared<const lapmesh::Spectral_basis>(lapmesh::Spectral_basis::compute<CGAL::Parallel_if_available_tag>(
      mesh, Eigen::Index(settings.k),
      LP::spectral_progress(settings.progress,
                            LP::mollification_factor(settings.mollification,
                                                     LP::vertex_area(settings.area, LP::laplacian(settings.laplacian, np))))));
  });
}

void check_basis_fits(const lapmesh::Spectral_basis& basis, const Mesh& mesh, std::optional<lapmesh::Laplacian> laplacian,
                      std::optional<lapmesh::Vertex_area> area)
{
  const long long n = (long long)vertex_count(mesh);
  if(basis.num_vertices() != n)
    throw lapmesh::Parameter_error("basis", "the basis has " + std::to_string(basis.num_vertices()) +
                                              " vertices, the mesh has " + std::to_string(n));
  if(laplacian && basis.laplacian() != *laplacian)
    throw lapmesh::Parameter_error("laplacian", std::string("the basis was computed with the ") +
                                                  lapmesh::to_string(basis.laplacian()) + " Laplacian, not the " +
                                                  lapmesh::to_string(*laplacian) + " one asked for");
  if(area && basis.vertex_area() != *area)
    throw lapmesh::Parameter_error("area", std::string("the basis was computed with the ") +
                                             lapmesh::to_string(basis.vertex_area()) + " vertex area, not the " +
                                             lapmesh::to_string(*area) + " one asked for");
  // The mass of the mesh must be the basis's: catches a basis of another mesh with as many vertices.
  namespace LP = lapmesh::parameters;
  const Eigen::VectorXd mass = with_numbering(mesh, [&](const auto& np) {
    return lapmesh::laplacian_pencil(mesh, LP::vertex_area(basis.vertex_area(), LP::laplacian(basis.laplacian(), np)))
      .mass;
  });
  if((mass - basis.mass()).cwiseAbs().maxCoeff() > 1e-9 * mass.cwiseAbs().maxCoeff())
    throw lapmesh::Parameter_error("basis", "the basis does not belong to this mesh (different vertex masses)");
}

std::shared_ptr<const lapmesh::Spectral_basis> Basis_cache::find(const std::string& mesh, long long geometry,
                                                                 lapmesh::Laplacian laplacian, lapmesh::Vertex_area area,
                                                                 double mollification, long long k)
{
  std::lock_guard<std::mutex> g(m_mutex);
  for(auto it = m_lru.begin(); it != m_lru.end(); ++it) {
    if(it->mesh == mesh && it->geometry == geometry && it->same_operator(laplacian, area, mollification) &&
       it->basis->size() >= k) {
      m_lru.splice(m_lru.begin(), m_lru, it);
      return m_lru.front().basis;
    }
  }
  return nullptr;
}

void Basis_cache::insert(const std::string& mesh, long long geometry, double mollification,
                         std::shared_ptr<const lapmesh::Spectral_basis> basis)
{
  const std::size_t bytes = bytes_of(*basis);
  std::lock_guard<std::mutex> g(m_mutex);
  m_lru.remove_if([&](const Entry& e) {
    const bool same = e.mesh == mesh && e.geometry == geometry &&
                      e.same_operator(basis->laplacian(), basis->vertex_area(), mollification);
    if(same) m_bytes -= e.bytes;
    return same;
  });
  if(bytes > m_budget) return;  // used for this request only
  while(!m_lru.empty() && m_bytes + bytes > m_budget) {
    m_bytes -= m_lru.back().bytes;
    m_lru.pop_back();
  }
  m_lru.push_front({mesh, geometry, basis->laplacian(), basis->vertex_area(), mollification, basis, bytes});
  m_bytes += bytes;
}

void Basis_cache::forget(const std::string& mesh, long long keep_a, long long keep_b)
{
  std::lock_guard<std::mutex> g(m_mutex);
  m_lru.remove_if([&](const Entry& e) {
    const bool gone = e.mesh == mesh && e.geometry != keep_a && e.geometry != keep_b;
    if(gone) m_bytes -= e.bytes;
    return gone;
  });
}

Basis_cache::Stats Basis_cache::stats()
{
  std::lock_guard<std::mutex> g(m_mutex);
  return {m_bytes, m_budget, m_lru.size()};
}

std::size_t Basis_cache::bytes_of(const lapmesh::Spectral_basis& b)
{
  const std::size_t n = std::size_t(b.num_vertices()), m = std::size_t(b.size());
  return sizeof(double) * (n * m + m + n);  // eigenvectors, eigenvalues, mass
}

namespace {

Reconstruction reconstruct_with(const Mesh& mesh, const Reconstruct_settings& settings,
                                std::shared_ptr<const lapmesh::Spectral_basis> basis, bool verify_basis)
{
  const long long n = (long long)vertex_count(mesh);
  check_k(settings.k, n, "k");
  const long long k = settings.k;
  if(basis) {
    if(k > basis->size())
      throw lapmesh::Parameter_error("k", "k = " + std::to_string(k) + " is out of range: the basis holds " +
                                            std::to_string(basis->size()) + " eigenpairs");
    if(verify_basis) check_basis_fits(*basis, mesh);
  } else {
    if(settings.basis_size < 0 || settings.basis_size > n)
      throw lapmesh::Parameter_error("basis_size", "basis size " + std::to_string(settings.basis_size) +
                                                     " is out of range (expected 0 <= basis size <= " +
                                                     std::to_string(n) + ", the number of vertices)");
    Spectral_settings s;
    s.k = std::max(k, settings.basis_size);
    s.laplacian = settings.laplacian;
    s.area = settings.area;
    s.mollification = settings.mollification;
    s.progress = settings.progress;
    basis = spectral_basis(mesh, s);
  }
  Reconstruction out;
  out.positions = basis->reconstruct(positions(mesh), Eigen::Index(k));
  out.basis = basis;
  out.eigenvalue_k_minus_1 = basis->eigenvalues()[k - 1];
  if(basis->splits_eigenspace(Eigen::Index(k)))
    out.warnings.push_back({"lambda_" + std::to_string(k - 1) + " and lambda_" + std::to_string(k) +
                              " agree to 1e-8 relative: the reconstruction depends on the basis chosen inside that "
                              "eigenspace",
                            {}});
  return out;
}

} // namespace

Reconstruction reconstruct(const Mesh& mesh, const Reconstruct_settings& settings,
                           std::shared_ptr<const lapmesh::Spectral_basis> basis)
{
  return reconstruct_with(mesh, settings, std::move(basis), true);
}

Reconstruction reconstruct(const Mesh& mesh, const Reconstruct_settings& settings, Basis_cache& cache,
                           const Basis_key& key)
{
  auto basis = cache.find(key.mesh, key.geometry, settings.laplacian, settings.area, settings.mollification, settings.k);
  const bool cached = basis != nullptr;
  Reconstruction out = reconstruct_with(mesh, settings, std::move(basis), false);
  out.basis_from_cache = cached;
  if(!cached) cache.insert(key.mesh, key.geometry, settings.mollification, out.basis);
  return out;
}

} // namespace lapmesh_ops
