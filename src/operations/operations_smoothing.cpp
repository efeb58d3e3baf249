// The smoothing operations: Laplacian smoothing, noise and the denoising study.
#include "operations.h"
#include "numbering.h"

#include <lapmesh/denoising.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/noise.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace lapmesh_ops {

namespace {

using lapmesh::message_number;

// The text of an option as given, bounded: it goes into a one-line message.
std::string bounded(const std::string& text) { return text.size() <= 40 ? text : text.substr(0, 40) + "..."; }

// One line for the components a flow shrank to nearly a point and held there.
std::string collapsed_components_message(const std::vector<lapmesh::Collapsed_component>& collapsed)
{
  const lapmesh::Collapsed_component& first = collapsed.front();
  const std::string where = "the connected component of vertex " + std::to_string(first.first_vertex) + " (" +
                            std::to_string(first.vertices) + " vertices) at iteration " +
                            std::to_string(first.iteration);
  if(collapsed.size() == 1)
    return "the flow shrank " + where + " to nearly a point; it was held there for the remaining steps while the "
                                        "other components went on";
  std::size_t vertices = 0;
  for(const auto& c : collapsed) vertices += c.vertices;
  return "the flow shrank " + std::to_string(collapsed.size()) + " connected components (" +
         std::to_string(vertices) + " vertices) to nearly a point, the first " + where +
         "; each was held there for the remaining steps while the other components went on";
}

} // namespace

Time_step parse_time_step(const std::string& text, lapmesh::Time_step_unit unit)
{
  Time_step t;
  t.unit = unit;
  if(text == "auto") return t;
  char* end = nullptr;
  t.automatic = false;
  t.value = std::strtod(text.c_str(), &end);
  if(text.empty() || *end != '\0')
    throw lapmesh::Parameter_error("lambda", "expected a positive number or 'auto', got '" + bounded(text) + "'");
  if(!(t.value > 0) || !std::isfinite(t.value))
    throw lapmesh::Parameter_error("lambda", "must be a positive finite time step (got " + bounded(text) + ")");
  return t;
}

void check(const Smooth_settings& s, const Smoothing_limits& limits)
{
  if(!s.lambda.automatic && (!(s.lambda.value > 0) || !std::isfinite(s.lambda.value) || s.lambda.value > limits.max_lambda))
    throw lapmesh::Parameter_error("lambda", "must be a positive finite time step" +
                                               std::string(std::isfinite(limits.max_lambda)
                                                             ? " at most " + message_number(limits.max_lambda)
                                                             : "") +
                                               " (got " + message_number(s.lambda.value) + ")");
  if(s.iterations <= 0)
    throw lapmesh::Parameter_error("iterations", "must be a positive integer (got " + std::to_string(s.iterations) + ")");
  if(s.iterations > limits.max_iterations)
    throw lapmesh::Parameter_error("iterations", "is too large (" + std::to_string(s.iterations) + ", at most " +
                                                   std::to_string(limits.max_iterations) + ")");
}

namespace {
template <typename Numbering>
Smooth_result smooth_numbered(Mesh& mesh, const Smooth_settings& s, const Numbering& numbering)
{
  namespace LP = lapmesh::parameters;
  const auto base = LP::fix_boundary(
    s.fix_boundary,
    LP::mollification_factor(s.mollification, LP::vertex_area(s.area, LP::laplacian(s.laplacian, numbering))));
  Smooth_result out;
  // The explicit scheme's bound is computed once, by explicit_stability_bound() on the input's
  // free vertices, and serves the automatic step, the bound unit, the warning and the report: the
  // smoother is handed it, and would otherwise compute it again where lambda exceeds the
  // Gershgorin bound (as 0.9 of it does).
  const bool explicit_scheme = s.scheme == lapmesh::Smoothing_scheme::explicit_euler;
  if(explicit_scheme) out.stability_bound = lapmesh::explicit_stability_bound(mesh, base);
  // With no free vertex the bound is infinite and a step relative to it undefined.
  if(explicit_scheme && std::isinf(out.stability_bound) &&
     (s.lambda.automatic || s.lambda.unit == lapmesh::Time_step_unit::stability_bound))
    throw lapmesh::Parameter_error("fix_boundary",
                                   "no vertex is free to move (every vertex is on the fixed boundary), so the "
                                   "explicit stability bound is undefined",
                                   "false");
  if(s.lambda.automatic)
    out.lambda = explicit_scheme ? lapmesh::automatic_explicit_time_step(out.stability_bound)
                                 : lapmesh::automatic_time_step(mesh, s.scheme, base);
  else
    out.lambda = explicit_scheme && s.lambda.unit == lapmesh::Time_step_unit::stability_bound
                   ? s.lambda.value * out.stability_bound
                   : lapmesh::time_step(mesh, s.lambda.value, s.lambda.unit, base);

  const auto np = LP::known_stability_bound(
                    out.stability_bound,
                    LP::reuse_factorization(
                      s.reuse_factorization,
                      LP::progress_callback(
                        s.progress,
                        LP::restore_area(s.restore_area,
                                         LP::restore_volume(s.restore_volume, LP::fixed_operator(s.fixed_operator, base))))))
                    .number_of_iterations(unsigned(s.iterations));
  Mesh work = mesh;  // a cancelled or failed run leaves the mesh as it was
  switch(s.scheme) {
    case lapmesh::Smoothing_scheme::explicit_euler:
      out.report = lapmesh::smooth_laplacian_explicit<CGAL::Parallel_if_available_tag>(work, out.lambda, np);
      break;
    case lapmesh::Smoothing_scheme::implicit_euler:
      out.report = lapmesh::smooth_laplacian_implicit<CGAL::Parallel_if_available_tag>(work, out.lambda, np);
      break;
    case lapmesh::Smoothing_scheme::conformal:
      out.report = lapmesh::smooth_conformal_flow<CGAL::Parallel_if_available_tag>(work, out.lambda, np);
      break;
  }
  mesh = std::move(work);
  if(!out.report.collapsed_components.empty())
    out.warnings.push_back({collapsed_components_message(out.report.collapsed_components), {{"fixed_operator", "true"}}});
  if(explicit_scheme && out.lambda > out.stability_bound)
    out.warnings.push_back({"lambda " + message_number(out.lambda) + " exceeds the explicit stability bound " +
                              message_number(out.stability_bound),
                            {{"lambda", "auto"}, {"lambda_unit", "bound"}}});
  return out;
}
} // namespace

