// Operator assembly and curvatures on generated tori of ~10k, ~100k and 1M vertices.
// Every timing starts from the raw Surface_mesh (extraction and topology included), as a
// user calling the public function pays it. Run: operators_benchmark --benchmark_repetitions=3
#include <lapmesh/curvature.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/shapes.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <map>

namespace {

using Mesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;
namespace LP = lapmesh::parameters;

// n x n torus grid: 100 -> 10k, 316 -> ~100k, 1000 -> 1M vertices; built once per size.
const Mesh& torus_mesh(int n)
{
  static std::map<int, Mesh> cache;
  auto it = cache.find(n);
  if(it == cache.end()) {
    Mesh m;
    lapmesh::make_mesh(lapmesh::torus(n, n, 1.0, 0.4), m);
    it = cache.emplace(n, std::move(m)).first;
  }
  return it->second;
}

template <typename Tag>
void BM_cotangent_stiffness_mixed_mass(benchmark::State& state)
{
  const Mesh& m = torus_mesh(int(state.range(0)));
  for(auto _ : state) {
    auto pencil = lapmesh::laplacian_pencil<Tag>(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
    benchmark::DoNotOptimize(pencil.stiffness.valuePtr());
  }
  state.counters["vertices"] = double(num_vertices(m));
}

// The same tori with every vertex moved by a seeded 0.3 edge length: obtuse triangles, so the
// intrinsic Delaunay Laplacian has edges to flip.
const Mesh& jittered_torus_mesh(int n)
{
  static std::map<int, Mesh> cache;
  auto it = cache.find(n);
  if(it == cache.end()) {
    lapmesh::Triangle_soup s = lapmesh::torus(n, n, 1.0, 0.4);
    const double h = 0.3 * 2 * M_PI * 0.4 / n;
    std::uint64_t state = 12345;
    for(auto& p : s.points)
      for(double& c : p) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        c += h * (double(state >> 11) / double(1ull << 53) - 0.5);
      }
    Mesh m;
    lapmesh::make_mesh(s, m);
    it = cache.emplace(n, std::move(m)).first;
  }
  return it->second;
}

// An n x n flat patch with a seeded jitter of 0.45 edge lengths: open, so the intrinsic
// Delaunay Laplacian works on its tufted cover (every face twice).
const Mesh& jittered_patch_mesh(int n)
{
  static std::map<int, Mesh> cache;
  auto it = cache.find(n);
  if(it == cache.end()) {
    Mesh m;
    lapmesh::make_mesh(lapmesh::plane_patch(n, 0.45, 3), m);
    it = cache.emplace(n, std::move(m)).first;
  }
  return it->second;
}

// Plain cotangent against intrinsic Delaunay on the same mesh (state.range(1): 0 = regular
// torus, 1 = jittered torus, 2 = jittered open patch), with the flips counted; the assembly
// from the raw mesh, as above.
void BM_cotangent_vs_intrinsic(benchmark::State& state)
{
  const int n = int(state.range(0));
  const Mesh& m = state.range(1) == 0 ? torus_mesh(n) : state.range(1) == 1 ? jittered_torus_mesh(n) : jittered_patch_mesh(n);
  const auto kind = state.range(2) != 0 ? lapmesh::Laplacian::intrinsic_delaunay : lapmesh::Laplacian::cotangent;
  for(auto _ : state) {
    auto pencil = lapmesh::laplacian_pencil(m, LP::laplacian(kind));
    benchmark::DoNotOptimize(pencil.stiffness.valuePtr());
  }
  if(kind == lapmesh::Laplacian::intrinsic_delaunay) {
    const auto e = lapmesh::internal::extract_mesh(m, CGAL::parameters::default_values());
    lapmesh::internal::Intrinsic_delaunay_stats stats;
    lapmesh::internal::intrinsic_delaunay_triangulation(e.topology, e.positions,
                                                        lapmesh::default_mollification_factor, &stats);
    state.counters["flips"] = double(stats.flips);
  }
  state.counters["vertices"] = double(num_vertices(m));
}

// general = 0: the default, read off the halfedges; 1: the general path (extraction and corner
// topology), which a vertex_index_map selects.
void BM_uniform_laplacian(benchmark::State& state)
{
  const Mesh& m = torus_mesh(int(state.range(0)));
  const auto uniform = LP::laplacian(lapmesh::Laplacian::uniform);
  for(auto _ : state) {
    auto pencil = state.range(1) == 0
                    ? lapmesh::laplacian_pencil(m, uniform)
                    : lapmesh::laplacian_pencil(m, uniform.vertex_index_map(get(boost::vertex_index, m)));
    benchmark::DoNotOptimize(pencil.stiffness.valuePtr());
  }
}

template <typename Tag>
void BM_all_curvatures(benchmark::State& state)
{
  const Mesh& m = torus_mesh(int(state.range(0)));
  for(auto _ : state) {
    auto c = lapmesh::vertex_curvatures<Tag>(m, LP::vertex_area(lapmesh::Vertex_area::mixed));
    benchmark::DoNotOptimize(c.k2.data());
  }
}

void BM_mean_curvature_only(benchmark::State& state)
{
  Mesh m = torus_mesh(int(state.range(0)));
  auto H = m.add_property_map<Mesh::Vertex_index, double>("v:H").first;
  for(auto _ : state) lapmesh::compute_mean_curvature(m, H, LP::vertex_area(lapmesh::Vertex_area::mixed));
}

void BM_gaussian_curvature_only(benchmark::State& state)
{
  Mesh m = torus_mesh(int(state.range(0)));
  auto K = m.add_property_map<Mesh::Vertex_index, double>("v:K").first;
  for(auto _ : state) lapmesh::compute_gaussian_curvature(m, K, LP::vertex_area(lapmesh::Vertex_area::mixed));
}

void BM_extract_and_topology(benchmark::State& state)
{
  const Mesh& m = torus_mesh(int(state.range(0)));
  for(auto _ : state) {
    auto e = lapmesh::internal::extract_mesh(m, CGAL::parameters::default_values());
    benchmark::DoNotOptimize(e.topology.inner.data());
  }
}

void sizes(benchmark::internal::Benchmark* b) { b->Arg(100)->Arg(316)->Arg(1000)->Unit(benchmark::kMillisecond); }

} // namespace

BENCHMARK(BM_extract_and_topology)->Apply(sizes);
BENCHMARK(BM_uniform_laplacian)
  ->ArgsProduct({{100, 316, 1000}, {0, 1}})
  ->ArgNames({"n", "general"})
  ->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_cotangent_stiffness_mixed_mass, CGAL::Sequential_tag)->Apply(sizes);
BENCHMARK_TEMPLATE(BM_cotangent_stiffness_mixed_mass, CGAL::Parallel_if_available_tag)->Apply(sizes);
BENCHMARK(BM_mean_curvature_only)->Apply(sizes);
BENCHMARK(BM_gaussian_curvature_only)->Apply(sizes);
BENCHMARK(BM_cotangent_vs_intrinsic)
  ->ArgsProduct({{316, 1000}, {0, 1, 2}, {0, 1}})
  ->ArgNames({"n", "mesh", "intrinsic"})
  ->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_all_curvatures, CGAL::Sequential_tag)->Apply(sizes);
BENCHMARK_TEMPLATE(BM_all_curvatures, CGAL::Parallel_if_available_tag)->Apply(sizes);
BENCHMARK_MAIN();
