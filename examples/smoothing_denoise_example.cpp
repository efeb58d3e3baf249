// Denoising: add seeded noise to a mesh, smooth it implicitly with a scale-free time step and
// the volume restored, and report how far the vertices moved back toward the clean mesh.
// Usage: smoothing_denoise_example [mesh.off|obj|ply|stl] [out.off]   (default: a bumpy sphere)
#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/noise.h>
#include <lapmesh/shapes.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>
#include <iostream>

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace LP = lapmesh::parameters;

int main(int argc, char** argv)
{
  try {
    Mesh clean;
    if(argc > 1) lapmesh::io::read_triangle_mesh(argv[1], clean);
    else lapmesh::make_mesh(lapmesh::bumpy_sphere(4), clean);

    Mesh mesh = clean;
    const double sigma = lapmesh::add_noise(mesh, 0.2, LP::noise_direction(lapmesh::Noise_direction::normal).random_seed(42));
    auto rms_to_clean = [&] {
      double s = 0;
      for(auto v : vertices(mesh)) s += CGAL::squared_distance(mesh.point(v), clean.point(v));
      return std::sqrt(s / double(num_vertices(mesh)));
    };
    const double before = rms_to_clean();

    // lambda = 0.1 x mean edge length^2: the same number works whatever the mesh's size.
    const double lambda = lapmesh::scale_free_time_step(mesh, 0.1);
    const lapmesh::Smoothing_report report = lapmesh::smooth_laplacian_implicit(
      mesh, lambda, LP::restore_volume(CGAL::is_closed(mesh)).number_of_iterations(2));

    std::cout << "noise sigma " << sigma << ", lambda " << lambda << ", " << report.iterations
              << " implicit iterations (" << report.solver << ")\n"
              << "RMS distance to the clean mesh: " << before << " -> " << rms_to_clean() << '\n';
    if(argc > 2) {
      const auto [P, tris] = lapmesh::io::mesh_arrays(mesh);
      lapmesh::io::write_mesh(argv[2], P, tris);
    }
  } catch(const std::exception& e) {
    std::cerr << "smoothing_denoise_example: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
