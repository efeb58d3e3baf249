// lapmesh smooth IN -o OUT: explicit / implicit Laplacian smoothing, conformalized MCF.
#include "cli_common.h"

#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <memory>

#include <unistd.h>

namespace lapmesh_cli {
namespace {

struct Smooth_options
{
  std::string input, output;
  std::string scheme, lambda, lambda_unit = "absolute", laplacian = "cotangent", area = "barycentric";
  long long iterations = 0;
  bool fixed_operator = false, restore_volume = false, restore_area = false, free_boundary = false,
       reuse_factorization = false, quiet = false;
};

void run(const Smooth_options& o)
{
  // Validate everything that does not need the mesh first: no work, no output on bad options.
  bool lambda_auto = o.lambda == "auto";
  double lambda_value = 0;
  if(!lambda_auto) {
    char* end = nullptr;
    lambda_value = std::strtod(o.lambda.c_str(), &end);
    if(o.lambda.empty() || *end != '\0')
      throw Failure(o.input + ": --lambda: expected a positive number or 'auto', got '" + o.lambda + "'");
    if(!(lambda_value > 0) || !std::isfinite(lambda_value))
      throw Failure(o.input + ": --lambda must be a positive finite time step (got " + o.lambda + ")");
  }
  if(o.iterations <= 0)
    throw Failure(o.input + ": --iterations must be a positive integer (got " + std::to_string(o.iterations) + ")");
  if(o.iterations > 100000000)
    throw Failure(o.input + ": --iterations is too large (" + std::to_string(o.iterations) + ")");
  check_output_path(o.output, {"off", "obj", "ply", "stl"});

  Mesh mesh = load_mesh(o.input);
  const auto scheme = *lapmesh::parse_smoothing_scheme(o.scheme);  // CLI11 checked the names
  const auto lap = laplacian_from(o.laplacian);
  const auto area = area_from(o.area);
  const auto base = lapmesh::parameters::fix_boundary(
    !o.free_boundary, lapmesh::parameters::vertex_area(area, lapmesh::parameters::laplacian(lap)));

  const bool tty = isatty(STDERR_FILENO);
  std::function<void(int, int)> progress;
  if(tty && !o.quiet)
    progress = [](int done, int total) {
      std::cerr << "\rsmoothing: iteration " << done << '/' << total << (done == total ? "\n" : "") << std::flush;
    };

  lapmesh::Smoothing_report report;
  double lambda = lambda_value;
  // The explicit scheme's bound is computed once, by explicit_stability_bound() on the input's
  // free vertices, and serves --lambda auto, --lambda-unit bound, the warning and the printed
  // figure (the smoother's own report may hold a cheaper Gershgorin bound instead).
  const bool explicit_scheme = scheme == lapmesh::Smoothing_scheme::explicit_euler;
  double bound = std::numeric_limits<double>::quiet_NaN();
  try {
    if(explicit_scheme) bound = lapmesh::explicit_stability_bound(mesh, base);
    const auto unit = *lapmesh::parse_time_step_unit(o.lambda_unit);
    if(lambda_auto)
      lambda = explicit_scheme ? lapmesh::automatic_explicit_time_step(bound)
                               : lapmesh::automatic_time_step(mesh, scheme, base);
    else
      lambda = explicit_scheme && unit == lapmesh::Time_step_unit::stability_bound
                 ? lambda_value * bound
                 : lapmesh::time_step(mesh, lambda_value, unit, base);

    auto np = lapmesh::parameters::reuse_factorization(o.reuse_factorization, lapmesh::parameters::progress_callback(
      progress, lapmesh::parameters::restore_area(
                  o.restore_area, lapmesh::parameters::restore_volume(
                                    o.restore_volume, lapmesh::parameters::fixed_operator(o.fixed_operator, base)))))
                .number_of_iterations(unsigned(o.iterations));
    switch(scheme) {
      case lapmesh::Smoothing_scheme::explicit_euler:
        report = lapmesh::smooth_laplacian_explicit<CGAL::Parallel_if_available_tag>(mesh, lambda, np);
        break;
      case lapmesh::Smoothing_scheme::implicit_euler:
        report = lapmesh::smooth_laplacian_implicit<CGAL::Parallel_if_available_tag>(mesh, lambda, np);
        break;
      default:
        report = lapmesh::smooth_conformal_flow<CGAL::Parallel_if_available_tag>(mesh, lambda, np);
    }
  } catch(const std::exception& e) {
    if(tty && progress) std::cerr << '\n';
    throw Failure(o.input + ": " + e.what());
  }
  if(explicit_scheme && lambda > bound)
    std::cerr << o.input << ": warning: lambda " << lambda << " exceeds the explicit stability bound " << bound
              << " (use --lambda auto or --lambda-unit bound)\n";
  try {
    const auto [P, tris] = lapmesh::io::mesh_arrays(mesh);
    lapmesh::io::write_mesh(o.output, P, tris);
  } catch(const lapmesh::Io_error& e) {
    throw Failure(o.output + ": " + e.what());
  }
  if(!o.quiet) {
    std::cout << o.input << ": " << num_vertices(mesh) << " vertices (" << report.free_vertices << " free); "
              << o.scheme << " " << o.laplacian << " smoothing, lambda " << lambda << ", " << report.iterations
              << " iteration(s)";
    if(explicit_scheme) std::cout << ", stability bound " << bound;
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
  cmd->add_option("--scheme", o->scheme, "explicit, implicit or conformal")
    ->check(CLI::IsMember({"explicit", "implicit", "conformal"}))
    ->required();
  cmd->add_option("--lambda", o->lambda, "time step (> 0) or 'auto'")->required();
  cmd->add_option("--lambda-unit", o->lambda_unit, "unit of --lambda: absolute, edge2 or bound")
    ->check(CLI::IsMember({"absolute", "edge2", "bound"}))
    ->capture_default_str();
  cmd->add_option("--iterations", o->iterations, "number of iterations (> 0)")->required();
  add_laplacian_option(*cmd, o->laplacian);
  add_area_option(*cmd, o->area);
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
