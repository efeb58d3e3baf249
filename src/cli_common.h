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

/// Options shared by several subcommands.
void add_laplacian_option(CLI::App& cmd, std::string& value);
void add_area_option(CLI::App& cmd, std::string& value);
lapmesh::Laplacian laplacian_from(const std::string& value);
lapmesh::Vertex_area area_from(const std::string& value);

/// Subcommand registration (one function per cmd_*.cpp file).
void register_curvature(CLI::App& app);
void register_spectrum(CLI::App& app);
void register_reconstruct(CLI::App& app);
void register_smooth(CLI::App& app);
void register_noise(CLI::App& app);

} // namespace lapmesh_cli

#endif
