// Cross-check of lapmesh's curvatures against CGAL's Jet_fitting_3 (Monge_via_jet_fitting).
//
// Shared by examples/jet_fitting_crosscheck.cpp (which prints the tables of
// doc/crosscheck.md) and test/crosscheck_test.cpp (which asserts them), so that the numbers
// the documentation quotes come from the code the tests check.
//
// Choices (doc/crosscheck.md explains them):
//  - lapmesh: cotangent Laplacian with the mixed vertex area (the barycentric area keeps a
//    ~15% error at irregular vertices, which would dominate the comparison).
//  - jet fit: degree 2, Monge degree 2, on the k-ring of the vertex gathered by breadth-first
//    search: at least `min_rings` rings (default 2) and grown ring by ring until it holds at
//    least `min_points` points (default 16), the vertex itself first (CGAL computes the
//    Monge form at the first point).
//  - orientation: the Monge normal is flipped to agree with lapmesh's area-weighted vertex
//    normal (comply_wrt_given_normal). CGAL writes the surface as z = (k1 x^2 + k2 y^2) / 2
//    along that normal, so a sphere with outward normal gets -1/r; lapmesh's convention is
//    H = +1/r there. Hence k1 = -monge k2, k2 = -monge k1 (the order reverses with the sign).
//  - boundary vertices are skipped (`used` = 0): lapmesh's H is not a surface curvature there.
#ifndef LAPMESH_EXAMPLES_JET_FITTING_CROSSCHECK_H
#define LAPMESH_EXAMPLES_JET_FITTING_CROSSCHECK_H

#include <lapmesh/curvature.h>

#include <CGAL/Monge_via_jet_fitting.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace crosscheck {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;

struct Jet_options
{
  std::size_t degree = 2;         ///< degree of the fitted jet
  std::size_t monge_degree = 2;   ///< degree of the Monge form (2: principal curvatures only)
  int min_rings = 2;              ///< rings always gathered
  std::size_t min_points = 16;    ///< grow the neighbourhood until it has this many points
  int max_rings = 6;              ///< never grow beyond this
  bool orient = true;             ///< comply with lapmesh's normal (false: CGAL's raw PCA frame)
};

/// Four per-vertex curvature fields in lapmesh's conventions (entry i = vertex i).
struct Curvature_fields
{
  Eigen::VectorXd mean, gaussian, k1, k2;
  std::vector<char> used;  ///< 0 for vertices left out of every statistic (boundary, too few points)

  const Eigen::VectorXd& operator[](int q) const
  {
    return q == 0 ? mean : q == 1 ? gaussian : q == 2 ? k1 : k2;
  }
};

inline const char* quantity_name(int q) { return q == 0 ? "H" : q == 1 ? "K" : q == 2 ? "k1" : "k2"; }

/// lapmesh's fields (cotangent, mixed area) with boundary vertices marked unused; also
/// returns the vertex normals through `normals`.
inline Curvature_fields lapmesh_curvatures(const Mesh& m, lapmesh::Vertex_vectors* normals = nullptr)
{
  const lapmesh::Vertex_curvatures c =
    lapmesh::vertex_curvatures(m, lapmesh::parameters::vertex_area(lapmesh::Vertex_area::mixed));
  Curvature_fields f{c.mean, c.gaussian, c.k1, c.k2, std::vector<char>(m.number_of_vertices(), 1)};
  for(Mesh::Vertex_index v : vertices(m))
    if(CGAL::is_border(v, m)) f.used[v.idx()] = 0;
  if(normals) *normals = c.normal;
  return f;
}

/// Gathers the rings around v (v first) by breadth-first search into `points`; returns the
/// number of rings gathered. `stamp` must hold one entry per vertex, never equal to v's index
/// before the call (it is set to v's index for every visited vertex).
inline int gather_rings(const Mesh& m, Mesh::Vertex_index v, const Jet_options& opt,
                        std::vector<std::size_t>& stamp, std::vector<Point>& points)
{
  points.assign(1, m.point(v));
  stamp[v.idx()] = v.idx();
  std::vector<Mesh::Vertex_index> frontier{v}, next;
  int rings = 0;
  while(!frontier.empty() && rings < opt.max_rings &&
        (rings < opt.min_rings || points.size() < opt.min_points)) {
    next.clear();
    for(Mesh::Vertex_index u : frontier)
      for(Mesh::Vertex_index w : CGAL::vertices_around_target(m.halfedge(u), m))
        if(stamp[w.idx()] != v.idx()) {
          stamp[w.idx()] = v.idx();
          next.push_back(w);
          points.push_back(m.point(w));
        }
    frontier.swap(next);
    ++rings;
  }
  return rings;
}

