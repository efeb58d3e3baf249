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

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
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

namespace internal {
/// Adds the points to `g` as vertices (vertex i = point i) and then the triangles one at a time
/// with CGAL::Euler::add_face(); returns false at the first face it refuses.
template <typename Points, typename Triangles, typename MutableFaceGraph>
bool add_face_by_face(const Points& points, const Triangles& triangles, MutableFaceGraph& g)
{
  using GT = boost::graph_traits<MutableFaceGraph>;
  using Point = typename boost::property_traits<
    typename boost::property_map<MutableFaceGraph, CGAL::vertex_point_t>::type>::value_type;
  auto vpm = get(CGAL::vertex_point, g);
  std::vector<typename GT::vertex_descriptor> vs;
  vs.reserve(points.size());
  for(const auto& p : points) {
    vs.push_back(add_vertex(g));
    put(vpm, vs.back(), Point(p[0], p[1], p[2]));
  }
  for(const auto& t : triangles) {
    const std::array<typename GT::vertex_descriptor, 3> f = {vs[t[0]], vs[t[1]], vs[t[2]]};
    if(CGAL::Euler::add_face(f, g) == GT::null_face()) return false;
  }
  return true;
}
} // namespace internal

/// Builds the soup into an (empty or not) mutable face graph; vertex i of the soup becomes
/// the i-th added vertex. Returns false if a face could not be added (non-manifold soup).
template <typename MutableFaceGraph>
bool make_mesh(const Triangle_soup& soup, MutableFaceGraph& g)
{
  return internal::add_face_by_face(soup.points, soup.triangles, g);
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

/// A sphere with radial bumps r(p) = 1 + amplitude * sin(f x) sin(f y) sin(f z): smooth, with
/// regions of both curvature signs, on the icosphere's regular, symmetric triangulation.
inline Triangle_soup bumpy_sphere(int level, double amplitude = 0.08, double frequency = 6.0)
{
  Triangle_soup s = icosphere(level, 1.0);
  for(auto& p : s.points) {
    const double r = 1.0 + amplitude * std::sin(frequency * p[0]) * std::sin(frequency * p[1]) * std::sin(frequency * p[2]);
    for(double& c : p) c *= r;
  }
  return s;
}

/// The solid of bumpy_box(): a cube of half-size 2.5 centred at the origin with its edges and
/// corners rounded to radius 1, and on each face a cylindrical bump of radius 0.9 along the
/// face's axis, ending in a half-ellipsoid (semi-axis 1.3 along the axis) whose tip is 4.4
/// from the centre. Returns true for points of the closed solid.
inline bool bumpy_box_contains(const std::array<double, 3>& p)
{
  constexpr double half = 2.5, rounding = 1.0, radius = 0.9, shaft = 3.1, cap = 1.3;
  double box = 0;
  for(double c : p) {
    const double out = std::max(std::abs(c) - (half - rounding), 0.0);
    box += out * out;
  }
  if(box <= rounding * rounding) return true;
  for(int k = 0; k < 3; ++k) {
    const double axial = std::abs(p[k]);
    const double rho2 = p[(k + 1) % 3] * p[(k + 1) % 3] + p[(k + 2) % 3] * p[(k + 2) % 3];
    const double beyond = std::max(axial - shaft, 0.0) / cap;
    if(rho2 / (radius * radius) + beyond * beyond <= 1.0) return true;
  }
  return false;
}

/// The point of bumpy_box()'s surface in the direction d (|d| = 1), to 1e-13: the solid is
/// star-shaped from the origin (a union of convex sets that contain it), so the ray from the
/// origin leaves it once, and bisection finds where.
inline std::array<double, 3> bumpy_box_surface_point(const std::array<double, 3>& d)
{
  double lo = 0.0, hi = 5.0;  // inside at 0, outside beyond the tips (4.4)
  for(int i = 0; i < 46; ++i) {
    const double mid = 0.5 * (lo + hi);
    (bumpy_box_contains({mid * d[0], mid * d[1], mid * d[2]}) ? lo : hi) = mid;
  }
  const double t = 0.5 * (lo + hi);
  return {t * d[0], t * d[1], t * d[2]};
}


namespace internal {

inline double corner_angle(const std::array<double, 3>& at, const std::array<double, 3>& p, const std::array<double, 3>& q)
{
  double uu = 0, vv = 0, uv = 0;
  for(int k = 0; k < 3; ++k) {
    const double u = p[k] - at[k], v = q[k] - at[k];
    uu += u * u; vv += v * v; uv += u * v;
  }
  return std::acos(std::max(-1.0, std::min(1.0, uv / std::sqrt(uu * vv))));
}

inline std::array<double, 3> triangle_normal(const Triangle_soup& s, int a, int b, int c)
{
  const auto &p = s.points[a], &q = s.points[b], &r = s.points[c];
  const double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
  return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
}



/// A closed soup with its directed edges indexed, for edge flips.
struct Flippable_soup
{
  Triangle_soup& s;
  std::map<std::pair<int, int>, int> face_of;  // directed edge (u, v) -> the face holding u -> v
  std::vector<int> valence;

  explicit Flippable_soup(Triangle_soup& soup) : s(soup), valence(soup.points.size(), 0)
  {
    for(int f = 0; f < int(s.triangles.size()); ++f) index(f, +1);
  }
  void index(int f, int sign)
  {
    const auto& t = s.triangles[std::size_t(f)];
    for(int k = 0; k < 3; ++k) {
      if(sign > 0) face_of[{t[k], t[(k + 1) % 3]}] = f;
      else face_of.erase({t[k], t[(k + 1) % 3]});
      valence[std::size_t(t[k])] += sign;
    }
  }
  void set(int f, const std::array<int, 3>& t) { index(f, -1); s.triangles[std::size_t(f)] = t; index(f, +1); }
  void add(const std::array<int, 3>& t) { s.triangles.push_back(t); index(int(s.triangles.size()) - 1, +1); }
  /// The third vertex of the face holding the directed edge u -> v, or -1.
  int apex(int u, int v) const
  {
    const auto it = face_of.find({u, v});
    if(it == face_of.end()) return -1;
    const auto& t = s.triangles[std::size_t(it->second)];
    return t[0] != u && t[0] != v ? t[0] : t[1] != u && t[1] != v ? t[1] : t[2];
  }
  /// Replaces the faces (a, b, c) and (b, a, d) by (a, d, c) and (d, b, c); refused (false) when
  /// c-d is already an edge or a or b would keep fewer than 3 neighbours.
  bool flip(int a, int b)
  {
    const auto f = face_of.find({a, b}), g = face_of.find({b, a});
    if(f == face_of.end() || g == face_of.end()) return false;
    const int fi = f->second, gi = g->second, c = apex(a, b), d = apex(b, a);
    if(c == d || face_of.count({c, d}) || face_of.count({d, c}) || valence[std::size_t(a)] <= 3 || valence[std::size_t(b)] <= 3)
      return false;
    index(fi, -1);
    index(gi, -1);
    s.triangles[std::size_t(fi)] = {a, d, c};
    s.triangles[std::size_t(gi)] = {d, b, c};
    index(fi, +1);
    index(gi, +1);
    return true;
  }
};

/// Flips every edge of a closed soup for which should_flip(a, b, c, d) holds ((a, b, c) and
/// (b, a, d) its faces), pass after pass until none is left; a flip that would fold the surface
/// (a new normal against the old pair's), duplicate an edge or leave a vertex with fewer than 3
/// neighbours is skipped.
template <typename ShouldFlip>
void flip_edges(Triangle_soup& s, ShouldFlip should_flip, int max_passes = 100)
{
  Flippable_soup tri(s);
  for(int pass = 0; pass < max_passes; ++pass) {
    bool flipped = false;
    for(std::size_t f = 0; f < s.triangles.size(); ++f)
      for(int k = 0; k < 3; ++k) {
        const auto t = s.triangles[f];
        const int a = t[k], b = t[(k + 1) % 3], c = t[(k + 2) % 3], d = tri.apex(b, a);
        if(d < 0 || !should_flip(a, b, c, d)) continue;
        // keep the surface unfolded: both new faces turn the same way as the old pair
        const auto n1 = triangle_normal(s, a, b, c), n2 = triangle_normal(s, b, a, d);
        const auto m1 = triangle_normal(s, a, d, c), m2 = triangle_normal(s, d, b, c);
        auto dot = [](const std::array<double, 3>& x, const std::array<double, 3>& y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
        const std::array<double, 3> n = {n1[0] + n2[0], n1[1] + n2[1], n1[2] + n2[2]};
        if(dot(m1, n) > 0 && dot(m2, n) > 0 && tri.flip(a, b)) flipped = true;
      }
    if(!flipped) break;
  }
}

} // namespace internal

/// @brief a rounded box with six cylindrical bumps (bumpy_box_contains()), triangulated
/// irregularly: a test shape like the classic "bumpy" mesh of smoothing courses, with flat
/// faces, rounded edges, concave creases where the bumps meet the box, and bumps whose
/// reconstruction needs many Laplacian eigenvectors.
///
/// The vertices are a Poisson-disk sample of the surface (no two closer than `spacing`, drawn
/// by dart throwing from `seed`, the six bump tips first); the triangles are the Delaunay
/// triangulation of their directions on the unit sphere carried radially onto the surface, then
/// flipped to the Delaunay criterion on the surface. Valences 4-9, no symmetry, so no repeated
/// eigenvalues. The default spacing 0.3 gives about 1.2k vertices (1218 for seed 1), edges of
/// 0.3-0.65, angles above 29 degrees, bounding box [-4.4, 4.4]^3. The same seed and spacing give
/// the same soup on every platform (random numbers from the raw bits of std::mt19937_64).
/// @throws std::invalid_argument for spacing outside [0.15, 2]
inline Triangle_soup bumpy_box(std::uint64_t seed = 1, double spacing = 0.3)
{
  if(!(spacing >= 0.15 && spacing <= 2.0)) throw std::invalid_argument("bumpy_box: spacing must be in [0.15, 2]");
  std::mt19937_64 rng(seed);
  auto uniform = [&rng] { return double(rng() >> 11) / double(1ull << 53); };  // same on every platform
  auto unit = [](std::array<double, 3> p) {
    const double l = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    for(double& c : p) c /= l;
    return p;
  };
  // 1. A fine reference triangulation of the surface (an icosphere's directions pushed out to
  //    it), to draw candidate points uniformly by area.
  Triangle_soup fine = icosphere(4);
  for(auto& p : fine.points) p = bumpy_box_surface_point(p);
  std::vector<double> cumulative_area;
  double total = 0;
  for(const auto& t : fine.triangles) {
    const auto &a = fine.points[t[0]], &b = fine.points[t[1]], &c = fine.points[t[2]];
    const std::array<double, 3> u = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const std::array<double, 3> n = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    total += 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    cumulative_area.push_back(total);
  }
  // 2. Dart throwing: a candidate is kept when no kept point lies within `spacing` (a Poisson
  //    disk sample: no two vertices closer than spacing, no hole much wider, no regular pattern).
  //    Candidates are drawn until a long run of rejections shows the surface is covered.
  std::vector<std::array<double, 3>> kept;  // the six bump tips first: the initial octahedron
  const double cell = spacing;
  std::map<std::array<long, 3>, std::vector<int>> grid;
  auto key = [cell](const std::array<double, 3>& p) {
    return std::array<long, 3>{long(std::floor(p[0] / cell)), long(std::floor(p[1] / cell)), long(std::floor(p[2] / cell))};
  };
  for(int k = 0; k < 6; ++k) {
    std::array<double, 3> d = {0, 0, 0};
    d[k / 2] = k % 2 ? -1.0 : 1.0;
    kept.push_back(bumpy_box_surface_point(d));
    grid[key(kept.back())].push_back(k);
  }
  for(int rejected = 0; rejected < 20000;) {
    const double r = uniform() * total;
    const std::size_t f = std::size_t(std::upper_bound(cumulative_area.begin(), cumulative_area.end(), r) - cumulative_area.begin());
    const auto& t = fine.triangles[std::min(f, fine.triangles.size() - 1)];
    double s = uniform(), q = uniform();
    if(s + q > 1) { s = 1 - s; q = 1 - q; }
    std::array<double, 3> p;
    for(int k = 0; k < 3; ++k)
      p[k] = fine.points[t[0]][k] + s * (fine.points[t[1]][k] - fine.points[t[0]][k]) + q * (fine.points[t[2]][k] - fine.points[t[0]][k]);
    p = bumpy_box_surface_point(unit(p));
    const auto c = key(p);
    bool close = false;
    for(long i = -1; i <= 1 && !close; ++i)
      for(long j = -1; j <= 1 && !close; ++j)
        for(long k = -1; k <= 1 && !close; ++k) {
          auto it = grid.find({c[0] + i, c[1] + j, c[2] + k});
          if(it == grid.end()) continue;
          for(int idx : it->second) {
            const auto& o = kept[idx];
            const double d2 = (o[0] - p[0]) * (o[0] - p[0]) + (o[1] - p[1]) * (o[1] - p[1]) + (o[2] - p[2]) * (o[2] - p[2]);
            if(d2 < spacing * spacing) { close = true; break; }
          }
        }
    if(close) { ++rejected; continue; }
    rejected = 0;
    grid[c].push_back(int(kept.size()));
    kept.push_back(p);
  }
  // 3. Connectivity: the Delaunay triangulation of the points' directions on the unit sphere
  //    (their convex hull), which the radial map carries onto the star-shaped surface. Built
  //    from the tips' octahedron by inserting the directions one by one: each splits the
  //    spherical triangle holding it, then the edges that fold outwards are flipped (Lawson).
  Triangle_soup sphere;
  for(const auto& p : kept) sphere.points.push_back(unit(p));
  sphere.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  internal::Flippable_soup tri(sphere);
  auto det = [](const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c) {
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
  };
  for(int i = 6; i < int(kept.size()); ++i) {
    const auto& p = sphere.points[i];
    // the spherical triangle holding p: all three edges turn left to it (the most inside
    // one, should rounding put p on no triangle at all)
    int f = 0;
    double best = -std::numeric_limits<double>::infinity();
    for(int g = 0; g < int(sphere.triangles.size()); ++g) {
      const auto& t = sphere.triangles[std::size_t(g)];
      const double inside = std::min({det(sphere.points[t[0]], sphere.points[t[1]], p), det(sphere.points[t[1]], sphere.points[t[2]], p),
                                      det(sphere.points[t[2]], sphere.points[t[0]], p)});
      if(inside > best) { best = inside; f = g; }
      if(inside >= 0) break;
    }
    const auto t = sphere.triangles[std::size_t(f)];
    tri.set(f, {t[0], t[1], i});
    tri.add({t[1], t[2], i});
    tri.add({t[2], t[0], i});
    // Restore the hull: the edges facing the new point fold outwards when the point beyond
    // them lies above the plane through them and the new point.
    std::vector<std::pair<int, int>> suspect = {{t[0], t[1]}, {t[1], t[2]}, {t[2], t[0]}};
    while(!suspect.empty()) {
      const auto [a, b] = suspect.back();
      suspect.pop_back();
      const int d = tri.apex(b, a);
      if(d < 0) continue;
      auto from_a = [&](int v) {
        const auto &x = sphere.points[std::size_t(v)], &o = sphere.points[std::size_t(a)];
        return std::array<double, 3>{x[0] - o[0], x[1] - o[1], x[2] - o[2]};
      };
      if(!(det(from_a(b), from_a(i), from_a(d)) > 0)) continue;
      if(!tri.flip(a, b)) continue;
      suspect.push_back({a, d});
      suspect.push_back({d, b});
    }
  }
  Triangle_soup s;
  s.points = kept;
  s.triangles = sphere.triangles;
  // 4. On the surface, flip to the Delaunay criterion (opposite angles summing to at most pi):
  //    the radial map stretches the bumps' sides, where the sphere's triangles become needles.
  const double pi = std::acos(-1.0);
  internal::flip_edges(s, [&s, pi](int a, int b, int c, int d) {
    return internal::corner_angle(s.points[c], s.points[a], s.points[b]) +
             internal::corner_angle(s.points[d], s.points[b], s.points[a]) > pi + 1e-12;
  });
  return s;
}

} // namespace lapmesh

#endif
