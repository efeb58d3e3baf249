// lapmesh noise IN -o OUT --level F: seeded Gaussian vertex noise, reproducible everywhere.
#include "cli_common.h"

#include <iostream>
#include <memory>

namespace lapmesh_cli {
namespace {

struct Noise_options
{
  std::string input, output;
  std::string scale = lapmesh::to_string(lapmesh_ops::Noise_settings{}.scale);
  std::string direction = lapmesh::to_string(lapmesh_ops::Noise_settings{}.direction);
  double level = 0;
  std::uint64_t seed = 0;
  bool quiet = false;
};

void run(const Noise_options& o)
{
  lapmesh_ops::Noise_settings s;
  s.level = o.level;
  s.seed = o.seed;
  s.direction = enum_from<lapmesh::Noise_direction>(o.direction);
  s.scale = enum_from<lapmesh::Noise_scale>(o.scale);
  or_fail(o.input, [&] { lapmesh_ops::check(s); });
  check_output_path(o.output, lapmesh_ops::mesh_output_formats());
  Mesh mesh = load_mesh(o.input);
  const double sigma = or_fail(o.input, [&] { return lapmesh_ops::add_noise(mesh, s); });
  or_fail(o.output, [&] { lapmesh_ops::write_mesh(o.output, mesh); });
  if(!o.quiet)
    std::cout << o.input << ": " << lapmesh_ops::vertex_count(mesh) << " vertices; " << o.direction << " noise, sigma " << sigma
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
  add_enum_option<lapmesh::Noise_scale>(*cmd, "--scale", o->scale, lapmesh::name_list<lapmesh::Noise_scale>());
  add_enum_option<lapmesh::Noise_direction>(*cmd, "--direction", o->direction,
                                            lapmesh::name_list<lapmesh::Noise_direction>());
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
