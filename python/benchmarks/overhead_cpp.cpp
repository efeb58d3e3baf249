// The C++ side of overhead.py: the operations layer's calls that the module's curvatures(),
// laplacian() and Mesh(V, F) make, timed in C++ on a mesh file (best of R runs), so that the
// Python timings can be compared with the same code without the bindings.
//   lapmesh_overhead_cpp MESH [R]   ->   one "name seconds" line per call
#include "operations/arrays.h"
#include "operations/operations.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

namespace {

template <typename Function>
double best_of(int repeats, Function&& f)
{
  double best = std::numeric_limits<double>::infinity();
  for(int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return best;
}

} // namespace

int main(int argc, char** argv)
{
  if(argc < 2) {
    std::fprintf(stderr, "usage: %s MESH [REPEATS]\n", argv[0]);
    return 2;
  }
  const int repeats = argc > 2 ? std::max(1, std::atoi(argv[2])) : 7;
  const lapmesh_ops::Mesh mesh = lapmesh_ops::load_mesh(argv[1]).mesh;

  // The soup the module builds from (V, F) (the same loops, from row-major arrays), then
  // validates into a mesh.
  const lapmesh::Vertex_vectors P = lapmesh_ops::positions(mesh);
  std::vector<std::int64_t> F;
  for(const auto& t : lapmesh_ops::triangles(mesh)) F.insert(F.end(), {std::int64_t(t[0]), std::int64_t(t[1]), std::int64_t(t[2])});
  lapmesh::io::Polygon_soup soup;
  auto build_soup = [&] {
    soup = {};
    soup.points.resize(std::size_t(P.rows()));
    for(Eigen::Index i = 0; i < P.rows(); ++i) soup.points[std::size_t(i)] = {P(i, 0), P(i, 1), P(i, 2)};
    soup.polygons.resize(F.size() / 3);
    for(std::size_t i = 0; i < F.size() / 3; ++i) {
      auto& p = soup.polygons[i];
      p.resize(3);
      for(int j = 0; j < 3; ++j) p[std::size_t(j)] = std::size_t(F[3 * i + std::size_t(j)]);
    }
  };
  const double soup_seconds = best_of(repeats, build_soup);

  // The operations run on the mesh that the module's Mesh(V, F) holds: the one validated from
  // the soup (a mesh read from a file may lay out its halfedges differently, which changes the timings).
  const lapmesh_ops::Mesh from_soup = lapmesh_ops::mesh_from_soup(soup).mesh;
  const lapmesh_ops::Curvature_settings settings;  // the defaults: cotangent, barycentric
  std::printf("vertices %zu\n", std::size_t(num_vertices(from_soup)));
  std::printf("soup_from_arrays %.9f\n", soup_seconds);
  std::printf("mesh_from_soup %.9f\n", best_of(repeats, [&] { (void)lapmesh_ops::mesh_from_soup(soup); }));
  std::printf("curvature %.9f\n", best_of(repeats, [&] { (void)lapmesh_ops::curvature(from_soup, settings); }));
  std::printf("laplacian %.9f\n", best_of(repeats, [&] { (void)lapmesh_ops::laplacian(from_soup, settings); }));
  std::printf("curvature_of_loaded_file %.9f\n", best_of(repeats, [&] { (void)lapmesh_ops::curvature(mesh, settings); }));
  // The whole chain of a call on arrays, timed as one: a sum of separate best times would
  // leave out what the steps cost each other (a fresh mesh is cold in the caches).
  std::printf("curvature_from_arrays %.9f\n", best_of(repeats, [&] {
                build_soup();
                (void)lapmesh_ops::curvature(lapmesh_ops::mesh_from_soup(soup).mesh, settings);
              }));
  std::printf("laplacian_from_arrays %.9f\n", best_of(repeats, [&] {
                build_soup();
                (void)lapmesh_ops::laplacian(lapmesh_ops::mesh_from_soup(soup).mesh, settings);
              }));
  return 0;
}
