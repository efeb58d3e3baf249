// lapmesh denoise-study IN -o OUT.csv: noise + smoothing + deviation from the clean mesh, per
// noise level, scheme, Laplacian, time step and iteration (lapmesh/denoising.h), with an
// optional SVG plot and the best time step per level and scheme on stdout.
#include "cli_common.h"
#include "svg_plot.h"

#include <lapmesh/denoising.h>
#include <lapmesh/io.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include <unistd.h>

namespace lapmesh_cli {
namespace {

struct Study_options
{
  std::string input, output, plot;
  std::string levels = "0.02,0.05,0.1", schemes = "explicit,implicit", laplacians = "uniform,cotangent";
  std::string lambdas = "0.03,0.1,0.3,1,3", lambda_unit = "edge2", area = "barycentric", direction = "isotropic";
  long long iterations = 20;
  std::uint64_t seed = 1;
  double hausdorff_spacing = 1.0;
  bool restore_volume = false, fixed_operator = false, quiet = false;
};

std::vector<std::string> split(const std::string& s)
{
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(s);
  while(std::getline(in, item, ',')) out.push_back(item);
  if(!s.empty() && s.back() == ',') out.push_back("");
  return out;
}

std::vector<double> parse_numbers(const std::string& input, const std::string& option, const std::string& text,
                                  bool allow_zero)
{
  std::vector<double> out;
  for(const std::string& item : split(text)) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if(item.empty() || *end != '\0')
      throw Failure(input + ": " + option + ": expected a comma-separated list of numbers, got '" + text + "'");
    if(!std::isfinite(v) || v < 0 || (!allow_zero && v == 0))
      throw Failure(input + ": " + option + ": every value must be a " + (allow_zero ? "finite number >= 0" : "positive finite number") +
                    " (got " + item + ")");
    out.push_back(v);
  }
  if(out.empty()) throw Failure(input + ": " + option + ": the list is empty");
  return out;
}

template <typename T, typename Parse>
std::vector<T> parse_names(const std::string& input, const std::string& option, const std::string& text,
                           const std::string& allowed, Parse parse)
{
  std::vector<T> out;
  for(const std::string& item : split(text)) {
    const std::optional<T> v = parse(item);
    if(!v) throw Failure(input + ": " + option + ": unknown value '" + item + "' (expected " + allowed + ")");
    out.push_back(*v);
  }
  if(out.empty()) throw Failure(input + ": " + option + ": the list is empty");
  return out;
}

std::string format(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

std::string series_color(lapmesh::Smoothing_scheme s, lapmesh::Laplacian l)
{
  const bool u = l == lapmesh::Laplacian::uniform;
  switch(s) {
    case lapmesh::Smoothing_scheme::explicit_euler: return u ? "#1f77b4" : "#17becf";
    case lapmesh::Smoothing_scheme::implicit_euler: return u ? "#d62728" : "#ff7f0e";
    default: return u ? "#2ca02c" : "#9467bd";
  }
}

std::string render_plot(const std::string& name, const lapmesh::Denoising_study& study,
                        const lapmesh::Denoising_study_settings& s, const std::string& unit)
{
  std::vector<Plot_panel> top, bottom;
  for(double level : s.noise_levels) {
    Plot_panel curves, by_lambda;
    curves.title = "noise level " + format(level) + ": RMS error vs iteration (best lambda)";
    curves.x_label = "iteration";
    curves.y_label = "RMS vertex distance / bbox diagonal";
    curves.log_y = true;
    by_lambda.title = "noise level " + format(level) + ": RMS error vs lambda";
    by_lambda.x_label = "lambda (" + unit + ")";
    by_lambda.y_label = "RMS vertex distance / bbox diagonal";
    by_lambda.log_x = by_lambda.log_y = true;
    for(auto scheme : s.schemes)
      for(auto lap : s.laplacians) {
        // Best time step of this (scheme, Laplacian): the smallest RMS over all iterations.
        double best_tau = std::nan(""), best_rms = std::numeric_limits<double>::infinity();
        Plot_series best_of_run, final_of_run;
        best_of_run.label = std::string(lapmesh::to_string(scheme)) + " " + lapmesh::to_string(lap) + ": best over iterations";
        final_of_run.label = std::string(lapmesh::to_string(scheme)) + " " + lapmesh::to_string(lap) + ": after " +
                             std::to_string(s.iterations) + " iterations";
        best_of_run.color = final_of_run.color = series_color(scheme, lap);
        final_of_run.dashed = true;
        for(double tau : s.time_steps) {
          double run_best = std::numeric_limits<double>::infinity(), run_final = std::nan("");
          for(const auto& r : study.records)
            if(r.noise_level == level && r.scheme == scheme && r.laplacian == lap && r.time_step == tau && r.iteration > 0) {
              if(r.status == lapmesh::Run_status::ok) run_best = std::min(run_best, r.deviation.rms_distance);
              if(r.iteration == s.iterations) run_final = r.status == lapmesh::Run_status::ok ? r.deviation.rms_distance : std::nan("");
            }
          best_of_run.x.push_back(tau);
          best_of_run.y.push_back(std::isfinite(run_best) ? run_best : std::nan(""));
          final_of_run.x.push_back(tau);
          final_of_run.y.push_back(run_final);
          if(run_best < best_rms) {
            best_rms = run_best;
            best_tau = tau;
          }
        }
        by_lambda.series.push_back(best_of_run);
        by_lambda.series.push_back(final_of_run);
        Plot_series curve;
        curve.color = series_color(scheme, lap);
        curve.label = std::string(lapmesh::to_string(scheme)) + " " + lapmesh::to_string(lap) + ", lambda " +
                      (std::isfinite(best_tau) ? format(best_tau) : std::string("-"));
        for(const auto& r : study.records)
          if(r.noise_level == level && r.scheme == scheme && r.laplacian == lap && r.time_step == best_tau) {
            curve.x.push_back(r.iteration);
            curve.y.push_back(r.deviation.rms_distance);
          }
        curves.series.push_back(curve);
      }
    top.push_back(curves);
    bottom.push_back(by_lambda);
  }
  std::vector<Plot_panel> panels = top;
  panels.insert(panels.end(), bottom.begin(), bottom.end());
  std::ostringstream out;
  write_svg_plot(out, "lapmesh denoise-study: " + name + " (iteration 0 = noisy mesh; lambda in " + unit + ")", panels,
                 int(s.noise_levels.size()));
  return out.str();
}

void write_csv(std::ostream& out, const lapmesh::Denoising_study& study, const std::string& unit)
{
  out << "noise_level,sigma,scheme,laplacian,lambda_" << unit
      << ",lambda,stability_bound,iteration,rms_distance,hausdorff_distance,normal_angle_error_deg,volume_change,status\n";
  for(const auto& r : study.records) {
    lapmesh::io::put_double(out, r.noise_level);
    out << ',';
    lapmesh::io::put_double(out, r.sigma);
    out << ',' << lapmesh::to_string(r.scheme) << ',' << lapmesh::to_string(r.laplacian) << ',';
    lapmesh::io::put_double(out, r.time_step);
    out << ',';
    lapmesh::io::put_double(out, r.lambda);
    out << ',';
    lapmesh::io::put_double(out, r.stability_bound);
    out << ',' << r.iteration << ',';
    lapmesh::io::put_double(out, r.deviation.rms_distance);
    out << ',';
    lapmesh::io::put_double(out, r.deviation.hausdorff_distance);
    out << ',';
    lapmesh::io::put_double(out, r.deviation.normal_angle_error);
    out << ',';
    lapmesh::io::put_double(out, r.deviation.volume_change);
    out << ',' << lapmesh::to_string(r.status) << '\n';
  }
}

void run(const Study_options& o)
{
  lapmesh::Denoising_study_settings s;
  s.noise_levels = parse_numbers(o.input, "--levels", o.levels, true);
  s.time_steps = parse_numbers(o.input, "--lambdas", o.lambdas, false);
  s.schemes = parse_names<lapmesh::Smoothing_scheme>(o.input, "--schemes", o.schemes, "explicit, implicit, conformal", lapmesh::parse_smoothing_scheme);
  s.laplacians = parse_names<lapmesh::Laplacian>(o.input, "--laplacians", o.laplacians, "uniform, cotangent",
                                                 [](const std::string& v) { return lapmesh::parse_laplacian(v); });
  if(o.iterations <= 0)
    throw Failure(o.input + ": --iterations must be a positive integer (got " + std::to_string(o.iterations) + ")");
  if(o.iterations > 100000) throw Failure(o.input + ": --iterations is too large (" + std::to_string(o.iterations) + ")");
  if(!(o.hausdorff_spacing > 0) || !std::isfinite(o.hausdorff_spacing))
    throw Failure(o.input + ": --hausdorff-spacing must be a positive number");
  s.iterations = int(o.iterations);
  s.unit = *lapmesh::parse_time_step_unit(o.lambda_unit);  // CLI11 checked the name
  s.seed = o.seed;
  s.noise_direction = o.direction == "normal" ? lapmesh::Noise_direction::normal : lapmesh::Noise_direction::isotropic;
  s.area = area_from(o.area);
  s.restore_volume = o.restore_volume;
  s.fixed_operator = o.fixed_operator;
  s.hausdorff_spacing = o.hausdorff_spacing;
  check_output_path(o.output, {"csv"});
  if(!o.plot.empty()) check_output_path(o.plot, {"svg"});

  const Mesh mesh = load_mesh(o.input);
  const bool tty = isatty(STDERR_FILENO) && !o.quiet;
  if(tty)
    s.progress = [](std::size_t done, std::size_t total) {
      std::cerr << "\rdenoise-study: run " << done << '/' << total << (done == total ? "\n" : "") << std::flush;
    };
  const lapmesh::Denoising_study study = or_fail(o.input, [&] { return lapmesh::run_denoising_study(mesh, s); });

  // Render everything first, then write: no output at all when something fails.
  std::string plot;
  if(!o.plot.empty()) plot = render_plot(std::filesystem::path(o.input).filename().string(), study, s, o.lambda_unit);
  or_fail(o.output, [&] { lapmesh::io::write_atomically(o.output, [&](std::ostream& out) { write_csv(out, study, o.lambda_unit); }); });
  if(!o.plot.empty())
    or_fail(o.plot, [&] { lapmesh::io::write_atomically(o.plot, [&](std::ostream& out) { out << plot; }); });

  if(o.quiet) return;
  std::cout << o.input << ": " << num_vertices(mesh) << " vertices; " << study.records.size() << " rows; wrote " << o.output
            << (o.plot.empty() ? "" : " and " + o.plot) << '\n';
  for(double level : s.noise_levels) {
    double noisy = std::nan("");
    for(const auto& r : study.records)
      if(r.noise_level == level && r.iteration == 0) noisy = r.deviation.rms_distance;
    for(auto scheme : s.schemes) {
      std::cout << "level " << level << ", " << lapmesh::to_string(scheme) << ": ";
      const auto best = study.best(level, scheme);
      if(!best) {
        std::cout << "no run stayed bounded\n";
        continue;
      }
      std::cout << "best " << lapmesh::to_string(best->laplacian) << " lambda " << best->time_step << " " << o.lambda_unit
                << " (" << best->lambda << "), " << best->iteration << " iteration(s): RMS " << best->deviation.rms_distance
                << " (noisy " << noisy << "), Hausdorff " << best->deviation.hausdorff_distance << ", normal error "
                << best->deviation.normal_angle_error << " deg\n";
    }
  }
}

} // namespace

void register_denoise_study(CLI::App& app)
{
  auto o = std::make_shared<Study_options>();
  CLI::App* cmd = app.add_subcommand("denoise-study", "add noise, smooth, and measure the error against the clean mesh");
  cmd->footer(
    "For each noise level (sigma = level x mean edge length, the same seed for every level), scheme, Laplacian\n"
    "and lambda, smooths the noisy mesh for --iterations steps and measures after every step: RMS vertex\n"
    "distance and symmetric Hausdorff distance (CGAL, grid sampling) over the bounding-box diagonal, mean angle\n"
    "between area-weighted vertex normals (degrees), relative volume change (closed meshes). CSV: one row per\n"
    "(level, scheme, laplacian, lambda, iteration), iteration 0 being the noisy mesh. Runs whose RMS error\n"
    "exceeds one bbox diagonal stop as 'diverged'. Prints the best lambda and iteration count per level and\n"
    "scheme (smallest RMS distance). --lambda-unit edge2: lambda x mean edge length^2 of the noisy mesh\n"
    "(cotangent; the uniform Laplacian's lambda is dimensionless); bound: lambda x the explicit stability bound.\n");
  add_input_output(*cmd, o->input, o->output, "output table (.csv)");
  cmd->add_option("--levels", o->levels, "comma-separated noise levels (>= 0)")->capture_default_str();
  cmd->add_option("--schemes", o->schemes, "comma-separated: explicit, implicit, conformal")->capture_default_str();
  cmd->add_option("--laplacians", o->laplacians, "comma-separated: uniform, cotangent")->capture_default_str();
  cmd->add_option("--lambdas", o->lambdas, "comma-separated time steps (> 0), in --lambda-unit")->capture_default_str();
  cmd->add_option("--lambda-unit", o->lambda_unit, "unit of --lambdas: edge2, bound or absolute")
    ->check(CLI::IsMember({"absolute", "edge2", "bound"}))
    ->capture_default_str();
  cmd->add_option("--iterations", o->iterations, "iterations per run (> 0)")->capture_default_str();
  cmd->add_option("--seed", o->seed, "random seed of the noise")->capture_default_str();
  cmd->add_option("--direction", o->direction, "noise direction: isotropic or normal")
    ->check(CLI::IsMember({"isotropic", "normal"}))
    ->capture_default_str();
  add_area_option(*cmd, o->area);
  cmd->add_flag("--restore-volume", o->restore_volume, "restore the enclosed volume after each step (closed meshes)");
  cmd->add_flag("--fixed-operator", o->fixed_operator, "keep the operator of the noisy mesh for all iterations");
  cmd->add_option("--hausdorff-spacing", o->hausdorff_spacing, "Hausdorff sampling grid spacing, in mean edge lengths")
    ->capture_default_str();
  cmd->add_option("--plot", o->plot, "also write an SVG plot of the error vs iteration and vs lambda");
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
