#include "cli_common.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

#include <unistd.h>

namespace lapmesh_cli {

std::string spelling(const std::string& parameter, const std::string& value)
{
  if(parameter == "fix_boundary") return "--free-boundary";  // the CLI's flag says the opposite
  if(parameter == "basis") return "--load-basis";
  std::string flag = parameter == "k" ? "-k" : "--" + parameter;
  std::replace(flag.begin(), flag.end(), '_', '-');
  return value.empty() || value == "true" ? flag : flag + " " + value;
}

std::string suggestion_text(const std::vector<lapmesh_ops::Suggestion>& suggestions)
{
  std::string text;
  for(std::size_t i = 0; i < suggestions.size(); ++i)
    text += (i == 0 ? "use " : " or ") + spelling(suggestions[i].parameter, suggestions[i].value);
  return text;
}

void print_warnings(const std::string& input, const std::vector<lapmesh_ops::Warning>& warnings)
{
  for(const auto& w : warnings) {
    std::cerr << input << ": warning: " << w.message;
    if(!w.suggestions.empty()) std::cerr << " (" << suggestion_text(w.suggestions) << ")";
    std::cerr << '\n';
  }
}

namespace {
std::vector<std::string>& pending_notes()
{
  static std::vector<std::string> notes;
  return notes;
}
} // namespace

Mesh load_mesh(const std::string& path)
{
  lapmesh_ops::Loaded_mesh loaded = or_fail(path, [&] { return lapmesh_ops::load_mesh(path); });
  for(const std::string& note : loaded.notes) pending_notes().push_back(path + ": note: " + note);
  return std::move(loaded.mesh);
}

void print_notes()
{
  for(const std::string& note : pending_notes()) std::cerr << note << '\n';
  pending_notes().clear();
}

void check_output_path(const std::string& out, const std::vector<std::string>& allowed)
{
  const std::string ext = lapmesh_ops::extension_of(out);
  std::string list;
  for(const std::string& a : allowed) {
    if(ext == a) return;
    list += (list.empty() ? "." : ", .") + a;
  }
  throw Failure(out + ": unsupported output format '." + ext + "' (expected " + list + ")");
}

void check_output_target(const std::string& input, const std::string& output, bool force)
{
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(output, ec);
  if(ec || !fs::exists(st)) return;  // a new file
  if(fs::equivalent(input, output, ec) && !ec && !force)
    throw Failure(output + ": is the input file " + input +
                  " (also through a link); refusing to overwrite the input (use --force to overwrite it)");
  if(fs::is_directory(st)) return;  // write_atomically() says "it is a directory"
  if(!fs::is_regular_file(st)) throw Failure(output + ": exists and is not a regular file; refusing to replace it");
  const auto writable = fs::perms::owner_write | fs::perms::group_write | fs::perms::others_write;
  if((st.permissions() & writable) == fs::perms::none && !force)
    throw Failure(output + ": the file is read-only; refusing to replace it (use --force to replace it)");
}

void add_input_output(CLI::App& cmd, std::string& input, std::string& output, const std::string& output_help)
{
  cmd.add_option("IN", input, "input mesh (.off, .obj, .ply, .stl)")->required();
  cmd.add_option("-o,--output", output, output_help)->required();
  // Checked once the subcommand's options are parsed, before it reads anything.
  auto force = std::make_shared<bool>(false);
  cmd.add_flag("--force", *force,
               "replace OUT even when it is the input file (same file, also through links) or read-only");
  cmd.parse_complete_callback([&input, &output, force] { check_output_target(input, output, *force); });
}

void add_laplacian_option(CLI::App& cmd, std::string& value)
{
  add_enum_option<lapmesh::Laplacian>(cmd, "--laplacian", value,
                                      "Laplacian: " + lapmesh::name_list<lapmesh::Laplacian>());
}

void add_mollification_option(CLI::App& cmd, double& value)
{
  cmd.add_option("--mollification", value,
                 "intrinsic-delaunay: every edge is lengthened until each triangle has a triangle-inequality "
                 "margin of this factor x the mean edge length (0: none)")
    ->default_val(lapmesh::default_mollification_factor)
    ->check(CLI::Range(0.0, 1.0));
}

void add_area_option(CLI::App& cmd, std::string& value)
{
  add_enum_option<lapmesh::Vertex_area>(cmd, "--area", value,
                                        "vertex area (mass): " + lapmesh::name_list<lapmesh::Vertex_area>());
}

namespace {
// The option's text as given, bounded (it goes into a one-line message).
std::string quoted_excerpt(const std::string& text)
{
  return "'" + (text.size() <= 40 ? text : text.substr(0, 40) + "...") + "'";
}
} // namespace

long long parse_count_option(const std::string& input, const std::string& option, const std::string& text,
                             long long lo, long long hi, const std::string& range_note)
{
  const std::string expected = "expected " + std::to_string(lo) + " <= " + option.substr(option.find_first_not_of('-')) +
                               " <= " + std::to_string(hi) + range_note;
  // Digits only, read without a width limit: a number past 2^64 is out of range, never wrapped.
  const bool negative = !text.empty() && text[0] == '-';
  const std::string digits = negative ? text.substr(1) : text;
  if(digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos)
    throw Failure(input + ": " + option + " " + quoted_excerpt(text) + " is not an integer (" + expected + ")");
  const std::size_t first = std::min(digits.find_first_not_of('0'), digits.size());
  const std::string significant = digits.substr(first);
  const bool fits = significant.size() < 19;  // below 10^18 < 2^63
  const long long magnitude = fits ? (significant.empty() ? 0 : std::stoll(significant)) : 0;
  const long long value = negative ? -magnitude : magnitude;
  if(!fits || value < lo || value > hi)
    throw Failure(input + ": " + option + " " + quoted_excerpt(text) + " is out of range (" + expected + ")");
  return value;
}

long long spectral_k_from(const std::string& input, const std::string& text, long long n)
{
  return parse_count_option(input, "-k", text, 1, n, ", the number of vertices");
}

std::function<void(const lapmesh::Spectral_progress&)> Spectral_progress_line::printer()
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

Spectral_progress_line::~Spectral_progress_line()
{
  if(::isatty(2)) std::fprintf(stderr, "\r%60s\r", "");
}

} // namespace lapmesh_cli
