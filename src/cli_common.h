// The command-line tool's shared glue: loading with file-named errors, output checks, the
// common options, and the CLI's spelling of the operations layer's settings. No geometry
// here: the subcommands parse, call src/operations and write.
#ifndef LAPMESH_SRC_CLI_COMMON_H
#define LAPMESH_SRC_CLI_COMMON_H

#include "operations/operations.h"

#include <lapmesh/errors.h>
#include <lapmesh/types.h>

#include <CLI/CLI.hpp>

#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

namespace lapmesh_cli {

using lapmesh_ops::Mesh;

/// A failure reported to the user as one line on stderr, exit status 1.
class Failure : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// The command line's spelling of a settings field set to `value` ("lambda", "auto" ->
/// "--lambda auto"; "fix_boundary", "false" -> "--free-boundary"); the bare option without
/// a value.
std::string spelling(const std::string& parameter, const std::string& value = "");

/// "use A or B": the suggestions of a warning or an error in the CLI's spelling ("" if none).
std::string suggestion_text(const std::vector<lapmesh_ops::Suggestion>& suggestions);

/// Runs f() and turns any library or I/O exception into Failure("path: what"), the CLI's
/// one-line error; a Parameter_error names the option ("path: --lambda: what", or "path:
/// what (use --option)" when it suggests a value). Failures pass through unchanged.
template <typename Function>
decltype(auto) or_fail(const std::string& path, Function&& f)
{
  try {
    return f();
  } catch(const Failure&) {
    throw;
  } catch(const lapmesh::Parameter_error& e) {
    if(!e.suggested_value().empty())
      throw Failure(path + ": " + e.what() + " (" + suggestion_text({{e.parameter(), e.suggested_value()}}) + ")");
    throw Failure(path + ": " + spelling(e.parameter()) + ": " + e.what());
  } catch(const std::exception& e) {
    throw Failure(path + ": " + e.what());
  }
}

/// Prints the warnings of an operation on stderr, one line each: "IN: warning: what (use ...)".
void print_warnings(const std::string& input, const std::vector<lapmesh_ops::Warning>& warnings);

/// Reads and validates IN; every problem becomes a Failure "IN: what" (with line, vertex or
/// face). Notes about repairs and defects (re-oriented faces, zero-area faces, vertices in
/// no face...) are kept for print_notes(), so that a failing run prints one line only.
Mesh load_mesh(const std::string& path);

/// Prints the notes of the meshes read, one line each: "IN: note: what" (after a success).
void print_notes();

/// Fails unless OUT's extension is one of `allowed` (lower-case, without the dot).
void check_output_path(const std::string& out, const std::vector<std::string>& allowed);

/// Fails when OUT exists and is IN itself (std::filesystem::equivalent: also through
/// symbolic or hard links) or is read-only, unless `force`; fails for an existing OUT that
/// is neither a regular file nor a directory (a device, a FIFO), force or not.
void check_output_target(const std::string& input, const std::string& output, bool force);

/// The positional IN, the required -o OUT and --force of every subcommand; OUT is checked
/// by check_output_target() as soon as the subcommand's arguments are parsed.
void add_input_output(CLI::App& cmd, std::string& input, std::string& output, const std::string& output_help);

/// An option whose values are the names of `Enum` (types.h), checked by CLI11 and listed in
/// --help; `value` holds the name, parse it with enum_from().
template <typename Enum>
CLI::Option* add_enum_option(CLI::App& cmd, const std::string& flags, std::string& value, const std::string& help)
{
  return cmd.add_option(flags, value, help)->check(CLI::IsMember(lapmesh::names<Enum>()))->capture_default_str();
}
/// The enumerator of a name that CLI11 has checked.
template <typename Enum>
Enum enum_from(const std::string& name)
{
  return *lapmesh::parse<Enum>(name);
}

/// Options shared by several subcommands.
void add_laplacian_option(CLI::App& cmd, std::string& value);
/// --mollification F: the intrinsic Delaunay Laplacian's mollification factor.
void add_mollification_option(CLI::App& cmd, double& value);
void add_area_option(CLI::App& cmd, std::string& value);

/// An integer option read from its text (no wrap-around past 2^64), checked against [lo, hi]:
/// the error quotes the text as given (bounded) and names the range.
long long parse_count_option(const std::string& input, const std::string& option, const std::string& text,
                             long long lo, long long hi, const std::string& range_note);

/// Spectral helpers shared by `spectrum` and `reconstruct`: -k parsed and checked against n,
/// and the eigensolver's progress line on a terminal, cleared when the guard goes (success or
/// failure) so that the result or the error starts on a clean line.
long long spectral_k_from(const std::string& input, const std::string& text, long long n);
class Spectral_progress_line
{
public:
  Spectral_progress_line() = default;
  ~Spectral_progress_line();
  Spectral_progress_line(const Spectral_progress_line&) = delete;
  Spectral_progress_line& operator=(const Spectral_progress_line&) = delete;
  /// The callback to pass as the settings' progress (empty when stderr is not a terminal).
  std::function<void(const lapmesh::Spectral_progress&)> printer();
};

/// Subcommand registration (one function per cmd_*.cpp file).
void register_curvature(CLI::App& app);
void register_spectrum(CLI::App& app);
void register_reconstruct(CLI::App& app);
void register_smooth(CLI::App& app);
void register_noise(CLI::App& app);
void register_view(CLI::App& app);  // cmd_view.cpp, when built with LAPMESH_HAS_VIEWER
void register_denoise_study(CLI::App& app);

} // namespace lapmesh_cli

#endif