/// CGAL's jet-fitting principal curvatures at every vertex, in lapmesh's sign convention
/// relative to `normals` (lapmesh's outward area-weighted vertex normals). Boundary vertices
/// and vertices with fewer points than the jet has coefficients are marked unused.
inline Curvature_fields jet_curvatures(const Mesh& m, const lapmesh::Vertex_vectors& normals,
                                       const Jet_options& opt = Jet_options())
{
  using Monge = CGAL::Monge_via_jet_fitting<Kernel>;
  const std::size_t n = m.number_of_vertices();
  Curvature_fields f{Eigen::VectorXd::Zero(Eigen::Index(n)), Eigen::VectorXd::Zero(Eigen::Index(n)),
                     Eigen::VectorXd::Zero(Eigen::Index(n)), Eigen::VectorXd::Zero(Eigen::Index(n)),
                     std::vector<char>(n, 0)};
  std::vector<std::size_t> stamp(n, std::numeric_limits<std::size_t>::max());
  std::vector<Point> points;
  const std::size_t coefficients = (opt.degree + 1) * (opt.degree + 2) / 2;
  Monge fitter;
  for(Mesh::Vertex_index v : vertices(m)) {
    if(CGAL::is_border(v, m)) continue;
    gather_rings(m, v, opt, stamp, points);
    if(points.size() < coefficients) continue;
    Monge::Monge_form form = fitter(points.begin(), points.end(), opt.degree, opt.monge_degree);
    double k1 = form.principal_curvatures(0), k2 = form.principal_curvatures(1);
    if(opt.orient) {
      const Eigen::Index i = Eigen::Index(v.idx());
      form.comply_wrt_given_normal(Kernel::Vector_3(normals(i, 0), normals(i, 1), normals(i, 2)));
      // CGAL: z = (k1 x^2 + k2 y^2) / 2 along the normal; lapmesh: sphere +1/r with outward normal
      k1 = -form.principal_curvatures(1);
      k2 = -form.principal_curvatures(0);
    }
    const Eigen::Index i = Eigen::Index(v.idx());
    f.k1[i] = k1;
    f.k2[i] = k2;
    f.mean[i] = 0.5 * (k1 + k2);
    f.gaussian[i] = k1 * k2;
    f.used[v.idx()] = 1;
  }
  return f;
}

/// Closed-form fields from a function of the vertex position returning {H, K}.
template <typename Exact>
Curvature_fields exact_curvatures(const Mesh& m, Exact exact)
{
  const Eigen::Index n = Eigen::Index(m.number_of_vertices());
  Curvature_fields f{Eigen::VectorXd(n), Eigen::VectorXd(n), Eigen::VectorXd(n), Eigen::VectorXd(n),
                     std::vector<char>(std::size_t(n), 1)};
  for(Mesh::Vertex_index v : vertices(m)) {
    const Point& p = m.point(v);
    const std::array<double, 2> hk = exact(std::array<double, 3>{p.x(), p.y(), p.z()});
    const double root = std::sqrt(std::max(hk[0] * hk[0] - hk[1], 0.0));
    const Eigen::Index i = Eigen::Index(v.idx());
    f.mean[i] = hk[0];
    f.gaussian[i] = hk[1];
    f.k1[i] = hk[0] + root;
    f.k2[i] = hk[0] - root;
  }
  return f;
}

/// Agreement of a field `a` with a reference field `b` over the vertices used by both.
struct Agreement
{
  double rms_difference = 0;  ///< sqrt(mean (a - b)^2)
  double relative_rms = 0;    ///< rms_difference / sqrt(mean b^2)
  double correlation = 0;     ///< Pearson correlation of a and b
  double rank_correlation = 0;  ///< Spearman: Pearson correlation of the ranks (robust to outliers)
  double sign_agreement = 0;  ///< fraction of the vertices where a and b have the same sign
  std::size_t count = 0;      ///< vertices compared
};

namespace internal {

inline double pearson(const std::vector<double>& a, const std::vector<double>& b)
{
  double ma = 0, mb = 0;
  for(std::size_t i = 0; i < a.size(); ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= double(a.size());
  mb /= double(b.size());
  double va = 0, vb = 0, cov = 0;
  for(std::size_t i = 0; i < a.size(); ++i) {
    va += (a[i] - ma) * (a[i] - ma);
    vb += (b[i] - mb) * (b[i] - mb);
    cov += (a[i] - ma) * (b[i] - mb);
  }
  // a constant field (the exact H of a sphere, k1 = 1/r on a torus) has no correlation
  const bool a_varies = va > 1e-20 * double(a.size()) * ma * ma, b_varies = vb > 1e-20 * double(b.size()) * mb * mb;
  return a_varies && b_varies && va > 0 && vb > 0 ? cov / std::sqrt(va * vb) : std::numeric_limits<double>::quiet_NaN();
}

inline std::vector<double> ranks(const std::vector<double>& x)
{
  std::vector<std::size_t> order(x.size());
  for(std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return x[i] < x[j]; });
  std::vector<double> r(x.size());
  for(std::size_t k = 0; k < order.size();) {  // ties share their mean rank
    std::size_t e = k;
    while(e + 1 < order.size() && x[order[e + 1]] == x[order[k]]) ++e;
    for(std::size_t t = k; t <= e; ++t) r[order[t]] = 0.5 * double(k + e);
    k = e + 1;
  }
  return r;
}

} // namespace internal

inline Agreement compare(const Eigen::VectorXd& a, const Eigen::VectorXd& b, const std::vector<char>& used_a,
                         const std::vector<char>& used_b)
{
  std::vector<double> x, y;
  double sd = 0, sbb = 0, same_sign = 0;
  for(Eigen::Index i = 0; i < a.size(); ++i) {
    if(!used_a[std::size_t(i)] || !used_b[std::size_t(i)]) continue;
    x.push_back(a[i]);
    y.push_back(b[i]);
    sd += (a[i] - b[i]) * (a[i] - b[i]);
    sbb += b[i] * b[i];
    same_sign += (a[i] > 0) == (b[i] > 0) ? 1 : 0;
  }
  Agreement r;
  r.count = x.size();
  if(x.empty()) return r;
  const double N = double(x.size());
  r.rms_difference = std::sqrt(sd / N);
  r.relative_rms = sbb > 0 ? std::sqrt(sd / sbb) : std::numeric_limits<double>::infinity();
  r.correlation = internal::pearson(x, y);
  r.rank_correlation = internal::pearson(internal::ranks(x), internal::ranks(y));
  r.sign_agreement = same_sign / N;
  return r;
}

inline Agreement compare(const Curvature_fields& a, const Curvature_fields& b, int quantity)
{
  return compare(a[quantity], b[quantity], a.used, b.used);
}

} // namespace crosscheck

#endif
