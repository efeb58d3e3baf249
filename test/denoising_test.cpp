// Denoising: the deviation metrics (zero on identical meshes, Hausdorff against a brute-force
// point-to-triangle computation and against CGAL's on the same sampling grid, the point-to-mesh
// search against CGAL's point-to-triangle distance over every face), their fall when a noisy sphere is smoothed, the study driver
// (row count, per-iteration records equal to separate runs, divergence above the bound, best
// lambda) and the command line's refusal of bad levels, lambdas and iteration counts.
#include "test_helpers.h"

#include <lapmesh/denoising.h>
#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/noise.h>

#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/distance.h>
#include <CGAL/Surface_mesh.h>

#include <Eigen/Dense>
#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/task_arena.h>
#endif

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

using namespace lapmesh_test;
namespace LP = lapmesh::parameters;

namespace {

Mesh jitter(Mesh m, double amount, unsigned seed)
{
  std::mt19937_64 rng(seed);
  auto u = [&] { return amount * (double(rng() >> 11) / double(1ull << 53) - 0.5); };
  for(auto v : vertices(m)) {
    const Point p = m.point(v);
    const double dx = u(), dy = u(), dz = u();
    m.point(v) = Point(p.x() + dx, p.y() + dy, p.z() + dz);
  }
  return m;
}

std::vector<Kernel::Triangle_3> triangles_of(const Mesh& m)
{
  std::vector<Kernel::Triangle_3> out;
  for(auto f : faces(m)) {
    const auto h = halfedge(f, m);
    out.emplace_back(m.point(source(h, m)), m.point(target(h, m)), m.point(target(next(h, m), m)));
  }
  return out;
}

// max over a barycentric grid (r subdivisions per triangle) of `from` of the distance to `to`,
// by CGAL's point-to-triangle distance to every face.
double brute_force_one_sided(const Mesh& from, const Mesh& to, int r)
{
  const auto A = triangles_of(from), B = triangles_of(to);
  double worst = 0;
  for(const auto& t : A)
    for(int i = 0; i <= r; ++i)
      for(int j = 0; i + j <= r; ++j) {
        const Point p = t[0] + (double(i) / r) * (t[1] - t[0]) + (double(j) / r) * (t[2] - t[0]);
        double best = std::numeric_limits<double>::infinity();
        for(const auto& s : B) best = std::min(best, CGAL::squared_distance(p, s));
        worst = std::max(worst, std::sqrt(best));
      }
  return worst;
}

// n faces around one apex, lifted above a ring of n vertices, closed or with a gap, each face
// turned so that its corners start at `first` (0, 1 or 2): the apex of every face at once.
struct Triangles
{
  lapmesh::internal::Positions P;
  lapmesh::internal::Working_array<lapmesh::internal::Index> triangles;
};

Triangles fan(int n, bool closed, int first)
{
  Triangles t;
  t.P.resize(n + 1, 3);
  t.P.row(0) << 0, 0, 0.1;
  for(int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    t.P.row(i + 1) << std::cos(a), std::sin(a), 0.02 * std::sin(7 * a);
  }
  for(int i = 0; i < (closed ? n : n - 1); ++i) {
    const std::array<lapmesh::internal::Index, 3> f{0, 1 + i, 1 + (i + 1) % n};
    for(int k = 0; k < 3; ++k) t.triangles.push_back(f[(first + k) % 3]);
  }
  return t;
}

Triangles triangles_of_mesh(const Mesh& m)
{
  Triangles t;
  t.P.resize(Eigen::Index(num_vertices(m)), 3);
  for(auto v : vertices(m)) t.P.row(v.idx()) << m.point(v).x(), m.point(v).y(), m.point(v).z();
  for(auto f : faces(m))
    for(auto v : vertices_around_face(halfedge(f, m), m)) t.triangles.push_back(lapmesh::internal::Index(v.idx()));
  return t;
}

// The nearest face by CGAL's point-to-triangle distance, or point-to-segment for a face without
// area, over every face.
double brute_force_squared_distance(const Triangles& t, const Eigen::Vector3d& q)
{
  const auto point = [&](lapmesh::internal::Index i) { return Point(t.P(i, 0), t.P(i, 1), t.P(i, 2)); };
  const Point p(q.x(), q.y(), q.z());
  double best = std::numeric_limits<double>::infinity();
  for(std::size_t f = 0; f < t.triangles.size(); f += 3) {
    const Point a = point(t.triangles[f]), b = point(t.triangles[f + 1]), c = point(t.triangles[f + 2]);
    if(!CGAL::collinear(a, b, c)) {
      best = std::min(best, CGAL::squared_distance(p, Kernel::Triangle_3(a, b, c)));
      continue;
    }
    for(const auto& s : {std::make_pair(a, b), std::make_pair(b, c), std::make_pair(c, a)})
      best = std::min(best, s.first == s.second ? CGAL::squared_distance(p, s.first)
                                                : CGAL::squared_distance(p, Kernel::Segment_3(s.first, s.second)));
  }
  return best;
}

// The faces as a Surface_mesh built face by face, as CGAL's sampling sees them.
Mesh surface_mesh_of(const Triangles& t)
{
  Mesh m;
  for(Eigen::Index i = 0; i < t.P.rows(); ++i) m.add_vertex(Point(t.P(i, 0), t.P(i, 1), t.P(i, 2)));
  for(std::size_t f = 0; f < t.triangles.size(); f += 3)
    m.add_face(Mesh::Vertex_index(std::uint32_t(t.triangles[f])), Mesh::Vertex_index(std::uint32_t(t.triangles[f + 1])),
               Mesh::Vertex_index(std::uint32_t(t.triangles[f + 2])));
  return m;
}

double diagonal(const Mesh& m)
{
  const auto box = CGAL::bbox_3(m.points().begin(), m.points().end());
  return std::sqrt(CGAL::square(box.xmax() - box.xmin()) + CGAL::square(box.ymax() - box.ymin()) +
                   CGAL::square(box.zmax() - box.zmin()));
}

} // namespace

TEST(Denoising, DeviationIsZeroForIdenticalMeshes)
{
  for(const Mesh& m : {to_mesh(lapmesh::bumpy_sphere(2)), to_mesh(lapmesh::plane_patch(8, 0.3))}) {
    const lapmesh::Mesh_deviation d = lapmesh::mesh_deviation(m, m);
    EXPECT_EQ(d.rms_distance, 0.0);
    EXPECT_LE(d.hausdorff_distance, 1e-15);
    EXPECT_EQ(d.normal_angle_error, 0.0);
    if(CGAL::is_closed(m)) EXPECT_EQ(d.volume_change, 0.0);
    else EXPECT_TRUE(std::isnan(d.volume_change));
  }
}

TEST(Denoising, DeviationMatchesDirectComputations)
{
  const Mesh clean = to_mesh(lapmesh::icosphere(1));
  const Mesh moved = jitter(clean, 0.2, 5);
  const lapmesh::Mesh_deviation d = lapmesh::mesh_deviation(clean, moved, LP::default_values(), LP::hausdorff_spacing(0.02));
  const double diag = diagonal(clean);

  // RMS vertex distance.
  double sq = 0;
  for(auto v : vertices(clean)) sq += CGAL::squared_distance(clean.point(v), moved.point(v));
  EXPECT_NEAR(d.rms_distance, std::sqrt(sq / double(num_vertices(clean))) / diag, 1e-15);

  // Hausdorff: brute force over a barycentric grid of 40 subdivisions per triangle (edge ~1.1,
  // so samples are <= 0.03 apart: the distance function, 1-Lipschitz, is within 0.015 of its
  // maximum at the nearest sample; CGAL's grid of 0.02 mean edge lengths is finer still).
  const double brute = std::max(brute_force_one_sided(clean, moved, 40), brute_force_one_sided(moved, clean, 40));
  EXPECT_GT(brute, 0.05);  // a real distance, well above the tolerance
  EXPECT_NEAR(d.hausdorff_distance * diag, brute, 0.015);
  EXPECT_EQ(d.hausdorff_coarsening, 1.0);  // 80 faces at 0.02 edge lengths: within the bound

  // Volume change against CGAL's volume.
  const double V0 = CGAL::Polygon_mesh_processing::volume(clean), V1 = CGAL::Polygon_mesh_processing::volume(moved);
  EXPECT_NEAR(d.volume_change, (V1 - V0) / V0, 1e-12);
  // Normal error: between 0 and 90 degrees and non-zero.
  EXPECT_GT(d.normal_angle_error, 1.0);
  EXPECT_LT(d.normal_angle_error, 90.0);
}

