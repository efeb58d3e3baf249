// lapmesh's curvatures (cotangent Laplacian, mixed area) against CGAL's jet fitting
// (Monge_via_jet_fitting, degree 2 on the 2-ring), vertex by vertex. doc/crosscheck.md quotes
// this program's output; test/crosscheck_test.cpp asserts the same numbers.
//
// Usage: jet_fitting_crosscheck               analytic meshes against their closed forms
//        jet_fitting_crosscheck MESH...       agreement on each mesh, split by region
#include "jet_fitting_crosscheck.h"

#include <lapmesh/io.h>
#include <lapmesh/noise.h>
#include <lapmesh/shapes.h>

#include <CGAL/Subdivision_method_3/subdivision_methods_3.h>

#include <cstdio>
#include <iostream>
#include <string>

using namespace crosscheck;

namespace {

using Exact = std::array<double, 2> (*)(const std::array<double, 3>&);
std::array<double, 2> sphere_exact(const std::array<double, 3>&) { return {1.0, 1.0}; }
std::array<double, 2> ellipsoid_exact(const std::array<double, 3>& p) { return lapmesh::ellipsoid_curvatures(p, 1.5, 1.0, 0.7); }
std::array<double, 2> torus_exact(const std::array<double, 3>& p)
{
  const double R = 1.0, r = 0.4, c = std::cos(lapmesh::torus_tube_angle(p, R));
  return {(R + 2 * r * c) / (2 * r * (R + r * c)), c / (r * (R + r * c))};
}

// One row per quantity: each method's relative RMS error against the closed form, and the
// agreement of the two methods with each other.
void analytic_rows(const char* name, const lapmesh::Triangle_soup& soup, Exact exact, double noise = 0)
{
  Mesh m;
  lapmesh::make_mesh(soup, m);
  if(noise > 0) lapmesh::add_noise(m, noise, lapmesh::parameters::noise_direction(lapmesh::Noise_direction::normal));
  lapmesh::Vertex_vectors normals;
  const Curvature_fields lap = lapmesh_curvatures(m, &normals), jet = jet_curvatures(m, normals);
  const Curvature_fields ref = exact_curvatures(m, exact);
  for(int q = 0; q < 4; ++q) {
    const Agreement el = compare(lap, ref, q), ej = compare(jet, ref, q), lj = compare(lap, jet, q);
    char pearson[32] = "(exact is constant)";  // el.correlation is NaN then
    if(el.correlation == el.correlation) std::snprintf(pearson, sizeof pearson, "%.4f", lj.correlation);
    std::printf("| %s | %zu | %s | %.2e | %.2e | %.2e | %s |\n", name, std::size_t(m.number_of_vertices()), quantity_name(q),
                el.relative_rms, ej.relative_rms, lj.relative_rms, pearson);
  }
}

// Per-vertex features that explain disagreement: largest dihedral angle at an incident
// edge (creases), valence, largest corner angle of an incident face (obtuse regions).
enum Region { crease, low_valence, obtuse, regular };
const char* region_name[] = {"crease (dihedral > 30 deg)", "valence <= 4", "obtuse corner (> 100 deg)", "other"};

std::vector<Region> classify(const Mesh& m)
{
  auto normal = [&](Mesh::Face_index f) {
    const auto h = m.halfedge(f);
    const Point &a = m.point(m.source(h)), &b = m.point(m.target(h)), &c = m.point(m.target(m.next(h)));
    const auto n = CGAL::cross_product(b - a, c - a);
    return n / std::sqrt(n.squared_length());
  };
  std::vector<Region> out(m.number_of_vertices(), regular);
  for(Mesh::Vertex_index v : vertices(m)) {
    double max_dihedral = 0, max_angle = 0;
    for(Mesh::Halfedge_index h : CGAL::halfedges_around_target(m.halfedge(v), m)) {
      if(!m.is_border(h) && !m.is_border(m.opposite(h)))
        max_dihedral = std::max(max_dihedral, std::acos(std::clamp(normal(m.face(h)) * normal(m.face(m.opposite(h))), -1.0, 1.0)));
      if(m.is_border(h)) continue;
      for(Mesh::Halfedge_index g : CGAL::halfedges_around_face(h, m)) {
        const Point &p = m.point(m.target(g)), &a = m.point(m.source(g)), &b = m.point(m.target(m.next(g)));
        const auto u = a - p, w = b - p;
        max_angle = std::max(max_angle, std::acos(std::clamp(u * w / std::sqrt(u.squared_length() * w.squared_length()), -1.0, 1.0)));
      }
    }
    out[v.idx()] = max_dihedral > M_PI / 6 ? crease : m.degree(v) <= 4 ? low_valence : max_angle > M_PI * 100 / 180 ? obtuse : regular;
  }
  return out;
}

void real_mesh(const std::string& path)
{
  Mesh m;
  lapmesh::io::read_triangle_mesh(path, m);
  lapmesh::Vertex_vectors normals;
  const Curvature_fields lap = lapmesh_curvatures(m, &normals), jet = jet_curvatures(m, normals);
  std::printf("\n%s: %zu vertices\n\n| quantity | RMS difference | relative RMS | Pearson | Spearman | same sign |\n"
              "|---|---|---|---|---|---|\n",
              path.substr(path.find_last_of('/') + 1).c_str(), std::size_t(m.number_of_vertices()));
  for(int q = 0; q < 4; ++q) {
    const Agreement a = compare(lap, jet, q);
    std::printf("| %s | %.3g | %.3f | %.4f | %.4f | %.1f%% |\n", quantity_name(q), a.rms_difference, a.relative_rms,
                a.correlation, a.rank_correlation, 100 * a.sign_agreement);
  }
  {
    Jet_options raw;  // CGAL's frame as fitted: the normal's sign is the PCA's, not the surface's
    raw.orient = false;
    const Agreement a = compare(lap, jet_curvatures(m, normals, raw), 0);
    std::printf("| H, Monge frame not oriented | %.3g | %.3f | %.4f | %.4f | %.1f%% |\n", a.rms_difference, a.relative_rms,
                a.correlation, a.rank_correlation, 100 * a.sign_agreement);
  }
  // where the differences in H are: share of the squared difference per region
  const std::vector<Region> region = classify(m);
  const Agreement all = compare(lap, jet, 0);
  std::printf("\n| region | vertices | relative RMS of H difference | share of squared difference | Pearson H |\n|---|---|---|---|---|\n");
  for(int r = 0; r < 4; ++r) {
    std::vector<char> in(lap.used);
    for(std::size_t i = 0; i < in.size(); ++i) in[i] = in[i] && region[i] == r;
    const Agreement a = compare(lap.mean, jet.mean, in, jet.used);
    const double rms_jet = all.rms_difference / all.relative_rms;
    std::printf("| %s | %zu | %.3f | %.1f%% | %.4f |\n", region_name[r], a.count, a.rms_difference / rms_jet,
                100.0 * a.rms_difference * a.rms_difference * double(a.count) /
                  (all.rms_difference * all.rms_difference * double(all.count)),
                a.correlation);
  }
  // the jet's smoothing radius: agreement of H as the neighbourhood grows
  std::printf("\n| jet neighbourhood | relative RMS of H difference | Pearson H |\n|---|---|---|\n");
  for(int rings = 1; rings <= 3; ++rings) {
    Jet_options opt;
    opt.min_rings = rings;
    opt.min_points = rings == 1 ? 6 : 16;
    const Agreement a = compare(lap, jet_curvatures(m, normals, opt), 0);
    std::printf("| %d-ring%s | %.3f | %.4f |\n", rings, rings == 1 ? " (2-ring below 6 points)" : "", a.relative_rms, a.correlation);
  }
  // the same shape, better resolved: Loop subdivision smooths it and shrinks the edges
  std::printf("\n| Loop subdivision | vertices | relative RMS of H difference | Pearson H | Spearman H |\n|---|---|---|---|---|\n");
  for(int level = 1; level <= 2; ++level) {
    Mesh fine(m);
    CGAL::Subdivision_method_3::Loop_subdivision(fine, CGAL::parameters::number_of_iterations(level));
    lapmesh::Vertex_vectors fine_normals;
    const Curvature_fields fl = lapmesh_curvatures(fine, &fine_normals);
    const Agreement a = compare(fl, jet_curvatures(fine, fine_normals), 0);
    std::printf("| %d | %zu | %.3f | %.4f | %.4f |\n", level, std::size_t(fine.number_of_vertices()), a.relative_rms,
                a.correlation, a.rank_correlation);
  }
}

} // namespace

