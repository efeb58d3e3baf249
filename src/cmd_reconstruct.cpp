// lapmesh reconstruct IN -o OUT -k K: the mesh rebuilt from its k smallest eigenvectors,
// x <- sum_{i<k} (x^T M phi_i) phi_i per coordinate, with the input's vertex order and faces.
#include "cli_common.h"

#include <lapmesh/io.h>
#include <lapmesh/spectral_reconstruction.h>

#include <iostream>
#include <memory>

namespace lapmesh_cli {

namespace {

struct Reconstruct_options
{
  std::string input, output, laplacian = "cotangent", area = "barycentric", k, save_basis, load_basis, basis_size;
  bool quiet = false;
};

lapmesh::Spectral_basis load_basis(const Reconstruct_options& o, const Mesh& mesh, bool laplacian_given,
                                   bool area_given)
{
  lapmesh::Spectral_basis b;
  try {
    b = lapmesh::Spectral_basis::load(o.load_basis);
  } catch(const std::exception& e) {
    throw Failure(o.load_basis + ": " + e.what());
  }
  if(b.num_vertices() != (long long)num_vertices(mesh))
    throw Failure(o.load_basis + ": the basis has " + std::to_string(b.num_vertices()) + " vertices, " + o.input +
                  " has " + std::to_string(num_vertices(mesh)));
  if((laplacian_given && b.laplacian() != laplacian_from(o.laplacian)) ||
     (area_given && b.vertex_area() != area_from(o.area)))
    throw Failure(o.load_basis + ": the basis was computed with --laplacian " + lapmesh::to_string(b.laplacian()) +
                  " --area " + lapmesh::to_string(b.vertex_area()) + ", not the options given");
  // The mass of the mesh must be the basis's: catches a basis of another mesh with as many vertices.
  const Eigen::VectorXd mass = lapmesh::laplacian_pencil(mesh, lapmesh::parameters::vertex_area(
                                                                 b.vertex_area(), lapmesh::parameters::laplacian(b.laplacian())))
                                 .mass;
  if((mass - b.mass()).cwiseAbs().maxCoeff() > 1e-9 * mass.cwiseAbs().maxCoeff())
    throw Failure(o.load_basis + ": the basis does not belong to " + o.input + " (different vertex masses)");
  return b;
}

void run(const Reconstruct_options& o, bool laplacian_given, bool area_given)
{
  check_output_path(o.output, {"off", "obj", "ply", "stl"});
  const Mesh mesh = load_mesh(o.input);
  const long long n = (long long)num_vertices(mesh);
  const long long k = spectral_k_from(o.input, o.k, n);
  lapmesh::Spectral_basis basis;
  if(!o.load_basis.empty()) {
    basis = load_basis(o, mesh, laplacian_given, area_given);
    if(k > basis.size())
      throw Failure(o.input + ": -k " + o.k + " is out of range: the basis " + o.load_basis + " holds " +
                    std::to_string(basis.size()) + " eigenpairs");
  } else {
    const long long basis_size =
      o.basis_size.empty() ? 0 : parse_count_option(o.input, "--basis-size", o.basis_size, 0, n, ", the number of vertices");
    const long long m = std::max(k, basis_size);
    basis = compute_spectral_basis(o.input, mesh, m, o.laplacian, o.area);
  }
  auto [P, tris] = lapmesh::io::mesh_arrays(mesh);
  const Eigen::MatrixXd R = basis.reconstruct(P, k);
  if(basis.splits_eigenspace(k))
    std::cerr << o.input << ": warning: lambda_" << k - 1 << " and lambda_" << k
              << " agree to 1e-8 relative; the reconstruction depends on the basis chosen inside that eigenspace\n";
  if(!o.save_basis.empty()) or_fail(o.save_basis, [&] { basis.save(o.save_basis); });
  or_fail(o.output, [&] { lapmesh::io::write_mesh(o.output, R, tris); });
  if(!o.quiet)
    std::cout << o.input << ": " << n << " vertices reconstructed from " << k << " eigenvectors ("
              << lapmesh::to_string(basis.laplacian()) << ", " << lapmesh::to_string(basis.vertex_area())
              << " area; basis of " << basis.size() << "); wrote " << o.output << '\n';
}

} // namespace

void register_reconstruct(CLI::App& app)
{
  auto o = std::make_shared<Reconstruct_options>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "the mesh rebuilt from its k smallest Laplacian eigenvectors");
  cmd->footer("x <- sum_{i<k} (x^T M phi_i) phi_i for the three coordinates (M-orthonormal phi_i).\n"
              "Output: a mesh in the format of OUT's extension, input vertex order and faces.\n"
              "--save-basis keeps the eigenpairs (binary, see doc/spectral.md) for later runs with\n"
              "--load-basis at any k up to the number held (--basis-size computes more than k).\n"
              "Warns when lambda_{k-1} = lambda_k (to 1e-8 relative). Progress on stderr when a terminal.\n");
  add_input_output(*cmd, o->input, o->output, "output mesh (.off, .obj, .ply, .stl)");
  cmd->add_option("-k", o->k, "number of eigenvectors, 1 <= k <= number of vertices")->required();
  add_laplacian_option(*cmd, o->laplacian);
  add_area_option(*cmd, o->area);
  cmd->add_option("--save-basis", o->save_basis, "write the computed eigenpairs to this file");
  cmd->add_option("--load-basis", o->load_basis, "read the eigenpairs from this file instead of computing them");
  cmd->add_option("--basis-size", o->basis_size,
                  "compute this many eigenpairs (at least k, at most the number of vertices), e.g. for --save-basis");
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o, cmd] { run(*o, cmd->count("--laplacian") > 0, cmd->count("--area") > 0); });
}

} // namespace lapmesh_cli