Smooth_result smooth(Mesh& mesh, const Smooth_settings& s, const Smoothing_limits& limits)
{
  check(s, limits);
  return with_numbering(mesh, [&](const auto& numbering) { return smooth_numbered(mesh, s, numbering); });
}

void check(const Noise_settings& s)
{
  if(!(s.level >= 0) || !std::isfinite(s.level))
    throw lapmesh::Parameter_error("level", "must be a finite number >= 0 (got " + message_number(s.level) + ")");
}

double add_noise(Mesh& mesh, const Noise_settings& s)
{
  check(s);
  namespace LP = lapmesh::parameters;
  return with_numbering(mesh, [&](const auto& np) {
    return lapmesh::add_noise(mesh, s.level,
                              LP::noise_seed(s.seed, LP::noise_direction(s.direction, LP::noise_scale(s.scale, np))));
  });
}

void check(const lapmesh::Denoising_study_settings& s)
{
  if(s.iterations <= 0)
    throw lapmesh::Parameter_error("iterations", "must be a positive integer (got " + std::to_string(s.iterations) + ")");
  if(s.iterations > 100000)
    throw lapmesh::Parameter_error("iterations", "is too large (" + std::to_string(s.iterations) + ", at most 100000)");
  if(!(s.hausdorff_spacing > 0) || !std::isfinite(s.hausdorff_spacing))
    throw lapmesh::Parameter_error("hausdorff_spacing", "must be a positive number");
}

lapmesh::Denoising_study denoise_study(const Mesh& mesh, const lapmesh::Denoising_study_settings& settings)
{
  check(settings);
  return with_numbering(mesh, [&](const auto& np) { return lapmesh::run_denoising_study<CGAL::Parallel_if_available_tag>(mesh, settings, np); });
}

std::vector<Study_summary_line> summarize(const lapmesh::Denoising_study& study,
                                          const lapmesh::Denoising_study_settings& s)
{
  std::vector<Study_summary_line> lines;
  for(double level : s.noise_levels) {
    double noisy = std::nan("");
    for(const auto& r : study.records)
      if(r.noise_level == level && r.iteration == 0) noisy = r.deviation.rms_distance;
    for(auto scheme : s.schemes) {
      Study_summary_line line;
      line.noise_level = level;
      line.scheme = scheme;
      line.noisy_rms = noisy;
      line.best = study.best(level, scheme);
      line.best_is_worse_than_noisy = line.best && !(line.best->deviation.rms_distance < noisy);
      for(const auto& r : study.records)
        if(r.noise_level == level && r.scheme == scheme && r.iteration == s.iterations) {
          ++line.runs;
          if(r.status == lapmesh::Run_status::ok) continue;
          const bool held = r.status == lapmesh::Run_status::held;
          ++(held ? line.held_runs : line.stopped_runs);
          std::string& reason = held ? line.first_hold : line.first_stop_reason;
          if(reason.empty()) {
            char tau[32];
            std::snprintf(tau, sizeof tau, "%.3g", r.time_step);
            reason = std::string(lapmesh::to_string(r.laplacian)) + " lambda " + tau + ": " + r.message;
          }
        }
      lines.push_back(std::move(line));
    }
  }
  return lines;
}

} // namespace lapmesh_ops