int main(int argc, char** argv)
{
  for(int i = 1; i < argc; ++i) try {
      real_mesh(argv[i]);
    } catch(const std::exception& e) {
      std::cerr << argv[i] << ": " << e.what() << '\n';
      return 1;
    }
  if(argc > 1) return 0;
  try {
    std::printf("| mesh | vertices | quantity | lapmesh error | jet error | lapmesh vs jet | Pearson |\n"
                "|---|---|---|---|---|---|---|\n");
    for(int level = 3; level <= 5; ++level) analytic_rows("unit sphere", lapmesh::icosphere(level), sphere_exact);
    for(int level = 3; level <= 5; ++level)
      analytic_rows("ellipsoid 1.5 x 1 x 0.7", lapmesh::ellipsoid(level, 1.5, 1.0, 0.7), ellipsoid_exact);
    for(int nu = 40; nu <= 160; nu *= 2) analytic_rows("torus R=1, r=0.4", lapmesh::torus(nu, nu * 2 / 5), torus_exact);
    for(double noise : {0.01, 0.05})
      analytic_rows(noise == 0.01 ? "unit sphere, noise 0.01" : "unit sphere, noise 0.05", lapmesh::icosphere(4), sphere_exact, noise);
  } catch(const std::exception& e) {
    std::cerr << "built-in mesh: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
