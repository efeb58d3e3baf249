// lapmesh — command-line entry point: subcommand dispatch and error reporting.
// Every failure is one line on stderr and a non-zero exit: 2 for a usage error, 1 for bad
// input or a failed computation.
#include "cli_common.h"
#include "operations/heap.h"
#include "restart.h"

#include <lapmesh/errors.h>

#include <iostream>

int main(int argc, char** argv)
{
  lapmesh_cli::restart_if_useful(argc, argv);
  lapmesh_ops::keep_heap_between_calls();
  CLI::App app{"lapmesh: Laplacian geometry processing on triangle meshes "
               "(curvature, spectrum, reconstruction, smoothing, noise)"};
  app.set_version_flag("--version", "lapmesh 0.1.0");
  app.require_subcommand(1);
  lapmesh_cli::register_curvature(app);
  lapmesh_cli::register_spectrum(app);
  lapmesh_cli::register_reconstruct(app);
  lapmesh_cli::register_smooth(app);
  lapmesh_cli::register_noise(app);
#ifdef LAPMESH_HAS_VIEWER
  lapmesh_cli::register_view(app);
#endif
  lapmesh_cli::register_denoise_study(app);

  try {
    app.parse(argc, argv);
    lapmesh_cli::print_notes();
  } catch(const CLI::Success& e) {
    return app.exit(e);
  } catch(const CLI::ParseError& e) {
    const auto used = app.get_subcommands();
    std::cerr << "lapmesh" << (used.empty() ? "" : " " + used.front()->get_name()) << ": " << e.what()
              << " (see --help)\n";
    return 2;
  } catch(const lapmesh_cli::Failure& e) {
    std::cerr << "lapmesh: " << e.what() << '\n';
    return 1;
  } catch(const std::exception& e) {
    std::cerr << "lapmesh: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