TEST(Denoising, NormalErrorOfAMeshWhoseFaceCrossProductsOverflowIsNotANumber)
{
  // A vertex normal is zero only where the faces' cross products sum to zero; an overflowed sum
  // gives no direction, so a blown-up mesh must not score a finite normal error.
  using lapmesh::internal::unit_vertex_normal;
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(unit_vertex_normal(Eigen::Vector3d::Zero()), Eigen::Vector3d::Zero());
  EXPECT_TRUE(unit_vertex_normal(Eigen::Vector3d(3, 0, 4)).isApprox(Eigen::Vector3d(0.6, 0, 0.8), 1e-15));
  EXPECT_TRUE(unit_vertex_normal(Eigen::Vector3d(inf, 0, 0)).hasNaN());
  EXPECT_TRUE(unit_vertex_normal(Eigen::Vector3d(std::nan(""), 1, 0)).hasNaN());

  const Mesh clean = to_mesh(lapmesh::icosphere(1));
  Mesh blown_up = clean;
  for(auto v : vertices(blown_up)) blown_up.point(v) = CGAL::ORIGIN + 1e160 * (blown_up.point(v) - CGAL::ORIGIN);
  const lapmesh::Mesh_deviation d = lapmesh::mesh_deviation(clean, blown_up);
  EXPECT_TRUE(std::isnan(d.normal_angle_error)) << d.normal_angle_error;
  // Scaled by a power of two that keeps every product finite, the normals do not change.
  Mesh scaled = clean;
  for(auto v : vertices(scaled)) scaled.point(v) = CGAL::ORIGIN + 0x1p40 * (scaled.point(v) - CGAL::ORIGIN);
  EXPECT_LE(lapmesh::mesh_deviation(clean, scaled).normal_angle_error, 1e-12);
}

TEST(Denoising, HausdorffEqualsTheDisplacementOfAVertexAboveAPlane)
{
  // One interior vertex of a flat patch lifted by h: the tent's apex is the farthest point,
  // at distance exactly h from the plane, and the plane is nowhere farther from the tent.
  const Mesh flat = to_mesh(lapmesh::plane_patch(6));
  Mesh lifted = flat;
  const double h = 0.05;
  Mesh::Vertex_index apex;
  double best = 1e9;
  for(auto v : vertices(flat)) {
    const double r = std::hypot(flat.point(v).x(), flat.point(v).y());
    if(!flat.is_border(v) && r < best) best = r, apex = v;
  }
  const Point p = flat.point(apex);
  lifted.point(apex) = Point(p.x(), p.y(), p.z() + h);
  const auto d = lapmesh::mesh_deviation(flat, lifted);
  EXPECT_NEAR(d.hausdorff_distance * diagonal(flat), h, 1e-12);
}

TEST(SurfaceDistance, EqualsTheNearestOfEveryFaceOnFansAndDegenerateFaces)
{
  using lapmesh::internal::Surface_distance;
  std::vector<Triangles> meshes;
  for(int first = 0; first < 3; ++first) meshes.push_back(fan(400, first != 1, first));
  // Two fans at one apex, one of them turned over and below (not a manifold surface).
  Triangles bowtie = fan(300, true, 0), lower = fan(200, true, 2);
  const auto shift = lapmesh::internal::Index(bowtie.P.rows()) - 1;
  lower.P.bottomRows(200) *= 0.7;
  lower.P.bottomRows(200).col(2).array() -= 0.3;
  bowtie.P.conservativeResize(shift + lower.P.rows(), 3);
  bowtie.P.bottomRows(200) = lower.P.bottomRows(200);
  for(std::size_t k = 0; k < lower.triangles.size(); ++k)
    bowtie.triangles.push_back(lower.triangles[k] == 0 ? 0 : lower.triangles[k] + shift);
  meshes.push_back(bowtie);
  // A jittered sphere with faces of no area: a corner repeated, three corners on a line.
  Triangles sphere = triangles_of_mesh(jitter(to_mesh(lapmesh::icosphere(2)), 0.1, 3));
  const auto n = lapmesh::internal::Index(sphere.P.rows());
  sphere.P.conservativeResize(n + 3, 3);
  sphere.P.row(n) << 2, 0, 0;
  sphere.P.row(n + 1) << 2.5, 0.5, 0.5;
  sphere.P.row(n + 2) << 3, 1, 1;
  for(lapmesh::internal::Index v : {n, n, n + 1, n, n + 1, n + 2}) sphere.triangles.push_back(v);
  meshes.push_back(sphere);

  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.5, 1.5), small(-1e-3, 1e-3);
  for(std::size_t m = 0; m < meshes.size(); ++m) {
    const Surface_distance surface(meshes[m].P, meshes[m].triangles);
    EXPECT_EQ(surface.fan_count(), m < 4 ? 1u : 0u) << m;
    for(int q = 0; q < 600; ++q) {
      // Anywhere, near the apex, and near the faces' middles.
      Eigen::Vector3d p(u(rng), u(rng), u(rng));
      if(q % 3 == 1) p = meshes[m].P.row(0).transpose() + Eigen::Vector3d(small(rng), small(rng), small(rng));
      if(q % 3 == 2) {
        const std::size_t f = 3 * (std::size_t(rng()) % (meshes[m].triangles.size() / 3));
        p = Eigen::Vector3d(small(rng), small(rng), small(rng));
        for(int k = 0; k < 3; ++k) p += meshes[m].P.row(meshes[m].triangles[f + k]).transpose() / 3;
      }
      // The coordinates are about 1: distances agree to rounding, 1e-12.
      const double exact = brute_force_squared_distance(meshes[m], p);
      EXPECT_NEAR(std::sqrt(surface.squared_distance(p)), std::sqrt(exact), 1e-12) << m << " " << q;
      // With a distance that is enough, a face at most that far ends the search; none, the answer.
      const double enough = exact * (q % 2 ? 1.5 : 0.5);
      const double answer = surface.squared_distance(p, enough);
      if(exact <= enough) EXPECT_LE(answer, enough) << m << " " << q;
      else EXPECT_NEAR(std::sqrt(answer), std::sqrt(exact), 1e-12) << m << " " << q;
    }
  }
}

TEST(SurfaceDistance, RefittedToMovedVerticesFindsWhatANewBuildFinds)
{
  using lapmesh::internal::Surface_distance;
  // A fan (searched by direction), and a sphere with a face of no area; each moved and stretched
  // so far that the old tree's boxes no longer hold its faces.
  std::vector<Triangles> meshes{fan(300, true, 1), triangles_of_mesh(jitter(to_mesh(lapmesh::icosphere(3)), 0.1, 4))};
  meshes[1].triangles.insert(meshes[1].triangles.end(), {0, 0, 1});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.5, 1.5), move(-0.1, 0.1);
  for(std::size_t m = 0; m < meshes.size(); ++m) {
    Triangles moved = meshes[m];
    for(Eigen::Index i = 0; i < moved.P.rows(); ++i) {
      moved.P.row(i) += Eigen::RowVector3d(move(rng), move(rng), move(rng));
      moved.P.row(i) *= 1 + 0.5 * double(i % 3);
    }
    Surface_distance refitted(meshes[m].P, meshes[m].triangles);
    refitted.refit(moved.P);
    const Surface_distance built(moved.P, moved.triangles);
    EXPECT_EQ(refitted.fan_count(), built.fan_count());
    for(int q = 0; q < 400; ++q) {
      Eigen::Vector3d p(u(rng), u(rng), u(rng));
      if(q % 2) p = moved.P.row(Eigen::Index(std::size_t(rng()) % std::size_t(moved.P.rows()))).transpose() * 1.01;
      const double exact = brute_force_squared_distance(moved, p);
      EXPECT_EQ(refitted.squared_distance(p), built.squared_distance(p)) << m << " " << q;
      EXPECT_NEAR(std::sqrt(refitted.squared_distance(p)), std::sqrt(exact), 1e-12) << m << " " << q;
      // One face, by its index in the triangles: that face's distance, in fans and out of them.
      const std::size_t f = std::size_t(rng()) % refitted.face_count();
      Triangles one;
      one.P = moved.P;
      one.triangles.assign(moved.triangles.begin() + std::ptrdiff_t(3 * f), moved.triangles.begin() + std::ptrdiff_t(3 * f + 3));
      EXPECT_NEAR(std::sqrt(refitted.squared_distance_to_face(f, p)), std::sqrt(brute_force_squared_distance(one, p)), 1e-12)
        << m << " " << q;
      EXPECT_GE(refitted.squared_distance_to_face(f, p), refitted.squared_distance(p)) << m << " " << q;
    }
    EXPECT_EQ(refitted.face_count(), moved.triangles.size() / 3);
  }
}

