// Denoising: the deviation metrics (zero on identical meshes, Hausdorff against a brute-force
// point-to-triangle computation), their fall when a noisy sphere is smoothed, the study driver
// (row count, per-iteration records equal to separate runs, divergence above the bound, best
// lambda) and the command line's refusal of bad levels, lambdas and iteration counts.
#include "test_helpers.h"

#include <lapmesh/denoising.h>
#include <lapmesh/io.h>
#include <lapmesh/laplacian_smoothing.h>
#include <lapmesh/noise.h>

#include <Eigen/Dense>

#include <cstdlib>
#include <filesystem>
#include <fstream>
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

// Closest point on triangle abc to p, by regions (vertex, edge, interior).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c)
{
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if(d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if(d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if(vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if(d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if(vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if(va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

std::vector<std::array<Eigen::Vector3d, 3>> triangles_of(const Mesh& m)
{
  std::vector<std::array<Eigen::Vector3d, 3>> out;
  for(auto f : faces(m)) {
    std::array<Eigen::Vector3d, 3> t;
    int k = 0;
    for(auto v : vertices_around_face(halfedge(f, m), m)) {
      const Point& p = m.point(v);
      t[k++] = Eigen::Vector3d(p.x(), p.y(), p.z());
    }
    out.push_back(t);
  }
  return out;
}

// max over a barycentric grid (r subdivisions per triangle) of `from` of the distance to `to`.
double brute_force_one_sided(const Mesh& from, const Mesh& to, int r)
{
  const auto A = triangles_of(from), B = triangles_of(to);
  double worst = 0;
  for(const auto& t : A)
    for(int i = 0; i <= r; ++i)
      for(int j = 0; i + j <= r; ++j) {
        const Eigen::Vector3d p = t[0] + (double(i) / r) * (t[1] - t[0]) + (double(j) / r) * (t[2] - t[0]);
        double best = std::numeric_limits<double>::infinity();
        for(const auto& s : B) best = std::min(best, (closest_on_triangle(p, s[0], s[1], s[2]) - p).norm());
        worst = std::max(worst, best);
      }
  return worst;
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

  // Volume change against CGAL's volume.
  const double V0 = CGAL::Polygon_mesh_processing::volume(clean), V1 = CGAL::Polygon_mesh_processing::volume(moved);
  EXPECT_NEAR(d.volume_change, (V1 - V0) / V0, 1e-12);
  // Normal error: between 0 and 90 degrees and non-zero.
  EXPECT_GT(d.normal_angle_error, 1.0);
  EXPECT_LT(d.normal_angle_error, 90.0);
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
                           "--lambdas 0.1,0.3 --iterations 20 --progress-interval 0.01";
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
