// lapmesh — analytic triangle meshes with known curvature: for tests, benchmarks, examples
// and the command line's built-in meshes.
//
// Each generator returns a Triangle_soup (vertex positions and consistently oriented
// triangles with outward normals), which make_mesh() turns into any MutableFaceGraph.
// The closed forms of their curvatures are given beside each generator.
#ifndef LAPMESH_SHAPES_H
#define LAPMESH_SHAPES_H

#include <CGAL/boost/graph/Euler_operations.h>
#include <CGAL/boost/graph/helpers.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

namespace lapmesh {

/// Vertex positions and triangles (indices into `points`), consistently oriented.
struct Triangle_soup
{
  std::vector<std::array<double, 3>> points;  ///< vertex positions
  std::vector<std::array<int, 3>> triangles;  ///< counter-clockwise seen from outside
};

/// Builds the soup into an (empty or not) mutable face graph; vertex i of the soup becomes
/// the i-th added vertex. Returns false if a face could not be added (non-manifold soup).
template <typename MutableFaceGraph>
bool make_mesh(const Triangle_soup& soup, MutableFaceGraph& g)
{
  using GT = boost::graph_traits<MutableFaceGraph>;
  using Point = typename boost::property_traits<
    typename boost::property_map<MutableFaceGraph, CGAL::vertex_point_t>::type>::value_type;
  auto vpm = get(CGAL::vertex_point, g);
  std::vector<typename GT::vertex_descriptor> vs;
  vs.reserve(soup.points.size());
  for(const auto& p : soup.points) {
    vs.push_back(add_vertex(g));
    put(vpm, vs.back(), Point(p[0], p[1], p[2]));
  }
  for(const auto& t : soup.triangles) {
    const std::array<typename GT::vertex_descriptor, 3> f = {vs[t[0]], vs[t[1]], vs[t[2]]};
    if(CGAL::Euler::add_face(f, g) == GT::null_face()) return false;
  }
  return true;
}

/// Icosahedron subdivided `level` times, projected on the sphere of radius r:
/// 10 * 4^level + 2 vertices. H = 1/r, K = 1/r^2. Valence-5 vertices stay irregular.
inline Triangle_soup icosphere(int level, double r = 1.0)
{
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  Triangle_soup s;
  s.points = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
              {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  s.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  auto project = [r](std::array<double, 3>& p) {
    const double l = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    for(double& c : p) c *= r / l;
  };
  for(auto& p : s.points) project(p);
  for(int l = 0; l < level; ++l) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if(it != midpoint.end()) return it->second;
      std::array<double, 3> p;
      for(int k = 0; k < 3; ++k) p[k] = 0.5 * (s.points[a][k] + s.points[b][k]);
      project(p);
      s.points.push_back(p);
      return midpoint[key] = int(s.points.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    next.reserve(4 * s.triangles.size());
    for(const auto& f : s.triangles) {
      const int a = mid(f[0], f[1]), b = mid(f[1], f[2]), c = mid(f[2], f[0]);
      next.push_back({f[0], a, c});
      next.push_back({f[1], b, a});
      next.push_back({f[2], c, b});
      next.push_back({a, b, c});
    }
    s.triangles = std::move(next);
  }
  return s;
}

/// Icosphere scaled to the ellipsoid x^2/a^2 + y^2/b^2 + z^2/c^2 = 1 (vertices on it).
/// K = 1 / (a b c)^2 / q^2 and H = (a^2 + b^2 + c^2 - |x|^2) / (2 (a b c)^2 q^(3/2)),
/// with q = x^2/a^4 + y^2/b^4 + z^2/c^4 (outward normal, H > 0).
inline Triangle_soup ellipsoid(int level, double a, double b, double c)
{
  Triangle_soup s = icosphere(level, 1.0);
  for(auto& p : s.points) {
    p[0] *= a; p[1] *= b; p[2] *= c;
  }
  return s;
}

/// Closed-form curvatures of the ellipsoid at a point on it: {H, K}.
inline std::array<double, 2> ellipsoid_curvatures(const std::array<double, 3>& p, double a, double b, double c)
{
  const double q = p[0] * p[0] / (a * a * a * a) + p[1] * p[1] / (b * b * b * b) + p[2] * p[2] / (c * c * c * c);
  const double abc2 = a * a * b * b * c * c;
  const double r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
  return {(a * a + b * b + c * c - r2) / (2.0 * abc2 * std::pow(q, 1.5)), 1.0 / (abc2 * q * q)};
}

/// Torus with major radius R and minor radius r, nu x nv grid (u around the axis z, v
/// around the tube), each quad split into two triangles. With v the tube angle,
/// K = cos v / (r (R + r cos v)), H = (R + 2 r cos v) / (2 r (R + r cos v)).
inline Triangle_soup torus(int nu, int nv, double R = 1.0, double r = 0.4)
{
  if(nu < 3 || nv < 3) throw std::invalid_argument("torus needs at least a 3 x 3 grid");
  Triangle_soup s;
  s.points.reserve(std::size_t(nu) * nv);
  for(int i = 0; i < nu; ++i)
    for(int j = 0; j < nv; ++j) {
      const double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
      s.points.push_back({(R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v)});
    }
  auto id = [nu, nv](int i, int j) { return ((i + nu) % nu) * nv + (j + nv) % nv; };
  s.triangles.reserve(2 * std::size_t(nu) * nv);
  for(int i = 0; i < nu; ++i)
    for(int j = 0; j < nv; ++j) {
      s.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      s.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return s;
}

/// Tube angle v of a torus point (for the closed forms above).
inline double torus_tube_angle(const std::array<double, 3>& p, double R)
{
  return std::atan2(p[2], std::hypot(p[0], p[1]) - R);
}

/// Height-field patch z = f(x, y) over [-1, 1]^2 on an n x n vertex grid, with in-plane
/// jitter of `jitter` times the spacing (deterministic for a seed) to make it irregular.
/// Faces are oriented so that the normals point to +z.
template <typename HeightFunction>
Triangle_soup height_field(int n, HeightFunction f, double jitter = 0.0, std::uint64_t seed = 1)
{
  if(n < 2) throw std::invalid_argument("height_field needs at least 2 x 2 vertices");
  Triangle_soup s;
  std::mt19937_64 rng(seed);
  const double h = 2.0 / (n - 1);
  for(int i = 0; i < n; ++i)
    for(int j = 0; j < n; ++j) {
      double x = -1 + h * j, y = -1 + h * i;
      const bool interior = i > 0 && j > 0 && i < n - 1 && j < n - 1;
      if(interior && jitter > 0) {
        // uniform in [-jitter, jitter] * h from the raw bits: identical on every platform
        x += jitter * h * (2.0 * double(rng() >> 11) / double(1ull << 53) - 1.0);
        y += jitter * h * (2.0 * double(rng() >> 11) / double(1ull << 53) - 1.0);
      }
      s.points.push_back({x, y, f(x, y)});
    }
  for(int i = 0; i + 1 < n; ++i)
    for(int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
      s.triangles.push_back({a, b, d});
      s.triangles.push_back({a, d, c});
    }
  return s;
}

/// A flat square patch in z = 0 with boundary (irregular when jitter > 0).
inline Triangle_soup plane_patch(int n, double jitter = 0.0, std::uint64_t seed = 1)
{
  return height_field(n, [](double, double) { return 0.0; }, jitter, seed);
}

/// A sphere with radial bumps r(p) = 1 + amplitude * sin(f x) sin(f y) sin(f z): a generated
/// stand-in for the seed's bumpy mesh (smooth, with regions of both curvature signs).
inline Triangle_soup bumpy_sphere(int level, double amplitude = 0.08, double frequency = 6.0)
{
  Triangle_soup s = icosphere(level, 1.0);
  for(auto& p : s.points) {
    const double r = 1.0 + amplitude * std::sin(frequency * p[0]) * std::sin(frequency * p[1]) * std::sin(frequency * p[2]);
    for(double& c : p) c *= r;
  }
  return s;
}

} // namespace lapmesh

#endif