TEST(SurfaceDistance, SampledDistanceEqualsCGALsApproximateHausdorffOnTheSameGrid)
{
  namespace PMP = CGAL::Polygon_mesh_processing;
  using namespace lapmesh::internal;
  // A fan and a jittered sphere, each against a moved copy; the sphere at a fine grid, so that
  // faces are sampled inside as well as on their edges.
  std::vector<std::pair<Triangles, double>> cases{{fan(300, true, 1), 1.0},
                                                  {triangles_of_mesh(to_mesh(lapmesh::icosphere(2))), 0.3}};
  for(auto& [clean, spacing_factor] : cases) {
    Triangles moved = clean;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-0.02, 0.02);
    for(Eigen::Index i = 0; i < moved.P.rows(); ++i) moved.P.row(i) += Eigen::RowVector3d(u(rng), u(rng), u(rng));
    const Mesh_topology t = build_topology(Index(clean.P.rows()), clean.triangles);
    const double spacing = spacing_factor * mean_edge_length(t, clean.P);
    const Surface_distance to_clean(clean.P, clean.triangles), to_moved(moved.P, moved.triangles);
    const Mesh a = surface_mesh_of(moved), b = surface_mesh_of(clean);
    const auto grid = CGAL::parameters::use_grid_sampling(true).grid_spacing(spacing);
    const double ab = PMP::approximate_Hausdorff_distance<CGAL::Sequential_tag>(a, b, grid);
    const double ba = PMP::approximate_Hausdorff_distance<CGAL::Sequential_tag>(b, a, grid);
    EXPECT_GT(std::min(ab, ba), 0.005);
    EXPECT_NEAR(sampled_one_sided_distance(t, moved.P, spacing, to_clean), ab, 1e-12 * ab);
    EXPECT_NEAR(sampled_one_sided_distance(t, clean.P, spacing, to_moved), ba, 1e-12 * ba);
    std::vector<Point> samples;
    PMP::sample_triangle_mesh(a, std::back_inserter(samples), grid);
    EXPECT_EQ(grid_sample_count(t, moved.P, spacing), double(samples.size()));
  }
}

TEST(SurfaceDistance, ParallelSearchGivesTheSameDistances)
{
  using namespace lapmesh::internal;
  // Tens of thousands of samples a direction, in some twenty runs of faces, which the threads
  // start from different largest distances so far.
  const Mesh clean_mesh = to_mesh(lapmesh::icosphere(4));
  const Mesh moved_mesh = jitter(clean_mesh, 0.02, 9);
  const Triangles clean = triangles_of_mesh(clean_mesh), moved = triangles_of_mesh(moved_mesh);
  const Mesh_topology t = build_topology(Index(clean.P.rows()), clean.triangles);
  const double spacing = 0.2 * mean_edge_length(t, clean.P);
  ASSERT_GT(grid_sample_count(t, clean.P, spacing), 50000.0);
  const Surface_distance to_clean(clean.P, clean.triangles), to_moved(moved.P, moved.triangles);
  const auto check = [&] {
    EXPECT_EQ(sampled_one_sided_distance(t, moved.P, spacing, to_clean, true),
              sampled_one_sided_distance(t, moved.P, spacing, to_clean, false));
    EXPECT_EQ(sampled_one_sided_distance(t, clean.P, spacing, to_moved, true),
              sampled_one_sided_distance(t, clean.P, spacing, to_moved, false));
    const auto np = LP::hausdorff_spacing(0.2);
    const auto serial = lapmesh::mesh_deviation(clean_mesh, moved_mesh, LP::default_values(), np);
    const auto parallel = lapmesh::mesh_deviation<CGAL::Parallel_tag>(clean_mesh, moved_mesh, LP::default_values(), np);
    EXPECT_GT(serial.hausdorff_distance, 0.0);
    EXPECT_EQ(parallel.hausdorff_distance, serial.hausdorff_distance);
    EXPECT_EQ(parallel.rms_distance, serial.rms_distance);
    EXPECT_EQ(parallel.normal_angle_error, serial.normal_angle_error);
  };
#ifdef CGAL_LINKED_WITH_TBB
  tbb::task_arena arena(4);
  arena.execute(check);
#else
  check();
#endif
}

TEST(SurfaceDistance, GridIsCoarsenedOnlyWhereItWouldExceedItsBound)
{
  using namespace lapmesh::internal;
  const Triangles sphere = triangles_of_mesh(to_mesh(lapmesh::icosphere(3)));
  const Mesh_topology t = build_topology(Index(sphere.P.rows()), sphere.triangles);
  const double edge = mean_edge_length(t, sphere.P);
  EXPECT_EQ(bounded_grid_spacing(t, sphere.P, edge), edge);
  EXPECT_EQ(bounded_grid_spacing(t, sphere.P, 0.05 * edge), 0.05 * edge);
  const double limit = std::max(grid_sample_floor, grid_samples_per_corner * double(sphere.triangles.size()));
  const double coarse = bounded_grid_spacing(t, sphere.P, 1e-4 * edge);
  EXPECT_LE(grid_sample_count(t, sphere.P, coarse), limit);
  EXPECT_GT(grid_sample_count(t, sphere.P, 0.5 * coarse), limit);  // not coarser than it needs
  double visited = 0;
  for_each_grid_sample(t, sphere.P, 0.3 * edge, [&](const Eigen::Vector3d&) { ++visited; });
  EXPECT_EQ(visited, grid_sample_count(t, sphere.P, 0.3 * edge));

  // mesh_deviation() reports the coarsening: here both directions sample the same mesh.
  const Mesh m = to_mesh(lapmesh::icosphere(3));
  EXPECT_EQ(lapmesh::mesh_deviation(m, m).hausdorff_coarsening, 1.0);
  const auto d = lapmesh::mesh_deviation(m, m, LP::default_values(), LP::hausdorff_spacing(1e-4));
  EXPECT_NEAR(d.hausdorff_coarsening, coarse / (1e-4 * edge), 1e-9 * d.hausdorff_coarsening);
  EXPECT_GT(d.hausdorff_coarsening, 100.0);
}

TEST(Denoising, SmoothingANoisySphereLowersEveryMetric)
{
  const Mesh clean = to_mesh(lapmesh::icosphere(3));
  Mesh noisy = clean;
  // Along the normals: isotropic noise is 2/3 tangential, which the cotangent flow does not
  // undo (it moves vertices along the mean curvature normal), so the vertex-to-vertex RMS
  // distance would not tell geometric smoothing apart (doc/denoising.md).
  lapmesh::add_noise(noisy, 0.1, LP::noise_direction(lapmesh::Noise_direction::normal).random_seed(4));
  const auto before = lapmesh::mesh_deviation(clean, noisy);
  for(lapmesh::Laplacian lap : {lapmesh::Laplacian::cotangent, lapmesh::Laplacian::uniform}) {
    Mesh m = noisy;
    lapmesh::smooth_laplacian_implicit(m, lapmesh::scale_free_time_step(m, 0.3, LP::laplacian(lap)),
                                       LP::restore_volume(true, LP::laplacian(lap)).number_of_iterations(2));
    const auto after = lapmesh::mesh_deviation(clean, m);
    EXPECT_LT(after.rms_distance, 0.7 * before.rms_distance) << lapmesh::to_string(lap);
    EXPECT_LT(after.hausdorff_distance, 0.8 * before.hausdorff_distance) << lapmesh::to_string(lap);
    EXPECT_LT(after.normal_angle_error, 0.75 * before.normal_angle_error) << lapmesh::to_string(lap);
    EXPECT_NEAR(after.volume_change, before.volume_change, 1e-9);
  }
}

