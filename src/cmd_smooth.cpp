// lapmesh smooth IN -o OUT: explicit / implicit Laplacian smoothing, conformalized MCF.
#include "cli_common.h"
#include "blas_warning.h"

#include <iostream>
#include <memory>

#include <unistd.h>

namespace lapmesh_cli {
namespace {

struct Smooth_options
{
  std::string input, output;
  std::string scheme, lambda;
  std::string lambda_unit = lapmesh::to_string(lapmesh_ops::Time_step{}.unit);
  std::string laplacian = lapmesh::to_string(lapmesh_ops::Smooth_settings{}.laplacian);
  std::string area = lapmesh::to_string(lapmesh_ops::Smooth_settings{}.area);
  double mollification = lapmesh::default_mollification_factor;
  long long iterations = 0;
  bool fixed_operator = false, restore_volume = false, restore_area = false, free_boundary = false,
       reuse_factorization = false, quiet = false;
};

void run(const Smooth_options& o)
{
  lapmesh_ops::Smooth_settings s;
  s.scheme = enum_from<lapmesh::Smoothing_scheme>(o.scheme);
  s.laplacian = enum_from<lapmesh::Laplacian>(o.laplacian);
  s.area = enum_from<lapmesh::Vertex_area>(o.area);
  s.mollification = o.mollification;
  s.iterations = o.iterations;
  s.fixed_operator = o.fixed_operator;
  s.restore_volume = o.restore_volume;
  s.restore_area = o.restore_area;
  s.fix_boundary = !o.free_boundary;
  s.reuse_factorization = o.reuse_factorization;
  // Everything that does not need the mesh is checked first: no work, no output on bad options.
  or_fail(o.input, [&] {
    s.lambda = lapmesh_ops::parse_time_step(o.lambda, enum_from<lapmesh::Time_step_unit>(o.lambda_unit));
    lapmesh_ops::check(s);
  });
  check_output_path(o.output, lapmesh_ops::mesh_output_formats());

  Mesh mesh = load_mesh(o.input);
  warn_if_slow_blas(s.scheme != lapmesh::Smoothing_scheme::explicit_euler);
  const bool tty = isatty(STDERR_FILENO);
  if(tty && !o.quiet)
    s.progress = [](int done, int total) {
      std::cerr << "\rsmoothing: iteration " << done << '/' << total << (done == total ? "\n" : "") << std::flush;
    };
  lapmesh_ops::Smooth_result result;
  try {
    result = or_fail(o.input, [&] { return lapmesh_ops::smooth(mesh, s); });
  } catch(...) {
    if(s.progress) std::cerr << '\n';
    throw;
  }
  print_warnings(o.input, result.warnings);
  or_fail(o.output, [&] { lapmesh_ops::write_mesh(o.output, mesh); });
  if(!o.quiet) {
    std::cout << o.input << ": " << lapmesh_ops::vertex_count(mesh) << " vertices (" << result.report.free_vertices << " free); "
              << o.scheme << " " << o.laplacian << " smoothing, lambda " << result.lambda << ", "
              << result.report.iterations << " iteration(s)";
    if(s.scheme == lapmesh::Smoothing_scheme::explicit_euler) std::cout << ", stability bound " << result.stability_bound;
    std::cout << "; wrote " << o.output << '\n';
  }
}

} // namespace

void register_smooth(CLI::App& app)
{
  auto o = std::make_shared<Smooth_options>();
  CLI::App* cmd = app.add_subcommand("smooth", "explicit or implicit Laplacian smoothing (mean curvature flow)");
  cmd->footer(
    "explicit: P <- P + lambda L P, stable only for lambda below 2/mu_max (mu_max: largest eigenvalue of -L on\n"
    "the free vertices of the input, computed by Lanczos and printed); a warning is printed above it.\n"
    "implicit: (M - lambda S) P' = M P (backward Euler, sparse Cholesky). conformal: Kazhdan et al. 2012.\n"
    "The operator is rebuilt from the current positions every iteration unless --fixed-operator.\n"
    "Boundary vertices stay fixed unless --free-boundary. --lambda auto: 0.9 x the stability bound (explicit) or one mean edge\n"
    "length squared (implicit, conformal). --lambda-unit edge2: lambda x mean edge length^2 (scale-free;\n"
    "the uniform Laplacian is already dimensionless); bound: lambda x the explicit stability bound.\n");
  add_input_output(*cmd, o->input, o->output, "output mesh (.off, .obj, .ply, .stl)");
  add_enum_option<lapmesh::Smoothing_scheme>(*cmd, "--scheme", o->scheme,
                                             lapmesh::name_list<lapmesh::Smoothing_scheme>())
    ->required();
  cmd->add_option("--lambda", o->lambda, "time step (> 0) or 'auto'")->required();
  add_enum_option<lapmesh::Time_step_unit>(*cmd, "--lambda-unit", o->lambda_unit,
                                           "unit of --lambda: " + lapmesh::name_list<lapmesh::Time_step_unit>());
  cmd->add_option("--iterations", o->iterations, "number of iterations (> 0)")->required();
  add_laplacian_option(*cmd, o->laplacian);
  add_area_option(*cmd, o->area);
  add_mollification_option(*cmd, o->mollification);
  cmd->add_flag("--fixed-operator", o->fixed_operator, "keep the operator of the input mesh for all iterations");
  cmd->add_flag("--restore-volume", o->restore_volume,
                "rescale to the input's enclosed volume and centroid after each step (closed meshes)");
  cmd->add_flag("--restore-area", o->restore_area,
                "rescale to the input's surface area and area centroid after each step (no fixed vertex: "
                "with a boundary, add --free-boundary)");
  cmd->add_flag("--free-boundary", o->free_boundary, "boundary vertices move with the flow (natural boundary condition)");
  cmd->add_flag("--reuse-factorization", o->reuse_factorization,
                "implicit: solve by CG preconditioned with the previous Cholesky factor, refactorise only when needed");
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
