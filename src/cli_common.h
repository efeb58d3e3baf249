// The command-line tool's shared glue: the mesh type, loading with file-named errors, output
// checks and the common options. No geometry here: that lives in include/lapmesh.
#ifndef LAPMESH_SRC_CLI_COMMON_H
#define LAPMESH_SRC_CLI_COMMON_H

#include <lapmesh/parameters.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <CLI/CLI.hpp>

#include <initializer_list>
#include <stdexcept>
#include <string>

namespace lapmesh {
class Spectral_basis;
}

namespace lapmesh_cli {

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;

/// A failure reported to the user as one line on stderr, exit status 1.
class Failure : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// Reads and validates IN; every problem becomes a Failure "IN: what" (with line, vertex or
/// face). Notes about repairs (re-oriented faces, triangulated polygons) go to stderr.
Mesh load_mesh(const std::string& path);

/// Fails unless OUT's extension is one of `allowed` (lower-case, without the dot).
void check_output_path(const std::string& out, std::initializer_list<const char*> allowed);

/// Runs f() and turns any library or I/O exception into Failure("path: what"), the CLI's
/// one-line error. Failures pass through unchanged.
template <typename Function>
decltype(auto) or_fail(const std::string& path, Function&& f)
{
  try {
    return f();
  } catch(const Failure&) {
    throw;
  } catch(const std::exception& e) {
    throw Failure(path + ": " + e.what());
  }
}

/// Fails when OUT exists and is IN itself (std::filesystem::equivalent: also through
/// symbolic or hard links) or is read-only, unless `force`; fails for an existing OUT that
/// is neither a regular file nor a directory (a device, a FIFO), force or not.
void check_output_target(const std::string& input, const std::string& output, bool force);

/// The positional IN, the required -o OUT and --force of every subcommand; OUT is checked
/// by check_output_target() as soon as the subcommand's arguments are parsed.
void add_input_output(CLI::App& cmd, std::string& input, std::string& output, const std::string& output_help);

/// Options shared by several subcommands.
void add_laplacian_option(CLI::App& cmd, std::string& value);
void add_area_option(CLI::App& cmd, std::string& value);
lapmesh::Laplacian laplacian_from(const std::string& value);
lapmesh::Vertex_area area_from(const std::string& value);

/// An integer option read from its text (no wrap-around past 2^64), checked against [lo, hi]:
/// the error quotes the text as given (bounded) and names the range.
long long parse_count_option(const std::string& input, const std::string& option, const std::string& text,
                             long long lo, long long hi, const std::string& range_note);

/// Spectral helpers shared by `spectrum` and `reconstruct` (cmd_spectrum.cpp): -k parsed and
/// checked against n, and the basis computed with progress on a terminal and file-named errors.
long long spectral_k_from(const std::string& input, const std::string& text, long long n);
lapmesh::Spectral_basis compute_spectral_basis(const std::string& input, const Mesh& mesh, long long count,
                                               const std::string& laplacian, const std::string& area);

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