TEST(Denoising, StudyRecordsEveryIterationAndFindsAFiniteBestLambda)
{
  const Mesh clean = to_mesh(lapmesh::icosphere(2));
  lapmesh::Denoising_study_settings s;
  s.noise_levels = {0.05, 0.1};
  s.time_steps = {0.1, 1.0, 100.0};
  s.iterations = 4;
  s.seed = 3;
  s.noise_direction = lapmesh::Noise_direction::normal;
  s.restore_volume = true;  // the closed sphere would otherwise shrink, which the RMS distance counts
  const lapmesh::Denoising_study study = lapmesh::run_denoising_study(clean, s);
  ASSERT_EQ(study.records.size(), std::size_t(2 * 2 * 2 * 3 * (4 + 1)));

  for(double level : s.noise_levels)
    for(auto scheme : s.schemes) {
      const auto best = study.best(level, scheme);
      ASSERT_TRUE(best.has_value());
      EXPECT_TRUE(std::isfinite(best->lambda));
      EXPECT_GE(best->iteration, 1);
      double noisy = 0;
      for(const auto& r : study.records)
        if(r.noise_level == level && r.iteration == 0) noisy = r.deviation.rms_distance;
      EXPECT_LT(best->deviation.rms_distance, 0.8 * noisy);
    }

  // Explicit cotangent at 100 mean edge lengths squared is far above the stability bound: it
  // must be stopped as diverged; the implicit scheme at the same lambda stays bounded (it may
  // collapse the sphere's faces, a failure, but it never blows up).
  bool explicit_diverged = false, implicit_bounded = true;
  for(const auto& r : study.records) {
    if(r.laplacian != lapmesh::Laplacian::cotangent || r.time_step != 100.0 || r.iteration == 0) continue;
    EXPECT_GT(r.lambda, r.stability_bound);
    if(r.scheme == lapmesh::Smoothing_scheme::explicit_euler) explicit_diverged |= r.status == lapmesh::Run_status::diverged;
    else implicit_bounded &= r.status != lapmesh::Run_status::diverged;
  }
  EXPECT_TRUE(explicit_diverged);
  EXPECT_TRUE(implicit_bounded);

  // A record after k iterations equals a separate k-iteration run on the same noisy mesh.
  Mesh noisy = clean;
  lapmesh::add_noise(noisy, 0.1, LP::noise_direction(lapmesh::Noise_direction::normal).random_seed(3));
  for(int k : {1, 3}) {
    Mesh m = noisy;
    const double lambda = lapmesh::scale_free_time_step(m, 1.0);
    lapmesh::smooth_laplacian_implicit(m, lambda, LP::restore_volume(true).number_of_iterations(unsigned(k)));
    const auto direct = lapmesh::mesh_deviation(clean, m);
    bool found = false;
    for(const auto& r : study.records)
      if(r.noise_level == 0.1 && r.scheme == lapmesh::Smoothing_scheme::implicit_euler &&
         r.laplacian == lapmesh::Laplacian::cotangent && r.time_step == 1.0 && r.iteration == k) {
        found = true;
        EXPECT_NEAR(r.lambda, lambda, 1e-15 * lambda);
        EXPECT_NEAR(r.deviation.rms_distance, direct.rms_distance, 1e-12);
        EXPECT_NEAR(r.deviation.hausdorff_distance, direct.hausdorff_distance, 1e-12);
        EXPECT_NEAR(r.deviation.normal_angle_error, direct.normal_angle_error, 1e-9);
      }
    EXPECT_TRUE(found);
  }
}

// The study's mollification reaches the intrinsic Delaunay operator: a record equals a separate
// run with the same mollification_factor, and another factor gives another record.
TEST(Denoising, StudyPassesItsMollificationToTheIntrinsicOperator)
{
  const Mesh clean = to_mesh(lapmesh::icosphere(2));
  lapmesh::Denoising_study_settings s;
  s.noise_levels = {0.1};
  s.schemes = {lapmesh::Smoothing_scheme::implicit_euler};
  s.laplacians = {lapmesh::Laplacian::intrinsic_delaunay};
  s.time_steps = {1.0};
  s.iterations = 2;
  s.seed = 5;
  auto rms_after = [&](double mollification) {
    s.mollification = mollification;
    for(const auto& r : lapmesh::run_denoising_study(clean, s).records)
      if(r.iteration == 2) return r.deviation.rms_distance;
    return std::nan("");
  };
  Mesh noisy = clean;
  lapmesh::add_noise(noisy, 0.1, LP::noise_direction(lapmesh::Noise_direction::isotropic).random_seed(5));
  const double lambda = lapmesh::scale_free_time_step(noisy, 1.0);
  const double strong = 0.9;  // above the least triangle-inequality slack of the noisy sphere
  lapmesh::smooth_laplacian_implicit(
    noisy, lambda,
    LP::mollification_factor(strong, LP::laplacian(lapmesh::Laplacian::intrinsic_delaunay).number_of_iterations(2)));
  const double direct = lapmesh::mesh_deviation(clean, noisy).rms_distance;
  const double with_strong = rms_after(strong), with_default = rms_after(lapmesh::default_mollification_factor);
  EXPECT_NEAR(with_strong, direct, 1e-12);
  EXPECT_GT(std::abs(with_strong - with_default), 1e-6) << "the factor must change the operator";
  s.mollification = -1;
  EXPECT_THROW(lapmesh::run_denoising_study(clean, s), lapmesh::Parameter_error);
}

TEST(Denoising, StudyRejectsBadSettings)
{
  const Mesh clean = to_mesh(lapmesh::icosphere(1));
  lapmesh::Denoising_study_settings s;
  s.iterations = 0;
  EXPECT_THROW(lapmesh::run_denoising_study(clean, s), std::invalid_argument);
  s.iterations = 2;
  s.time_steps = {0.1, -1.0};
  EXPECT_THROW(lapmesh::run_denoising_study(clean, s), std::invalid_argument);
  s.time_steps = {0.1};
  s.noise_levels = {std::nan("")};
  EXPECT_THROW(lapmesh::run_denoising_study(clean, s), std::invalid_argument);
}

// ---- command line -------------------------------------------------------------------

namespace {

Cli_result run_study_cli(const std::string& args) { return run_lapmesh("denoise-study " + args); }

} // namespace

TEST(DenoisingCli, BadLevelsLambdasOrIterationsFailCleanly)
{
  const std::string in = lapmesh_test::scratch_dir() + "/study_in.off";
  {
    const auto [P, tris] = lapmesh::io::mesh_arrays(to_mesh(lapmesh::icosphere(1)));
    lapmesh::io::write_mesh(in, P, tris);
  }
  const std::string out = lapmesh_test::scratch_dir() + "/study_bad.csv";
  const std::string svg = lapmesh_test::scratch_dir() + "/study_bad.svg";
  const std::vector<std::string> bad = {
    "--levels -0.1",        "--levels abc",          "--levels 0.02,,0.1",  "--levels nan",
    "--levels ''",          "--lambdas 0",           "--lambdas 0.1,-1",    "--lambdas inf",
    "--lambdas x",          "--iterations 0",        "--iterations -3",     "--schemes explicit,bogus",
    "--laplacians cotan"};
  run_test_cases(bad, [&](const std::string& args) {
    std::filesystem::remove(out);
    std::filesystem::remove(svg);
    const Cli_result r = run_study_cli(in + " -o " + out + " --plot " + svg + " " + args);
    EXPECT_NE(r.status, 0) << args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << ": " << r.err;
    EXPECT_FALSE(std::filesystem::exists(out)) << args;
    EXPECT_FALSE(std::filesystem::exists(svg)) << args;
  });
}

TEST(DenoisingCli, WritesOneRowPerIterationAndReportsTheBest)
{
  const std::string in = lapmesh_test::scratch_dir() + "/study_in2.off";
  {
    const auto [P, tris] = lapmesh::io::mesh_arrays(to_mesh(lapmesh::bumpy_sphere(2)));
    lapmesh::io::write_mesh(in, P, tris);
  }
  const std::string out = lapmesh_test::scratch_dir() + "/study.csv", svg = lapmesh_test::scratch_dir() + "/study.svg";
  std::filesystem::remove(out);
  std::filesystem::remove(svg);
  const Cli_result r = run_study_cli(in + " -o " + out + " --plot " + svg + " --levels 0.02,0.1 --lambdas 0.1,1 --iterations 3");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string csv = read_file(out);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 2 * 2 * 2 * 2 * (3 + 1));
  EXPECT_EQ(csv.rfind("noise_level,sigma,scheme,laplacian,lambda_edge2,", 0), 0u);
  // Four "level ..., scheme: best ..." lines.
  std::size_t best_lines = 0;
  for(std::size_t p = r.out.find("best "); p != std::string::npos; p = r.out.find("best ", p + 1)) ++best_lines;
  EXPECT_EQ(best_lines, 4u) << r.out;
  const std::string plot = read_file(svg);
  EXPECT_EQ(plot.rfind("<svg", 0), 0u);
  EXPECT_NE(plot.find("implicit cotangent"), std::string::npos);
  EXPECT_EQ(r.out.find("coarsened"), std::string::npos) << r.out;
}

