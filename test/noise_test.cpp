// Noise: the same seed gives the same noise and another seed other noise (noise_seed's 64 bits
// over random_seed's 32), and the displacements have the requested sigma, scale and direction.
#include "test_helpers.h"

#include <lapmesh/noise.h>

#include <cmath>
#include <cstdint>
#include <random>

using namespace lapmesh_test;
namespace LP = lapmesh::parameters;

TEST(Noise, SameSeedSameNoiseDifferentSeedDifferentNoise)
{
  const Mesh input = to_mesh(lapmesh::icosphere(3));
  for(auto dir : {lapmesh::Noise_direction::isotropic, lapmesh::Noise_direction::normal}) {
    Mesh a = input, b = input, c = input;
    lapmesh::add_noise(a, 0.1, LP::noise_direction(dir).random_seed(7));
    lapmesh::add_noise(b, 0.1, LP::noise_direction(dir).random_seed(7));
    lapmesh::add_noise(c, 0.1, LP::noise_direction(dir).random_seed(8));
    EXPECT_EQ((positions(a) - positions(b)).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_GT((positions(a) - positions(c)).cwiseAbs().maxCoeff(), 1e-3);
  }
  // noise_seed takes all 64 bits and precedence over random_seed, which it equals below 2^32.
  Mesh a = input, b = input, c = input;
  lapmesh::add_noise(a, 0.1, LP::noise_seed(std::uint64_t(7)));
  lapmesh::add_noise(b, 0.1, LP::noise_seed(std::uint64_t(7) + (std::uint64_t(1) << 40)).random_seed(7));
  lapmesh::add_noise(c, 0.1, CGAL::parameters::random_seed(7));
  EXPECT_EQ((positions(a) - positions(c)).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((positions(a) - positions(b)).cwiseAbs().maxCoeff(), 1e-3);
  // std::mt19937_64 is fixed by the standard: its 10000th output from the default seed.
  std::mt19937_64 rng;
  rng.discard(9999);
  EXPECT_EQ(rng(), 9981545732273789042ull);
}

TEST(Noise, StatisticsMatchSigma)
{
  const Mesh input = to_mesh(lapmesh::icosphere(5));
  double edge_sum = 0;
  for(auto e : edges(input)) edge_sum += std::sqrt(CGAL::squared_distance(input.point(source(e, input)), input.point(target(e, input))));
  const double mean_edge = edge_sum / double(num_edges(input));
  const double level = 0.05;
  {
    Mesh m = input;
    const double sigma = lapmesh::add_noise(m, level, CGAL::parameters::random_seed(3));
    EXPECT_NEAR(sigma, level * mean_edge, 1e-12);
    const Eigen::MatrixXd d = positions(m) - positions(input);
    const Eigen::Map<const Eigen::VectorXd> all(d.data(), d.size());  // 30726 samples
    EXPECT_NEAR(all.mean(), 0.0, 4 * sigma / std::sqrt(double(all.size())));
    EXPECT_NEAR(rms(all), sigma, 0.03 * sigma);
  }
  {
    Mesh m = input;
    const double sigma = lapmesh::add_noise(
      m, level, LP::noise_scale(lapmesh::Noise_scale::bounding_box_diagonal, LP::noise_direction(lapmesh::Noise_direction::normal)));
    const Eigen::MatrixXd P = positions(input);
    const double diag = (P.colwise().maxCoeff() - P.colwise().minCoeff()).norm();
    EXPECT_NEAR(sigma, level * diag, 1e-12);
    const Eigen::MatrixXd d = positions(m) - P;
    Eigen::VectorXd along(d.rows());
    for(Eigen::Index i = 0; i < d.rows(); ++i) {
      const Eigen::Vector3d normal = P.row(i).normalized();  // icosphere: the normal is radial to ~1e-3
      along[i] = d.row(i).dot(normal);
      EXPECT_LE((d.row(i).transpose() - along[i] * normal).norm(), 1e-2 * std::abs(along[i]) + 1e-15);
    }
    EXPECT_NEAR(rms(along), sigma, 0.03 * sigma);
  }
}

// Normal noise passes over a zero-area face (it has no normal and weighs nothing in the
// area-weighted normals) instead of refusing the mesh: on an icosphere with one face split into
// two and a collinear sliver (closed and manifold), it moves every vertex exactly as on the same
// mesh without the sliver. Before, the sliver made the call throw.
TEST(Noise, NormalNoisePassesOverAZeroAreaFace)
{
  lapmesh::Triangle_soup soup = lapmesh::icosphere(2);
  const std::array<int, 3> split = soup.triangles.front();  // (a, b, c)
  const auto &pa = soup.points[std::size_t(split[0])], &pb = soup.points[std::size_t(split[1])];
  const int m = int(soup.points.size());
  soup.points.push_back({0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]), 0.5 * (pa[2] + pb[2])});
  soup.triangles.front() = {split[0], m, split[2]};
  soup.triangles.push_back({m, split[1], split[2]});
  lapmesh::Triangle_soup without_sliver = soup;
  soup.triangles.push_back({m, split[0], split[1]});  // collinear: zero area

  Mesh with = to_mesh(soup), without = to_mesh(without_sliver);
  ASSERT_EQ(num_faces(with), num_faces(without) + 1);
  const Eigen::MatrixXd before = positions(with);
  // Scaled by the bounding box, which the sliver does not change (the mean edge length would).
  const auto np = LP::noise_scale(lapmesh::Noise_scale::bounding_box_diagonal,
                                  LP::noise_direction(lapmesh::Noise_direction::normal, LP::noise_seed(std::uint64_t(11))));
  ASSERT_NO_THROW(lapmesh::add_noise(with, 0.05, np));
  lapmesh::add_noise(without, 0.05, np);
  EXPECT_EQ((positions(with) - positions(without)).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((positions(with) - before).rowwise().norm().minCoeff(), 0.0);  // every vertex has a normal
}
