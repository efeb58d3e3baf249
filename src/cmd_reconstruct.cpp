// lapmesh reconstruct IN -o OUT -k K: the mesh rebuilt from its k smallest eigenvectors,
// x <- sum_{i<k} (x^T M phi_i) phi_i per coordinate, with the input's vertex order and faces.
#include "cli_common.h"
#include "blas_warning.h"

#include <lapmesh/spectral_reconstruction.h>

#include <iostream>
#include <memory>

namespace lapmesh_cli {

namespace {

struct Reconstruct_options
{
  std::string input, output, k, save_basis, load_basis, basis_size;
  std::string laplacian = lapmesh::to_string(lapmesh_ops::Reconstruct_settings{}.laplacian);
  std::string area = lapmesh::to_string(lapmesh_ops::Reconstruct_settings{}.area);
  double mollification = lapmesh::default_mollification_factor;
  bool quiet = false;
};

void run(const Reconstruct_options& o, bool laplacian_given, bool area_given)
{
  check_output_path(o.output, lapmesh_ops::mesh_output_formats());
  Mesh mesh = load_mesh(o.input);
  const long long n = (long long)lapmesh_ops::vertex_count(mesh);
  lapmesh_ops::Reconstruct_settings s;
  s.k = spectral_k_from(o.input, o.k, n);
  s.laplacian = enum_from<lapmesh::Laplacian>(o.laplacian);
  s.area = enum_from<lapmesh::Vertex_area>(o.area);
  s.mollification = o.mollification;
  std::shared_ptr<const lapmesh::Spectral_basis> basis;
  if(!o.load_basis.empty()) {
    basis = or_fail(o.load_basis, [&] {
      auto b = std::make_shared<const lapmesh::Spectral_basis>(lapmesh::Spectral_basis::load(o.load_basis));
      lapmesh_ops::check_basis_fits(*b, mesh, laplacian_given ? std::optional(s.laplacian) : std::nullopt,
                                    area_given ? std::optional(s.area) : std::nullopt);
      return b;
    });
    if(s.k > basis->size())
      throw Failure(o.input + ": -k " + o.k + " is out of range: the basis " + o.load_basis + " holds " +
                    std::to_string(basis->size()) + " eigenpairs");
  } else if(!o.basis_size.empty()) {
    s.basis_size = parse_count_option(o.input, "--basis-size", o.basis_size, 0, n, ", the number of vertices");
  }
  warn_if_slow_blas(o.load_basis.empty());
  lapmesh_ops::Reconstruction r;
  {
    Spectral_progress_line line;
    s.progress = line.printer();
    r = or_fail(o.input, [&] { return lapmesh_ops::reconstruct(mesh, s, basis); });
  }
  print_warnings(o.input, r.warnings);
  if(!o.save_basis.empty()) or_fail(o.save_basis, [&] { r.basis->save(o.save_basis); });
  lapmesh_ops::set_positions(mesh, r.positions);
  or_fail(o.output, [&] { lapmesh_ops::write_mesh(o.output, mesh); });
  if(!o.quiet)
    std::cout << o.input << ": " << n << " vertices reconstructed from " << s.k << " eigenvectors ("
              << lapmesh::to_string(r.basis->laplacian()) << ", " << lapmesh::to_string(r.basis->vertex_area())
              << " area; basis of " << r.basis->size() << "); wrote " << o.output << '\n';
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
  add_mollification_option(*cmd, o->mollification);
  cmd->add_option("--save-basis", o->save_basis, "write the computed eigenpairs to this file");
  cmd->add_option("--load-basis", o->load_basis, "read the eigenpairs from this file instead of computing them");
  cmd->add_option("--basis-size", o->basis_size,
                  "compute this many eigenpairs (at least k, at most the number of vertices), e.g. for --save-basis");
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o, cmd] { run(*o, cmd->count("--laplacian") > 0, cmd->count("--area") > 0); });
}

} // namespace lapmesh_cli
