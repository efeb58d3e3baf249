// lapmesh noise IN -o OUT --level F: seeded Gaussian vertex noise, reproducible everywhere.
#include "cli_common.h"

#include <lapmesh/io.h>
#include <lapmesh/noise.h>

#include <cmath>
#include <iostream>
#include <memory>

namespace lapmesh_cli {
namespace {

struct Noise_options
{
  std::string input, output, scale = "mean-edge", direction = "isotropic";
  double level = 0;
  std::uint64_t seed = 0;
  bool quiet = false;
};

void run(const Noise_options& o)
{
  if(!(o.level >= 0) || !std::isfinite(o.level))
    throw Failure(o.input + ": --level must be a finite number >= 0 (got " + std::to_string(o.level) + ")");
  check_output_path(o.output, {"off", "obj", "ply", "stl"});
  Mesh mesh = load_mesh(o.input);
  namespace LP = lapmesh::parameters;
  const auto direction = o.direction == "normal" ? lapmesh::Noise_direction::normal : lapmesh::Noise_direction::isotropic;
  const auto scale = o.scale == "bbox" ? lapmesh::Noise_scale::bounding_box_diagonal : lapmesh::Noise_scale::mean_edge_length;
  const double sigma = or_fail(o.input, [&] {
    return lapmesh::add_noise(mesh, o.level, LP::noise_seed(o.seed, LP::noise_direction(direction, LP::noise_scale(scale))));
  });
  or_fail(o.output, [&] {
    const auto [positions, triangles] = lapmesh::io::mesh_arrays(mesh);
    lapmesh::io::write_mesh(o.output, positions, triangles);
  });
  if(!o.quiet)
    std::cout << o.input << ": " << num_vertices(mesh) << " vertices; " << o.direction << " noise, sigma " << sigma
              << " (level " << o.level << " x " << o.scale << "), seed " << o.seed << "; wrote " << o.output << '\n';
}

} // namespace

void register_noise(CLI::App& app)
{
  auto o = std::make_shared<Noise_options>();
  CLI::App* cmd = app.add_subcommand("noise", "add seeded Gaussian noise to the vertices");
  cmd->footer(
    "Each vertex moves by sigma * g (g standard normal 3-vector), or sigma * g * n (along the unit vertex\n"
    "normal). sigma = level x mean edge length (each edge once) or x bounding-box diagonal. The same seed\n"
    "gives the same output on every platform (mt19937_64 and lapmesh's own normal sampling).\n");
  add_input_output(*cmd, o->input, o->output, "output mesh (.off, .obj, .ply, .stl)");
  cmd->add_option("--level", o->level, "noise level (>= 0), relative to --scale")->required();
  cmd->add_option("--seed", o->seed, "random seed")->capture_default_str();
  cmd->add_option("--scale", o->scale, "mean-edge or bbox")
    ->check(CLI::IsMember({"mean-edge", "bbox"}))
    ->capture_default_str();
  cmd->add_option("--direction", o->direction, "isotropic or normal")
    ->check(CLI::IsMember({"isotropic", "normal"}))
    ->capture_default_str();
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
