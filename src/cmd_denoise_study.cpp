// lapmesh denoise-study IN -o OUT.csv: noise + smoothing + deviation from the clean mesh, per
// noise level, scheme, Laplacian, time step and iteration (lapmesh/denoising.h), with an
// optional SVG plot and the best time step per level and scheme on stdout.
#include "cli_common.h"
#include "blas_warning.h"
#include "svg_plot.h"


#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include <unistd.h>

namespace lapmesh_cli {
namespace {

struct Study_options
{
  std::string input, output, plot;
  std::string levels = "0.02,0.05,0.1", schemes = "explicit,implicit", laplacians = "uniform,cotangent";
  std::string lambdas = "0.03,0.1,0.3,1,3";
  std::string lambda_unit = lapmesh::to_string(lapmesh::Denoising_study_settings{}.unit);
  std::string area = lapmesh::to_string(lapmesh::Denoising_study_settings{}.area);
  std::string direction = lapmesh::to_string(lapmesh::Denoising_study_settings{}.noise_direction);
  long long iterations = 20;
  std::uint64_t seed = 1;
  double hausdorff_spacing = 1.0;
  double mollification = lapmesh::default_mollification_factor;
  double progress_interval = 5.0;  // seconds between progress lines when stderr is not a terminal
  bool restore_volume = false, fixed_operator = false, quiet = false, progress = false, no_progress = false;
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

template <typename Enum>
std::vector<Enum> parse_names(const std::string& input, const std::string& option, const std::string& text)
{
  std::vector<Enum> out;
  for(const std::string& item : split(text)) {
    const std::optional<Enum> v = lapmesh::parse<Enum>(item);
    if(!v)
      throw Failure(input + ": " + option + ": unknown value '" + item + "' (expected " + lapmesh::name_list<Enum>() +
                    ")");
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

// Progress on stderr from a watcher thread, so that it shows even while one iteration (a
// factorisation, a Hausdorff sampling) takes long. On a terminal one line is redrawn in place a
// few times a second; elsewhere (a log file, a pipe, CI) a full line is written every
// `interval` seconds.
class Study_progress
{
public:
  Study_progress(bool terminal, double interval, std::size_t total_runs, std::string unit)
      : m_terminal(terminal), m_interval(terminal ? 0.25 : interval), m_unit(std::move(unit)),
        m_start(Clock::now())
  {
    m_state.total_runs = total_runs;
    m_watcher = std::thread([this] { watch(); });
  }
  ~Study_progress() { stop(false); }
  Study_progress(const Study_progress&) = delete;
  Study_progress& operator=(const Study_progress&) = delete;

  void update(const lapmesh::Denoising_progress& p)
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    m_state = p;
    m_started = true;
  }
  /// Stops the watcher; on success, a last line with the total time.
  void stop(bool success)
  {
    {
      std::lock_guard<std::mutex> lock(m_mutex);
      if(m_stopped) return;
      m_stopped = true;
    }
    m_wake.notify_all();
    m_watcher.join();
    if(m_terminal) std::fprintf(stderr, "\r%-100s\r", "");
    if(success)
      std::fprintf(stderr, "denoise-study: %zu runs done in %.1f s\n", m_state.total_runs, seconds());
    std::fflush(stderr);
  }

private:
  using Clock = std::chrono::steady_clock;
  double seconds() const { return std::chrono::duration<double>(Clock::now() - m_start).count(); }

  std::string describe() const  // under the lock
  {
    char buf[320];
    if(!m_started) {
      std::snprintf(buf, sizeof buf, "denoise-study: 0/%zu runs done, %.0f s; measuring the noisy mesh and its bound",
                    m_state.total_runs, seconds());
      return buf;
    }
    const auto& p = m_state;
    std::snprintf(buf, sizeof buf, "denoise-study: %zu/%zu runs done, %.0f s; now level %g, %s %s, lambda %g %s, iteration %d/%d",
                  p.runs_done, p.total_runs, seconds(), p.noise_level, lapmesh::to_string(p.scheme),
                  lapmesh::to_string(p.laplacian), p.time_step, m_unit.c_str(), p.iteration, p.iterations);
    return buf;
  }

  void watch()
  {
    std::unique_lock<std::mutex> lock(m_mutex);
    while(!m_stopped) {
      m_wake.wait_for(lock, std::chrono::duration<double>(m_interval), [this] { return m_stopped; });
      if(m_stopped) break;
      const std::string line = describe();
      if(m_terminal) std::fprintf(stderr, "\r%-100s", line.c_str());
      else std::fprintf(stderr, "%s\n", line.c_str());
      std::fflush(stderr);
    }
  }

  const bool m_terminal;
  const double m_interval;
  const std::string m_unit;
  const Clock::time_point m_start;
  std::mutex m_mutex;
  std::condition_variable m_wake;
  lapmesh::Denoising_progress m_state;
  bool m_started = false, m_stopped = false;
  std::thread m_watcher;
};

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
        best_of_run.empty_note = "no run stayed finite: see the CSV's error column";
        final_of_run.empty_note = "no run reached iteration " + std::to_string(s.iterations) + ": see the CSV's error column";
        final_of_run.dashed = true;
        for(double tau : s.time_steps) {
          const auto best_step = study.best(level, scheme, lap, tau);
          const double run_best = best_step ? best_step->deviation.rms_distance : std::numeric_limits<double>::infinity();
          const std::vector<lapmesh::Denoising_record> run = study.run(level, scheme, lap, tau);
          const bool final_counts = !run.empty() && run.back().iteration == s.iterations &&
                                    lapmesh::Denoising_study::counts_for_best(run.back());
          const double run_final = final_counts ? run.back().deviation.rms_distance : std::nan("");
          best_of_run.x.push_back(tau);
          best_of_run.y.push_back(best_step ? run_best : std::nan(""));
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
        curve.label = std::string(lapmesh::to_string(scheme)) + " " + lapmesh::to_string(lap) +
                      (std::isfinite(best_tau) ? ", lambda " + format(best_tau) : std::string());
        curve.empty_note = "no run stayed finite: see the CSV's error column";
        for(const auto& r : study.run(level, scheme, lap, best_tau)) {
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

// RFC 4180 quoting: error messages hold commas and may hold quotes; empty stays empty.
std::string csv_field(const std::string& text)
{
  if(text.empty()) return text;
  std::string quoted = "\"";
  for(char c : text) {
    if(c == '"') quoted += '"';
    quoted += (c == '\n' || c == '\r') ? ' ' : c;
  }
  return quoted + '"';
}

void write_csv(std::ostream& out, const lapmesh::Denoising_study& study, const std::string& unit)
{
  out << "noise_level,sigma,scheme,laplacian,lambda_" << unit
      << ",lambda,stability_bound,iteration,rms_distance,hausdorff_distance,normal_angle_error_deg,volume_change,status,error\n";
  for(const auto& r : study.records) {
    lapmesh_ops::put_double(out, r.noise_level);
    out << ',';
    lapmesh_ops::put_double(out, r.sigma);
    out << ',' << lapmesh::to_string(r.scheme) << ',' << lapmesh::to_string(r.laplacian) << ',';
    lapmesh_ops::put_double(out, r.time_step);
    out << ',';
    lapmesh_ops::put_double(out, r.lambda);
    out << ',';
    lapmesh_ops::put_double(out, r.stability_bound);
    out << ',' << r.iteration << ',';
    lapmesh_ops::put_double(out, r.deviation.rms_distance);
    out << ',';
    lapmesh_ops::put_double(out, r.deviation.hausdorff_distance);
    out << ',';
    lapmesh_ops::put_double(out, r.deviation.normal_angle_error);
    out << ',';
    lapmesh_ops::put_double(out, r.deviation.volume_change);
    out << ',' << lapmesh::to_string(r.status) << ',' << csv_field(r.message) << '\n';
  }
}

void run(const Study_options& o)
{
  lapmesh::Denoising_study_settings s;
  s.noise_levels = parse_numbers(o.input, "--levels", o.levels, true);
  s.time_steps = parse_numbers(o.input, "--lambdas", o.lambdas, false);
  s.schemes = parse_names<lapmesh::Smoothing_scheme>(o.input, "--schemes", o.schemes);
  s.laplacians = parse_names<lapmesh::Laplacian>(o.input, "--laplacians", o.laplacians);
  // check() names the range; a count beyond int is refused here, quoting it as given.
  if(o.iterations > 1000000)
    throw Failure(o.input + ": --iterations: is too large (" + std::to_string(o.iterations) + ", at most 100000)");
  s.iterations = int(std::max<long long>(o.iterations, -1));
  s.unit = enum_from<lapmesh::Time_step_unit>(o.lambda_unit);
  s.seed = o.seed;
  s.noise_direction = enum_from<lapmesh::Noise_direction>(o.direction);
  s.area = enum_from<lapmesh::Vertex_area>(o.area);
  s.restore_volume = o.restore_volume;
  s.fixed_operator = o.fixed_operator;
  s.hausdorff_spacing = o.hausdorff_spacing;
  s.mollification = o.mollification;
  or_fail(o.input, [&] { lapmesh_ops::check(s); });
  check_output_path(o.output, {"csv"});
  if(!o.plot.empty()) check_output_path(o.plot, {"svg"});

  if(!(o.progress_interval > 0) || !std::isfinite(o.progress_interval))
    throw Failure(o.input + ": --progress-interval must be a positive number of seconds");

  const Mesh mesh = load_mesh(o.input);
  warn_if_slow_blas(std::any_of(s.schemes.begin(), s.schemes.end(), [](auto k) { return k != lapmesh::Smoothing_scheme::explicit_euler; }));
  // Progress by default (a study runs for minutes), off with --quiet unless asked for.
  const bool show_progress = o.progress || (!o.no_progress && !o.quiet);
  std::unique_ptr<Study_progress> progress;
  if(show_progress) {
    const std::size_t total = s.noise_levels.size() * s.schemes.size() * s.laplacians.size() * s.time_steps.size();
    progress = std::make_unique<Study_progress>(isatty(STDERR_FILENO), o.progress_interval, total, o.lambda_unit);
    s.progress = [&progress](const lapmesh::Denoising_progress& p) { progress->update(p); };
  }
  lapmesh::Denoising_study study;
  try {
    study = or_fail(o.input, [&] { return lapmesh_ops::denoise_study(mesh, s); });
  } catch(...) {
    if(progress) progress->stop(false);
    throw;
  }
  if(progress) progress->stop(true);

  // Render everything first, then write: no output at all when something fails.
  std::string plot;
  if(!o.plot.empty()) plot = render_plot(std::filesystem::path(o.input).filename().string(), study, s, o.lambda_unit);
  or_fail(o.output, [&] { lapmesh_ops::write_text(o.output, [&](std::ostream& out) { write_csv(out, study, o.lambda_unit); }); });
  if(!o.plot.empty())
    or_fail(o.plot, [&] { lapmesh_ops::write_text(o.plot, [&](std::ostream& out) { out << plot; }); });

  if(o.quiet) return;
  std::cout << o.input << ": " << lapmesh_ops::vertex_count(mesh) << " vertices; " << study.records.size() << " rows; wrote " << o.output
            << (o.plot.empty() ? "" : " and " + o.plot) << '\n';
  for(const lapmesh_ops::Study_summary_line& line : lapmesh_ops::summarize(study, s)) {
    const char* scheme = lapmesh::to_string(line.scheme);
    std::cout << "level " << line.noise_level << ", " << scheme << ": ";
    if(!line.best) {
      std::cout << "no run stayed bounded\n";
    } else {
      const lapmesh::Denoising_record& best = *line.best;
      std::cout << "best " << lapmesh::to_string(best.laplacian) << " lambda " << best.time_step << " " << o.lambda_unit
                << " (" << best.lambda << "), " << best.iteration << " iteration(s): RMS " << best.deviation.rms_distance
                << " (noisy " << line.noisy_rms << "), Hausdorff " << best.deviation.hausdorff_distance
                << ", normal error " << best.deviation.normal_angle_error << " deg\n";
      if(line.best_is_worse_than_noisy)
        std::cout << "  worse than the noisy input: no " << scheme << " run lowered the RMS distance below the noisy mesh's "
                  << line.noisy_rms << " (try smaller --lambdas or fewer --iterations)\n";
    }
    if(line.stopped_runs > 0)
      std::cout << "  " << line.stopped_runs << " of " << line.runs << " runs stopped early (failed or diverged; the reason "
                << "is in the CSV's error column), e.g. " << line.first_stop_reason << '\n';
    if(line.held_runs > 0)
      std::cout << "  " << line.held_runs << " of " << line.runs << " runs shrank a connected component to nearly a point "
                << "and held it there (status 'held', left out of the best), e.g. " << line.first_hold << '\n';
  }
  if(const double coarsening = study.largest_hausdorff_coarsening(); coarsening > 1)
    std::cout << "Hausdorff grid coarsened, up to " << coarsening << " times the spacing asked, where it would have held more "
              << "than 16 samples per corner\n";
}

} // namespace

void register_denoise_study(CLI::App& app)
{
  auto o = std::make_shared<Study_options>();
  CLI::App* cmd = app.add_subcommand("denoise-study", "add noise, smooth, and measure the error against the clean mesh");
  cmd->footer(
    "For each noise level (sigma = level x mean edge length, the same seed for every level), scheme, Laplacian\n"
    "and lambda, smooths the noisy mesh for --iterations steps and measures after every step: RMS vertex\n"
    "distance and symmetric Hausdorff distance (grid samples of vertices, edges, faces) over the bounding-box\n"
    "diagonal, mean angle between area-weighted vertex normals (degrees), relative volume change (closed\n"
    "meshes). CSV: one row per (level, scheme, laplacian, lambda, iteration), iteration 0 being the noisy\n"
    "mesh. Runs whose RMS error exceeds one bbox diagonal stop as 'diverged'. Prints the best lambda and\n"
    "iteration count per level and scheme (smallest RMS distance). --lambda-unit edge2: lambda x mean edge\n"
    "length^2 of the noisy mesh (cotangent; the uniform Laplacian's lambda is dimensionless); bound: lambda x\n"
    "the explicit stability bound.\n"
    "Runs stopped by an error are 'failed'; the CSV's last column, error, says why (e.g. a face the flow\n"
    "collapsed). The summary says when even the best run is further from the clean mesh than the noisy one.\n"
    "Progress goes to stderr: redrawn on a terminal, otherwise one line every --progress-interval seconds.\n");
  add_input_output(*cmd, o->input, o->output, "output table (.csv)");
  cmd->add_option("--levels", o->levels, "comma-separated noise levels (>= 0)")->capture_default_str();
  cmd->add_option("--schemes", o->schemes, "comma-separated: " + lapmesh::name_list<lapmesh::Smoothing_scheme>())->capture_default_str();
  cmd->add_option("--laplacians", o->laplacians, "comma-separated: " + lapmesh::name_list<lapmesh::Laplacian>())->capture_default_str();
  cmd->add_option("--lambdas", o->lambdas, "comma-separated time steps (> 0), in --lambda-unit")->capture_default_str();
  add_enum_option<lapmesh::Time_step_unit>(*cmd, "--lambda-unit", o->lambda_unit,
                                           "unit of --lambdas: " + lapmesh::name_list<lapmesh::Time_step_unit>());
  cmd->add_option("--iterations", o->iterations, "iterations per run (> 0)")->capture_default_str();
  cmd->add_option("--seed", o->seed, "random seed of the noise")->capture_default_str();
  add_enum_option<lapmesh::Noise_direction>(*cmd, "--direction", o->direction,
                                            "noise direction: " + lapmesh::name_list<lapmesh::Noise_direction>());
  add_area_option(*cmd, o->area);
  add_mollification_option(*cmd, o->mollification);
  cmd->add_flag("--restore-volume", o->restore_volume, "restore the enclosed volume after each step (closed meshes)");
  cmd->add_flag("--fixed-operator", o->fixed_operator, "keep the operator of the noisy mesh for all iterations");
  cmd->add_option("--hausdorff-spacing", o->hausdorff_spacing, "Hausdorff sampling grid spacing, in mean edge lengths (coarser where the grid would exceed 16 samples per corner)")
    ->capture_default_str();
  cmd->add_option("--plot", o->plot, "also write an SVG plot of the error vs iteration and vs lambda");
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success (and no progress, unless --progress)");
  auto* with = cmd->add_flag("--progress", o->progress, "show progress on stderr (the default, except with --quiet)");
  cmd->add_flag("--no-progress", o->no_progress, "show no progress")->excludes(with);
  cmd->add_option("--progress-interval", o->progress_interval,
                  "seconds between progress lines when stderr is not a terminal")
    ->capture_default_str();
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
