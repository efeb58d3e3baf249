// lapmesh spectrum IN -o OUT.csv -k K: the k smallest Laplace–Beltrami eigenvalues.
#include "cli_common.h"

#include <lapmesh/io.h>
#include <lapmesh/spectral_reconstruction.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include <unistd.h>

namespace lapmesh_cli {

namespace {

// The progress line of the eigensolver, shown only when stderr is a terminal.
std::function<void(const lapmesh::Spectral_progress&)> spectral_progress_printer()
{
  if(!::isatty(2)) return {};
  // The block solver reports after every block step (hundreds per second on small meshes):
  // redraw on a new stage or attempt, otherwise at most ten times a second.
  return [last_stage = std::string(), last_attempt = 0, last_time = -1.0](const lapmesh::Spectral_progress& p) mutable {
    if(p.stage == last_stage && p.attempt == last_attempt && p.elapsed_seconds < last_time + 0.1) return;
    last_stage = p.stage;
    last_attempt = p.attempt;
    last_time = p.elapsed_seconds;
    std::fprintf(stderr, "\r%s (attempt %d): %lld solves, %.1f s   ", p.stage, p.attempt, p.operations,
                 p.elapsed_seconds);
    std::fflush(stderr);
  };
}

void clear_progress_line()
{
  if(::isatty(2)) std::fprintf(stderr, "\r%60s\r", "");
}

struct Spectrum_options
{
  std::string input, output, laplacian = "cotangent", area = "barycentric", k;
  bool quiet = false;
};

void run(const Spectrum_options& o)
{
  check_output_path(o.output, {"csv"});
  const Mesh mesh = load_mesh(o.input);
  const long long n = (long long)num_vertices(mesh);
  const long long k = spectral_k_from(o.input, o.k, n);
  const lapmesh::Spectral_basis basis = compute_spectral_basis(o.input, mesh, k, o.laplacian, o.area);
  or_fail(o.output, [&] {
    lapmesh::io::write_atomically(o.output, [&](std::ostream& os) {
      os << "index,eigenvalue\n";
      for(long long i = 0; i < k; ++i) {
        os << i << ',';
        lapmesh::io::put_double(os, basis.eigenvalues()[i]);
        os << '\n';
      }
    });
  });
  if(!o.quiet)
    std::cout << o.input << ": " << n << " vertices; " << k << " smallest eigenvalues (" << o.laplacian << ", "
              << o.area << " area) in [" << basis.eigenvalues()[0] << ", " << basis.eigenvalues()[k - 1]
              << "]; wrote " << o.output << '\n';
}

} // namespace

lapmesh::Spectral_basis compute_spectral_basis(const std::string& input, const Mesh& mesh, long long count,
                                               const std::string& laplacian, const std::string& area)
{
  namespace LP = lapmesh::parameters;
  try {
    lapmesh::Spectral_basis basis = or_fail(input, [&] {
      return lapmesh::Spectral_basis::compute<CGAL::Parallel_if_available_tag>(
        mesh, count,
        LP::spectral_progress(spectral_progress_printer(),
                              LP::vertex_area(area_from(area), LP::laplacian(laplacian_from(laplacian)))));
    });
    clear_progress_line();
    return basis;
  } catch(...) {
    clear_progress_line();
    throw;
  }
}

long long spectral_k_from(const std::string& input, const std::string& text, long long n)
{
  return parse_count_option(input, "-k", text, 1, n, ", the number of vertices");
}

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
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