TEST(DenoisingCli, SaysWhenTheHausdorffGridWasCoarsened)
{
  const std::string in = lapmesh_test::scratch_dir() + "/study_in3.off";
  {
    const auto [P, tris] = lapmesh::io::mesh_arrays(to_mesh(lapmesh::icosphere(1)));
    lapmesh::io::write_mesh(in, P, tris);
  }
  const std::string out = lapmesh_test::scratch_dir() + "/study_grid.csv";
  const std::string args = " --levels 0.05 --schemes implicit --laplacians cotangent --lambdas 0.1 --iterations 1";
  const Cli_result fine = run_study_cli(in + " -o " + out + args + " --hausdorff-spacing 0.05");
  ASSERT_EQ(fine.status, 0) << fine.err;
  EXPECT_EQ(fine.out.find("coarsened"), std::string::npos) << fine.out;
  // 1e-5 edge lengths would put about 5e9 samples on each of the 80 faces; 2^20 samples in all
  // is a spacing of about 1/160 edge length, some 600 times coarser.
  const Cli_result coarse = run_study_cli(in + " -o " + out + args + " --hausdorff-spacing 1e-5");
  ASSERT_EQ(coarse.status, 0) << coarse.err;
  const std::string note = "Hausdorff grid coarsened, up to ";
  const std::size_t at = coarse.out.find(note);
  ASSERT_NE(at, std::string::npos) << coarse.out;
  const double factor = std::stod(coarse.out.substr(at + note.size()));
  EXPECT_GT(factor, 300.0) << coarse.out;
  EXPECT_LT(factor, 1500.0) << coarse.out;
}

// ---- why runs fail, and what the command line says about it ---------------------------

