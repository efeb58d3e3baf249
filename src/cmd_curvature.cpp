// lapmesh curvature IN -o OUT: per-vertex curvatures to CSV, or a coloured PLY/COFF mesh.
#include "cli_common.h"

#include <lapmesh/colormap.h>

#include <cstdio>
#include <iostream>
#include <memory>

namespace lapmesh_cli {
namespace {

struct Curvature_options
{
  std::string input, output;
  // Defaults are the operations layer's, spelled by the name tables.
  std::string laplacian = lapmesh::to_string(lapmesh_ops::Curvature_settings{}.laplacian);
  std::string area = lapmesh::to_string(lapmesh_ops::Curvature_settings{}.area);
  double mollification = lapmesh::default_mollification_factor;
  std::string quantity = "mean", colormap = lapmesh::to_string(lapmesh::Colormap::jet), range = "auto";
  double clip_percent = 0;
  bool quiet = false;
};

void write_csv(const std::string& path, const lapmesh::Vertex_curvatures& c)
{
  lapmesh_ops::write_text(path, [&](std::ostream& os) {
    os << "vertex,mean,gaussian,k1,k2\n";
    for(Eigen::Index i = 0; i < c.mean.size(); ++i) {
      os << i;
      for(double x : {c.mean[i], c.gaussian[i], c.k1[i], c.k2[i]}) {
        os << ',';
        lapmesh_ops::put_double(os, x);
      }
      os << '\n';
    }
  });
}

void run(const Curvature_options& o)
{
  check_output_path(o.output, {"csv", "ply", "off"});
  std::optional<lapmesh::Value_range> fixed_range;
  if(o.range != "auto") {
    fixed_range = lapmesh::parse_range(o.range);
    if(!fixed_range) throw Failure("--range: expected 'auto' or MIN:MAX with MIN < MAX, got '" + o.range + "'");
  }
  const Mesh mesh = load_mesh(o.input);
  lapmesh_ops::Curvature_settings settings;
  settings.laplacian = enum_from<lapmesh::Laplacian>(o.laplacian);
  settings.area = enum_from<lapmesh::Vertex_area>(o.area);
  settings.mollification = o.mollification;
  const lapmesh::Vertex_curvatures c = or_fail(o.input, [&] { return lapmesh_ops::curvature(mesh, settings); });

  const Eigen::VectorXd& shown = o.quantity == "mean" ? c.mean : o.quantity == "gaussian" ? c.gaussian
                                 : o.quantity == "k1" ? c.k1 : c.k2;
  const std::vector<double> values(shown.data(), shown.data() + shown.size());
  const lapmesh::Value_range range = fixed_range ? *fixed_range : lapmesh::auto_range(values, o.clip_percent);

  or_fail(o.output, [&] {
    if(lapmesh_ops::extension_of(o.output) == "csv") {
      write_csv(o.output, c);
    } else {
      std::vector<std::pair<std::string, std::vector<double>>> scalars;
      auto values_of = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
      if(lapmesh_ops::extension_of(o.output) == "ply")
        scalars = {{"mean", values_of(c.mean)}, {"gaussian", values_of(c.gaussian)}, {"k1", values_of(c.k1)},
                   {"k2", values_of(c.k2)}};
      lapmesh_ops::write_mesh(o.output, mesh, scalars,
                              lapmesh::colorize(values, enum_from<lapmesh::Colormap>(o.colormap), range));
    }
  });
  if(!o.quiet)
    std::cout << o.input << ": " << lapmesh_ops::vertex_count(mesh) << " vertices, " << num_faces(mesh) << " faces; " << o.quantity
              << " curvature (" << o.laplacian << ", " << o.area << " area) in [" << shown.minCoeff() << ", "
              << shown.maxCoeff() << "], colour range [" << range.min << ", " << range.max << "]; wrote "
              << o.output << '\n';
}

} // namespace

void register_curvature(CLI::App& app)
{
  auto o = std::make_shared<Curvature_options>();
  CLI::App* cmd = app.add_subcommand("curvature", "per-vertex mean, Gaussian and principal curvatures");
  cmd->footer(
    "Output: .csv (vertex,mean,gaussian,k1,k2), .ply (mesh + the four scalars + colours of --quantity)\n"
    "or .off (COFF mesh with colours). Curvatures are pointwise; H > 0 on a sphere with outward normals.\n"
    "Uniform mean curvature is the graph-Laplacian quantity and is not scale-correct. Cotangent mean\n"
    "curvature with the barycentric area does not converge at irregular vertices: prefer --area mixed.\n"
    "On boundary vertices the mean and principal curvatures are not surface curvatures.\n");
  add_input_output(*cmd, o->input, o->output, "output file (.csv, .ply or .off)");
  add_laplacian_option(*cmd, o->laplacian);
  add_area_option(*cmd, o->area);
  add_mollification_option(*cmd, o->mollification);
  cmd->add_option("--quantity", o->quantity, "quantity to colour: mean, gaussian, k1 or k2")
    ->check(CLI::IsMember({"mean", "gaussian", "k1", "k2"}))
    ->capture_default_str();
  add_enum_option<lapmesh::Colormap>(*cmd, "--colormap", o->colormap,
                                     "colour map: " + lapmesh::name_list<lapmesh::Colormap>() +
                                       " (coolwarm is diverging, for signed values)");
  cmd->add_option("--range", o->range,
                  "colour range: auto ([min, max], symmetric about 0 when the values have both signs) or MIN:MAX")
    ->capture_default_str();
  cmd->add_option("--clip", o->clip_percent, "with --range auto: ignore this percentage of values at each end")
    ->check(CLI::Range(0.0, 49.9))
    ->capture_default_str();
  cmd->add_flag("-q,--quiet", o->quiet, "print nothing on success");
  cmd->callback([o] { run(*o); });
}

} // namespace lapmesh_cli
