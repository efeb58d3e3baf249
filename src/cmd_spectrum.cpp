// lapmesh spectrum IN -o OUT.csv -k K: the k smallest Laplace–Beltrami eigenvalues.
#include "cli_common.h"
#include "blas_warning.h"

#include <lapmesh/spectral_reconstruction.h>

#include <iostream>
#include <memory>
#include <string>

namespace lapmesh_cli {

namespace {

struct Spectrum_options
{
  std::string input, output, k;
  std::string laplacian = lapmesh::to_string(lapmesh_ops::Spectral_settings{}.laplacian);
  std::string area = lapmesh::to_string(lapmesh_ops::Spectral_settings{}.area);
  double mollification = lapmesh::default_mollification_factor;
  bool quiet = false;
};

void run(const Spectrum_options& o)
{
  check_output_path(o.output, {"csv"});
  const Mesh mesh = load_mesh(o.input);
  const long long n = (long long)lapmesh_ops::vertex_count(mesh);
  lapmesh_ops::Spectral_settings s;
  s.k = spectral_k_from(o.input, o.k, n);
  s.laplacian = enum_from<lapmesh::Laplacian>(o.laplacian);
  s.area = enum_from<lapmesh::Vertex_area>(o.area);
  s.mollification = o.mollification;
  warn_if_slow_blas();
  std::shared_ptr<const lapmesh::Spectral_basis> basis;
  {
    Spectral_progress_line line;
    s.progress = line.printer();
    basis = or_fail(o.input, [&] { return lapmesh_ops::spectral_basis(mesh, s); });
  }
  const Eigen::VectorXd& values = basis->eigenvalues();
  or_fail(o.output, [&] {
    lapmesh_ops::write_text(o.output, [&](std::ostream& os) {
      os << "index,eigenvalue\n";
      for(long long i = 0; i < s.k; ++i) {
        os << i << ',';
        lapmesh_ops::put_double(os, values[i]);
        os << '\n';
      }
    });
  });
  if(!o.quiet)
    std::cout << o.input << ": " << n << " vertices; " << s.k << " smallest eigenvalues (" << o.laplacian << ", "
              << o.area << " area) in [" << values[0] << ", " << values[s.k - 1] << "]; wrote " << o.output << '\n';
}

} // namespace

void register_spectrum(CLI::App& app)
{
  auto o = std::make_shared<Spectrum_options>();
  CLI::App* cmd = app.add_subcommand("spectrum", "the k smallest eigenvalues of -S phi = lambda M phi");
  cmd->footer("Output: .csv with the header index,eigenvalue and k rows, ascending, 17 significant digits.\n"
              "lambda_0 ~ 0 once per connected component; on a sphere of radius r, l(l+1)/r^2 with\n"
              "multiplicity 2l+1. Progress goes to stderr when it is a terminal.\n");
  add_input_output(*cmd, o->input, o->output, "output file (.csv)");
  cmd->add_option("-k", o->k, "number of eigenvalues, 1 <= k <= number of vertices")->required();
  add_laplacian_option(*cmd, o->laplacian);
  add_area_option(*cmd, o->area);
  add_mollification_option(*cmd, o->mollification);
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