namespace {

// A thin torus (tube radius 0.08, ring radius 1): under the implicit cotangent flow the tube
// collapses onto its core circle long before the ring moves, as the cow's horns and legs do,
// so its faces become nearly segments within a few steps of lambda = 0.01 and the
// factorisation fails (CHOLMOD's "not positive definite", reported, not printed).
Mesh thin_torus() { return to_mesh(lapmesh::torus(48, 8, 1.0, 0.08)); }

std::string write_thin_torus(const std::string& name)
{
  const std::string path = lapmesh_test::scratch_dir() + "/" + name;
  const auto [P, tris] = lapmesh::io::mesh_arrays(thin_torus());
  lapmesh::io::write_mesh(path, P, tris);
  return path;
}

// The fields of a CSV line (RFC 4180 quotes).
std::vector<std::string> csv_fields(const std::string& line)
{
  std::vector<std::string> out(1);
  bool quoted = false;
  for(std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if(quoted) {
      if(c == '"' && i + 1 < line.size() && line[i + 1] == '"') out.back() += '"', ++i;
      else if(c == '"') quoted = false;
      else out.back() += c;
    } else if(c == '"') {
      quoted = true;
    } else if(c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  return out;
}

} // namespace

TEST(Denoising, AFailedRunRecordsWhyAndTheIterationThatCollapsedAFace)
{
  const Mesh clean = thin_torus();
  lapmesh::Denoising_study_settings s;
  s.noise_levels = {0.0};
  s.schemes = {lapmesh::Smoothing_scheme::implicit_euler};
  s.laplacians = {lapmesh::Laplacian::cotangent};
  s.unit = lapmesh::Time_step_unit::absolute;
  s.time_steps = {0.01};
  s.iterations = 12;
  const lapmesh::Denoising_study study = lapmesh::run_denoising_study(clean, s);
  ASSERT_EQ(study.records.size(), 13u);

  // The same flow run directly: the engine names the iteration and the collapsed face.
  Mesh direct = clean;
  std::string direct_error;
  try {
    lapmesh::smooth_laplacian_implicit(direct, 0.01, CGAL::parameters::number_of_iterations(12));
  } catch(const std::exception& e) {  // zero area (Mesh_error) or a failed factorisation (Numerical_error)
    direct_error = e.what();
  }
  ASSERT_EQ(direct_error.rfind("iteration ", 0), 0u) << direct_error;
  EXPECT_NE(direct_error.find("the flow collapsed it"), std::string::npos) << direct_error;
  const int failed_at = std::stoi(direct_error.substr(10));
  EXPECT_GE(failed_at, 2);
  EXPECT_LT(failed_at, 12);

  for(const auto& r : study.records) {
    if(r.iteration <= failed_at) {
      // Measured before the collapse was detected: ok, finite, no message.
      EXPECT_EQ(r.status, lapmesh::Run_status::ok) << r.iteration;
      EXPECT_TRUE(std::isfinite(r.deviation.rms_distance)) << r.iteration;
      EXPECT_EQ(r.message, "") << r.iteration;
    } else {
      EXPECT_EQ(r.status, lapmesh::Run_status::failed) << r.iteration;
      EXPECT_EQ(r.message, direct_error) << r.iteration;
      EXPECT_TRUE(std::isnan(r.deviation.rms_distance)) << r.iteration;
    }
  }
}

// A run that ends with the step that collapses a face fails as a longer run does, naming the
// same iteration and face; one step fewer succeeds and leaves a mesh whose operator assembles.
// The cow's flow at this lambda takes a face below the zero-area tolerance in one step (the
// thin torus's nearly collapsed faces make the factorisation fail first).
TEST(Denoising, ARunEndingWithTheCollapsingStepFailsAsALongerRunDoes)
{
  Mesh cow;
  lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh("cow.off"), cow);
  Mesh smoothed;
  const auto error_of_run = [&](int iterations) {
    smoothed = cow;
    try {
      lapmesh::smooth_laplacian_implicit(smoothed, 1e-5, CGAL::parameters::number_of_iterations(iterations));
    } catch(const lapmesh::Mesh_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string longer = error_of_run(40);
  ASSERT_EQ(longer.rfind("iteration ", 0), 0u) << longer;
  EXPECT_NE(longer.find(" has zero area (the flow collapsed it"), std::string::npos) << longer;
  const int failed_at = std::stoi(longer.substr(10));
  ASSERT_GE(failed_at, 2);
  EXPECT_EQ(error_of_run(failed_at), longer);
  EXPECT_EQ(error_of_run(failed_at - 1), "");
  EXPECT_NO_THROW(lapmesh::laplacian_pencil(smoothed));
}

// The same with Voronoi areas, which valid faces can make non-positive: a run that ends with
// the step that makes one so fails as a longer run does, serially and in parallel (where the
// corner lists of the last assembly are released before the check); one step fewer leaves
// positive areas. CGAL's blade at this lambda takes a vertex's area below zero in a few steps.
TEST(Denoising, ARunEndingWithAStepThatMakesAVoronoiAreaNonPositiveFailsAsALongerRunDoes)
{
  Mesh blade;
  lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh("blade.off"), blade);
  ASSERT_GT(lapmesh::vertex_areas(blade, LP::vertex_area(lapmesh::Vertex_area::voronoi)).minCoeff(), 0);
  Mesh smoothed;
  const auto error_of_run = [&](int iterations, auto concurrency) {
    smoothed = blade;
    try {
      lapmesh::smooth_laplacian_implicit<decltype(concurrency)>(
        smoothed, 1e-3, LP::vertex_area(lapmesh::Vertex_area::voronoi, CGAL::parameters::number_of_iterations(iterations)));
    } catch(const lapmesh::Mesh_error& e) {
      EXPECT_EQ(e.element(), lapmesh::Mesh_error::Element::vertex) << e.what();
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string longer = error_of_run(20, CGAL::Sequential_tag());
  ASSERT_EQ(longer.rfind("iteration ", 0), 0u) << longer;
  EXPECT_NE(longer.find(" has a non-positive voronoi area ("), std::string::npos) << longer;
  const int failed_at = std::stoi(longer.substr(10));
  ASSERT_GE(failed_at, 2);
  EXPECT_EQ(error_of_run(failed_at, CGAL::Sequential_tag()), longer);
  EXPECT_EQ(error_of_run(failed_at, CGAL::Parallel_tag()), longer);
  EXPECT_EQ(error_of_run(failed_at - 1, CGAL::Parallel_tag()), "");
  EXPECT_GT(lapmesh::vertex_areas(smoothed, LP::vertex_area(lapmesh::Vertex_area::voronoi)).minCoeff(), 0);
}

// A flow that shrinks the whole mesh towards a point leaves M negligible beside lambda S (whose
// null space holds the constant vectors), and the factorisation fails although no face is flat:
// the error says so. CGAL's cube at lambda 5 (about one mean edge squared of its 8 vertices)
// shrinks by many orders of magnitude per step; with a fixed operator (and so a fixed M) the
// same run succeeds. (Volume restoration does not help: it rescales after each step, when the
// step has already reduced the cube to rounding noise.)
TEST(Denoising, AFlowThatShrinksTheMeshToAPointSaysSo)
{
  Mesh cube;
  lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh("cube.off"), cube);
  for(const auto area : {lapmesh::Vertex_area::barycentric, lapmesh::Vertex_area::voronoi}) {
    Mesh smoothed = cube;
    std::string error;
    try {
      lapmesh::smooth_laplacian_implicit(smoothed, 5.0,
                                         LP::vertex_area(area, CGAL::parameters::number_of_iterations(10)));
    } catch(const lapmesh::Numerical_error& e) {
      error = e.what();
    }
    ASSERT_EQ(error.rfind("iteration ", 0), 0u) << lapmesh::to_string(area) << ": " << error;
    EXPECT_NE(error.find(": the flow shrank the mesh to nearly a point (its area is "), std::string::npos) << error;
    const double ratio = std::stod(error.substr(error.find("its area is ") + 12));
    EXPECT_LT(ratio, 1e-12) << error;

    smoothed = cube;
    EXPECT_NO_THROW(lapmesh::smooth_laplacian_implicit(
      smoothed, 5.0, LP::vertex_area(area, LP::fixed_operator(true, CGAL::parameters::number_of_iterations(10)))));
    for(auto v : vertices(smoothed)) EXPECT_TRUE(std::isfinite(smoothed.point(v).x()));
  }
}

// A shrinking mesh can instead lose its vertex areas to underflow before a factorisation fails:
// CGAL's u.off under the intrinsic Delaunay flow at one mean edge length squared. Which of the
// two comes first depends on rounding (the optimisation level); the error names the shrinking
// in both cases, and which vertex area or factorisation failed after it.
TEST(Denoising, AShrinkingMeshThatLosesItsVertexAreasSaysItShrank)
{
  Mesh u;
  lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh("u.off"), u);
  ASSERT_GT(lapmesh::vertex_areas(u).minCoeff(), 0);
  const double h = lapmesh::mean_edge_length(u);
  std::string error;
  try {
    lapmesh::smooth_laplacian_implicit(u, h * h,
                                       LP::laplacian(lapmesh::Laplacian::intrinsic_delaunay,
                                                     CGAL::parameters::number_of_iterations(10)));
  } catch(const lapmesh::Numerical_error& e) {
    error = e.what();
  }
  ASSERT_EQ(error.rfind("iteration ", 0), 0u) << error;
  EXPECT_NE(error.find(": the flow shrank the mesh to nearly a point (its area is "), std::string::npos) << error;
  const bool areas = error.find("), and vertex ") != std::string::npos &&
                     error.find(" has a non-positive barycentric area (") != std::string::npos;
  const bool factorisation = error.find("), and the Cholesky factorisation of M - lambda S") != std::string::npos;
  EXPECT_TRUE(areas != factorisation) << error;
  EXPECT_NE(error.find("; a smaller lambda, fewer iterations or a fixed operator avoid this"), std::string::npos) << error;
}

// The same for one connected component: CGAL's bones (several components) under a conformal
// flow with area restoration and a free boundary keep their total area, but a small bone
// shrinks to a point, and the error names it by its first vertex and size.
TEST(Denoising, AFlowThatShrinksOneComponentToAPointNamesIt)
{
  Mesh bones;
  lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh("bones.off"), bones);
  std::string error;
  try {
    lapmesh::smooth_conformal_flow(
      bones, 0.07, LP::restore_area(true, LP::fix_boundary(false, CGAL::parameters::number_of_iterations(10))));
  } catch(const lapmesh::Numerical_error& e) {
    error = e.what();
  }
  ASSERT_EQ(error.rfind("iteration ", 0), 0u) << error;
  const std::string named = ": the flow shrank the connected component of vertex ";
  const std::size_t at = error.find(named);
  ASSERT_NE(at, std::string::npos) << error;
  // The component named, by CGAL's face components: its smallest vertex and its vertex count.
  const std::size_t first = std::stoul(error.substr(at + named.size()));
  const std::size_t size = std::stoul(error.substr(error.find(" (", at + named.size()) + 2));
  Mesh input;
  lapmesh::io::read_triangle_mesh(lapmesh_test::cgal_mesh("bones.off"), input);
  auto face_component = input.add_property_map<Mesh::Face_index, std::size_t>("f:component").first;
  ASSERT_GT(CGAL::Polygon_mesh_processing::connected_components(input, face_component), 1u);
  std::vector<std::size_t> component(num_vertices(input));
  for(auto f : faces(input))
    for(auto v : vertices_around_face(halfedge(f, input), input)) component[v.idx()] = face_component[f];
  ASSERT_LT(first, component.size());
  EXPECT_EQ(std::size_t(std::count(component.begin(), component.end(), component[first])), size);
  EXPECT_EQ(std::size_t(std::find(component.begin(), component.end(), component[first]) - component.begin()), first);
  EXPECT_LT(std::stod(error.substr(error.find("its area is ") + 12)), 1e-12) << error;
}

// The implicit cotangent flow maps a sphere of radius r << sqrt(lambda) nearly onto its centre in
// one step and, at the next, below 1e-12 x lambda in area, where its part of M is lost beside
// lambda S. The flow holds that component where it is and goes on with the others, whose steps
// are those they take alone (the components do not couple).
TEST(Denoising, AComponentShrunkToAPointIsHeldWhileTheOthersGoOn)
{
  const double lambda = 0.01;
  const int steps = 6;
  Mesh both = to_mesh(spheres({1.0, 0.01}));
  Mesh alone = to_mesh(spheres({1.0}));
  const std::size_t big = num_vertices(alone), small = num_vertices(both) - big;
  const auto report = lapmesh::smooth_laplacian_implicit(both, lambda, CGAL::parameters::number_of_iterations(steps));
  lapmesh::smooth_laplacian_implicit(alone, lambda, CGAL::parameters::number_of_iterations(steps));
  EXPECT_EQ(report.iterations, steps);
  ASSERT_EQ(report.collapsed_components.size(), 1u);
  const lapmesh::Collapsed_component& held = report.collapsed_components[0];
  EXPECT_EQ(held.iteration, 2);
  EXPECT_EQ(held.first_vertex, big);
  EXPECT_EQ(held.vertices, small);
  EXPECT_LT(held.area_over_lambda, 1e-12);
  const Eigen::MatrixXd P = positions(both), Q = positions(alone);
  for(std::size_t i = 0; i < big; ++i)
    ASSERT_LT((P.row(Eigen::Index(i)) - Q.row(Eigen::Index(i))).norm(), 1e-12) << i;
  // The small sphere stays where step 2 left it, a sphere of radius about 1e-8 around its
  // centre (where the flow keeps the mass-weighted centroid); another step would have shrunk
  // it far more.
  Mesh two_steps = to_mesh(spheres({1.0, 0.01}));
  lapmesh::smooth_laplacian_implicit(two_steps, lambda, CGAL::parameters::number_of_iterations(2));
  const Eigen::MatrixXd R = positions(two_steps);
  double spread = 0;
  for(std::size_t i = big; i < big + small; ++i) {
    const Eigen::Index row = Eigen::Index(i);
    spread = std::max(spread, (P.row(row) - Eigen::RowVector3d(3, 0, 0)).norm());
    ASSERT_LT((P.row(row) - R.row(row)).norm(), 1e-14) << i;
  }
  EXPECT_GT(spread, 1e-9);
  EXPECT_LT(spread, 1e-7);

  // When every component in the system shrinks at once, nothing is left to go on: the flow
  // ends with the error that names one of them, as on a single component.
  Mesh tiny = to_mesh(spheres({0.01, 0.01}));
  std::string error;
  try {
    lapmesh::smooth_laplacian_implicit(tiny, lambda, CGAL::parameters::number_of_iterations(steps));
  } catch(const lapmesh::Numerical_error& e) {
    error = e.what();
  }
  EXPECT_EQ(error.rfind("iteration 2: the flow shrank the connected component of vertex ", 0), 0u) << error;
}

// In the study, a run whose flow holds a collapsed component is marked `held` from the step
// that shrank it on (naming it), keeps its measurements, and is left out of the best run; a
// time step too small to collapse anything leaves its run `ok`.
TEST(Denoising, StudyMarksTheStepsAfterAComponentWasHeld)
{
  const Mesh clean = to_mesh(spheres({1.0, 0.01}));
  const std::size_t big = lapmesh::icosphere(3).points.size(), small = num_vertices(clean) - big;
  lapmesh::Denoising_study_settings s;
  s.noise_levels = {0.0};
  s.schemes = {lapmesh::Smoothing_scheme::implicit_euler};
  s.laplacians = {lapmesh::Laplacian::cotangent};
  s.unit = lapmesh::Time_step_unit::absolute;
  s.time_steps = {1e-6, 0.01};
  s.iterations = 5;
  s.area = lapmesh::Vertex_area::mixed;
  const lapmesh::Denoising_study study = lapmesh::run_denoising_study(clean, s);
  ASSERT_EQ(study.records.size(), 2u * 6u);

  // The same flow outside the study: where it holds the small sphere, and the positions then.
  Mesh alone = clean;
  const auto report = lapmesh::smooth_laplacian_implicit(
    alone, 0.01, LP::vertex_area(lapmesh::Vertex_area::mixed, CGAL::parameters::number_of_iterations(s.iterations)));
  ASSERT_EQ(report.collapsed_components.size(), 1u);
  const int held_at = report.collapsed_components[0].iteration;
  ASSERT_GE(held_at, 1);
  ASSERT_LT(held_at, s.iterations);
  const lapmesh::Mesh_deviation last = lapmesh::mesh_deviation(clean, alone);

  const std::string reason = "held: the connected component of vertex " + std::to_string(big) + " (" +
                             std::to_string(small) + " vertices) since iteration " + std::to_string(held_at);
  for(const lapmesh::Denoising_record& r : study.records) {
    const bool held = r.time_step == 0.01 && r.iteration >= held_at;
    EXPECT_EQ(r.status, held ? lapmesh::Run_status::held : lapmesh::Run_status::ok) << r.time_step << ", " << r.iteration;
    EXPECT_EQ(r.message, held ? reason : "") << r.time_step << ", " << r.iteration;
    EXPECT_TRUE(std::isfinite(r.deviation.rms_distance)) << r.time_step << ", " << r.iteration;
  }
  const lapmesh::Denoising_record& final_held = study.records.back();
  EXPECT_NEAR(final_held.deviation.rms_distance, last.rms_distance, 1e-12 * last.rms_distance);
  const auto best = study.best(0.0, lapmesh::Smoothing_scheme::implicit_euler);
  ASSERT_TRUE(best.has_value());
  EXPECT_EQ(best->status, lapmesh::Run_status::ok);
  // Here every later step is further from the clean mesh, so the best is `ok` whether or not
  // held rows count: a held row made closer than every `ok` one shows that they do not.
  lapmesh::Denoising_study closer = study;
  closer.records.back().deviation.rms_distance = 0.5 * best->deviation.rms_distance;
  const auto still = closer.best(0.0, lapmesh::Smoothing_scheme::implicit_euler);
  ASSERT_TRUE(still.has_value());
  EXPECT_EQ(still->status, lapmesh::Run_status::ok);
  EXPECT_EQ(still->deviation.rms_distance, best->deviation.rms_distance);
  // The best step of the held run alone: its closest `ok` row, never the made-up held one.
  const auto run_best = closer.best(0.0, lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Laplacian::cotangent, 0.01);
  ASSERT_TRUE(run_best.has_value());
  double closest_ok = std::numeric_limits<double>::infinity();
  for(const lapmesh::Denoising_record& r : closer.records)
    if(r.time_step == 0.01 && r.iteration >= 1 && r.iteration < held_at) closest_ok = std::min(closest_ok, r.deviation.rms_distance);
  EXPECT_EQ(run_best->deviation.rms_distance, closest_ok);
  EXPECT_EQ(run_best->time_step, 0.01);
  EXPECT_LT(run_best->iteration, held_at);
  EXPECT_FALSE(closer.best(0.0, lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Laplacian::uniform, 0.01).has_value());

  // Each run's records, from iteration 0 on, are the study's rows of that run; a run the study
  // did not make has none.
  for(std::size_t k = 0; k < s.time_steps.size(); ++k) {
    const double tau = s.time_steps[k];
    const std::vector<lapmesh::Denoising_record> run =
      study.run(0.0, lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Laplacian::cotangent, tau);
    ASSERT_EQ(run.size(), std::size_t(s.iterations) + 1) << tau;
    for(std::size_t i = 0; i < run.size(); ++i) {
      const lapmesh::Denoising_record& row = study.records[k * run.size() + i];
      EXPECT_EQ(run[i].iteration, int(i)) << tau;
      EXPECT_EQ(run[i].time_step, tau);
      EXPECT_EQ(run[i].status, row.status) << tau << ", " << i;
      EXPECT_EQ(run[i].deviation.rms_distance, row.deviation.rms_distance) << tau << ", " << i;
    }
  }
  EXPECT_EQ(study.run(0.0, lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Laplacian::cotangent, 0.01).back().status,
            lapmesh::Run_status::held);
  EXPECT_TRUE(study.run(0.0, lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Laplacian::uniform, 0.01).empty());
  EXPECT_TRUE(study.run(0.0, lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Laplacian::cotangent, 0.02).empty());
  EXPECT_TRUE(study.run(0.05, lapmesh::Smoothing_scheme::implicit_euler, lapmesh::Laplacian::cotangent, 0.01).empty());
}

// A run that holds a component and fails at a later step keeps its steps from the hold on
// `held`: the holds are collected as they happen, not taken from the report that the failure
// loses. Here the small sphere is held, and the large one then shrinks until a step fails.
TEST(Denoising, StudyKeepsTheHeldStepsOfARunThatFailsLater)
{
  const Mesh clean = to_mesh(spheres({1.0, 0.01}));
  const std::size_t big = lapmesh::icosphere(3).points.size(), small = num_vertices(clean) - big;
  constexpr double lambda = 0.1;
  lapmesh::Denoising_study_settings s;
  s.noise_levels = {0.0};
  s.schemes = {lapmesh::Smoothing_scheme::implicit_euler};
  s.laplacians = {lapmesh::Laplacian::cotangent};
  s.unit = lapmesh::Time_step_unit::absolute;
  s.time_steps = {lambda};
  s.iterations = 12;
  s.area = lapmesh::Vertex_area::mixed;
  const auto flow = [&](Mesh& m, int iterations) {
    return lapmesh::smooth_laplacian_implicit(
      m, lambda, LP::vertex_area(lapmesh::Vertex_area::mixed, CGAL::parameters::number_of_iterations(iterations)));
  };
  // The same flow outside the study: the step that holds the small sphere, and the failure.
  int held_at = 0;
  for(int iterations = 1; iterations <= s.iterations && held_at == 0; ++iterations) {
    Mesh m = clean;
    const auto report = flow(m, iterations);
    if(!report.collapsed_components.empty()) held_at = report.collapsed_components[0].iteration;
  }
  ASSERT_GE(held_at, 1);
  Mesh whole = clean;
  EXPECT_THROW(flow(whole, s.iterations), std::runtime_error);  // a collapsed face or a failed factorisation

  const lapmesh::Denoising_study study = lapmesh::run_denoising_study(clean, s);
  ASSERT_EQ(study.records.size(), std::size_t(s.iterations) + 1);
  const std::string reason = "held: the connected component of vertex " + std::to_string(big) + " (" +
                             std::to_string(small) + " vertices) since iteration " + std::to_string(held_at);
  int held_rows = 0, failed_rows = 0;
  for(const lapmesh::Denoising_record& r : study.records) {
    if(r.iteration < held_at) {
      EXPECT_EQ(r.status, lapmesh::Run_status::ok) << r.iteration;
    } else if(r.status == lapmesh::Run_status::held) {
      EXPECT_EQ(failed_rows, 0) << r.iteration << ": a held step after the failure";
      EXPECT_EQ(r.message, reason) << r.iteration;
      EXPECT_TRUE(std::isfinite(r.deviation.rms_distance)) << r.iteration;
      ++held_rows;
    } else {
      EXPECT_EQ(r.status, lapmesh::Run_status::failed) << r.iteration;
      EXPECT_FALSE(r.message.empty()) << r.iteration;
      EXPECT_EQ(r.message.find("held:"), std::string::npos) << r.iteration;
      ++failed_rows;
    }
  }
  EXPECT_GE(held_rows, 1);
  EXPECT_GE(failed_rows, 1);
}

// Negative cotangent weights (obtuse triangles) do not make M - lambda S indefinite: -S is a
// sum of positive semidefinite element matrices. A one-step flow on a mesh full of obtuse
// triangles factorises at any lambda.
TEST(Denoising, ImplicitSystemStaysPositiveDefiniteWithNegativeWeightsAtHugeLambda)
{
  Mesh m = jitter(to_mesh(lapmesh::icosphere(3)), 0.06, 5);
  const auto pencil = lapmesh::laplacian_pencil(m);
  int negative_weights = 0;
  for(int k = 0; k < pencil.stiffness.outerSize(); ++k)
    for(Eigen::SparseMatrix<double>::InnerIterator it(pencil.stiffness, k); it; ++it)
      if(it.row() != it.col() && it.value() < 0) ++negative_weights;
  ASSERT_GT(negative_weights, 0);
  for(double lambda : {1.0, 1e3, 1e6}) {
    Mesh smoothed = m;
    EXPECT_NO_THROW(lapmesh::smooth_laplacian_implicit(smoothed, lambda, CGAL::parameters::number_of_iterations(1))) << lambda;
    for(auto v : vertices(smoothed)) ASSERT_TRUE(std::isfinite(smoothed.point(v).x())) << lambda;
  }
}

#ifdef LAPMESH_HAS_CHOLMOD
// CHOLMOD prints its own warnings unless told not to; lapmesh reports them in its exceptions.
TEST(Denoising, CholmodFailuresAreReportedNotPrinted)
{
  Eigen::SparseMatrix<double> A(3, 3);  // lower triangle of an indefinite matrix
  A.insert(0, 0) = 1.0;
  A.insert(1, 1) = -1.0;
  A.insert(2, 2) = 1.0;
  A.insert(2, 0) = 0.5;
  A.makeCompressed();
  lapmesh::internal::Spd_direct_solver solver(true);
  ASSERT_STREQ(solver.name(), "cholmod-supernodal");
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  solver.analyze(A, 1);
  const bool ok = solver.factorize(A);
  std::fflush(nullptr);
  const std::string out = testing::internal::GetCapturedStdout(), err = testing::internal::GetCapturedStderr();
  EXPECT_FALSE(ok);
  EXPECT_EQ(out, "");
  EXPECT_EQ(err, "");
  EXPECT_NE(solver.failure().find("not positive definite"), std::string::npos) << solver.failure();
}
#endif

TEST(DenoisingCli, FailedRunsSayWhyInTheCsvAndTheSummary)
{
  const std::string in = write_thin_torus("thin_torus.off");
  const std::string out = lapmesh_test::scratch_dir() + "/fail.csv";
  // Level 0: noise would break the tube's symmetry and delay the collapse.
  const Cli_result r = run_study_cli(in + " -o " + out + " --levels 0 --schemes implicit --laplacians uniform,cotangent "
                                     "--lambda-unit absolute --lambdas 0.01 --iterations 12");
  ASSERT_EQ(r.status, 0) << r.err;
  std::istringstream csv(read_file(out));
  std::string line;
  std::getline(csv, line);
  const std::vector<std::string> header = csv_fields(line);
  ASSERT_EQ(header.size(), 14u) << line;
  EXPECT_EQ(header[12], "status");
  EXPECT_EQ(header[13], "error");
  int failed_rows = 0, ok_rows = 0;
  while(std::getline(csv, line)) {
    const std::vector<std::string> f = csv_fields(line);
    ASSERT_EQ(f.size(), 14u) << line;
    if(f[12] == "ok") {
      ++ok_rows;
      EXPECT_EQ(f[13], "") << line;
    } else {
      ++failed_rows;
      EXPECT_EQ(f[12], "failed") << line;
      EXPECT_EQ(f[3], "cotangent") << line;  // the uniform flow keeps the tube's shape
      EXPECT_EQ(f[13].rfind("iteration ", 0), 0u) << line;
      EXPECT_NE(f[13].find("the flow collapsed it"), std::string::npos) << line;
    }
  }
  EXPECT_GT(failed_rows, 0);
  EXPECT_GT(ok_rows, 13);
  EXPECT_NE(r.out.find("1 of 2 runs stopped early"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("cotangent lambda 0.01: iteration "), std::string::npos) << r.out;
}

TEST(DenoisingCli, LegendEntriesMatchThePlottedSeries)
{
  // The cotangent runs fail before the last iteration: their "after N iterations" series has
  // no point, and its legend entry must show no line.
  const std::string in = write_thin_torus("thin_torus.off");
  const std::string out = lapmesh_test::scratch_dir() + "/legend.csv", svg = lapmesh_test::scratch_dir() + "/legend.svg";
  const Cli_result r = run_study_cli(in + " -o " + out + " --plot " + svg + " --levels 0 --schemes implicit "
                                     "--laplacians uniform,cotangent --lambda-unit absolute --lambdas 0.01,0.03 --iterations 12");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string plot = read_file(svg);
  auto blocks = [&](const std::string& cls) {
    std::vector<std::string> out;
    const std::string open = "<g class=\"" + cls + "\"";
    for(std::size_t p = plot.find(open); p != std::string::npos; p = plot.find(open, p + 1))
      out.push_back(plot.substr(p, plot.find("</g>", p) - p));
    return out;
  };
  const std::vector<std::string> series = blocks("series"), legend = blocks("legend-entry");
  ASSERT_EQ(series.size(), legend.size());
  ASSERT_EQ(series.size(), 2u + 4u);  // one level: 2 curves (top), 2 x 2 by lambda (bottom)
  int empty_entries = 0;
  for(std::size_t i = 0; i < series.size(); ++i) {
    const bool line = series[i].find("<polyline") != std::string::npos;
    const bool markers = series[i].find("<circle") != std::string::npos;
    EXPECT_EQ(legend[i].find("<line") != std::string::npos, line) << legend[i];
    EXPECT_EQ(legend[i].find("<circle") != std::string::npos, markers) << legend[i];
    if(!line && !markers) {
      ++empty_entries;
      EXPECT_NE(legend[i].find("no run reached iteration 12"), std::string::npos) << legend[i];
    }
    // The colour and dash of the sample are the series' own.
    const std::size_t stroke = series[i].find("stroke=\"");
    if(line) {
      EXPECT_NE(legend[i].find(series[i].substr(stroke, 16)), std::string::npos) << legend[i];
      EXPECT_EQ(legend[i].find("stroke-dasharray") != std::string::npos,
                series[i].find("stroke-dasharray") != std::string::npos)
        << legend[i];
    }
  }
  EXPECT_EQ(empty_entries, 1);  // implicit cotangent after 12 iterations
}

TEST(DenoisingCli, SaysWhenTheBestRunIsWorseThanTheNoisyInput)
{
  const std::string in = lapmesh_test::scratch_dir() + "/sphere.off";
  {
    const auto [P, tris] = lapmesh::io::mesh_arrays(to_mesh(lapmesh::icosphere(2)));
    lapmesh::io::write_mesh(in, P, tris);
  }
  const std::string out = lapmesh_test::scratch_dir() + "/worse.csv";
  // Level 0: the "noisy" mesh is the clean one, so every smoothing step moves away from it.
  Cli_result r = run_study_cli(in + " -o " + out + " --levels 0 --schemes implicit --laplacians uniform --lambdas 0.1 "
                               "--iterations 2");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("level 0, implicit: best uniform"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  worse than the noisy input: no implicit run lowered the RMS distance below the noisy mesh's 0"),
            std::string::npos)
    << r.out;
  // The settings of StudyRecordsEveryIterationAndFindsAFiniteBestLambda, whose best run
  // lowers the RMS distance below 0.8 x the noisy mesh's.
  r = run_study_cli(in + " -o " + out + " --levels 0.1 --direction normal --restore-volume --seed 3 --schemes implicit "
                    "--lambdas 0.1,1,100 --iterations 4");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("level 0.1, implicit: best "), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("worse than the noisy input"), std::string::npos) << r.out;
}

TEST(DenoisingCli, ProgressLinesWhenStderrIsNotATerminal)
{
  const std::string in = write_thin_torus("thin_torus.off");
  const std::string out = lapmesh_test::scratch_dir() + "/progress.csv";
  const std::string args = in + " -o " + out + " --levels 0.01 --schemes explicit,implicit --laplacians uniform "
                           "--lambdas 0.1,0.3 --iterations 20 --progress-interval 0.001";
  Cli_result r = run_study_cli(args);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err.find('\r'), std::string::npos);  // whole lines, not a redrawn terminal line
  std::istringstream lines(r.err);
  std::string line;
  int periodic = 0, final_lines = 0;
  while(std::getline(lines, line)) {
    ASSERT_EQ(line.rfind("denoise-study: ", 0), 0u) << line;
    if(line.find("runs done in") != std::string::npos) ++final_lines;
    else if(line.find("/4 runs done, ") != std::string::npos) ++periodic;
    else ADD_FAILURE() << line;
  }
  EXPECT_EQ(final_lines, 1);
  EXPECT_GE(periodic, 2) << r.err;
  // Off with --no-progress and with --quiet; --progress brings it back under --quiet.
  EXPECT_EQ(run_study_cli(args + " --no-progress").err, "");
  EXPECT_EQ(run_study_cli(args + " -q").err, "");
  r = run_study_cli(args + " -q --progress");
  EXPECT_EQ(r.out, "");
  EXPECT_NE(r.err.find("runs done in"), std::string::npos) << r.err;
  EXPECT_NE(run_study_cli(args + " --progress --no-progress").status, 0);
}
