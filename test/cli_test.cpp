// End-to-end tests of `lapmesh curvature`: outputs against the library, the formats of doc/cli.md,
// and every bad input (one stderr line naming the file, non-zero exit, no output file).
#include "test_helpers.h"

#include <lapmesh/colormap.h>
#include <lapmesh/curvature.h>
#include <lapmesh/io.h>

#include <cstdio>
#include <fstream>
#include <sstream>

using namespace lapmesh_test;

namespace {

std::string tmp(const std::string& name) { return lapmesh_test::scratch_dir() + "/cli_" + name; }

std::size_t count_lines(const std::string& s) { return std::size_t(std::count(s.begin(), s.end(), '\n')); }

std::string write_mesh_file(const std::string& name, const lapmesh::Triangle_soup& soup)
{
  const Mesh m = to_mesh(soup);
  const auto [P, tris] = lapmesh::io::mesh_arrays(m);
  lapmesh::io::write_mesh(tmp(name), P, tris);
  return tmp(name);
}

} // namespace

TEST(Cli, CurvatureCsvMatchesTheLibraryToSeventeenDigits)
{
  const std::string in = write_mesh_file("torus.off", lapmesh::torus(30, 12));
  for(const char* lap : {"uniform", "cotangent"})
    for(const char* area : {"barycentric", "mixed"}) {
      const std::string out = tmp("torus.csv");
      std::remove(out.c_str());
      const Cli_result r = run_lapmesh("curvature " + in + " -o " + out + " --laplacian " + lap + " --area " + area + " -q");
      ASSERT_EQ(r.status, 0) << r.err;
      EXPECT_EQ(r.out, "");  // -q
      Mesh m;
      lapmesh::io::read_triangle_mesh(in, m);
      const auto c = lapmesh::vertex_curvatures(
        m, lapmesh::parameters::laplacian(*lapmesh::parse_laplacian(lap), lapmesh::parameters::vertex_area(*lapmesh::parse_vertex_area(area))));
      std::istringstream csv(read_file(out));
      std::string line;
      std::getline(csv, line);
      EXPECT_EQ(line, "vertex,mean,gaussian,k1,k2");
      Eigen::Index rows = 0;
      while(std::getline(csv, line)) {
        std::istringstream fields(line);
        std::string f;
        std::vector<std::string> cols;
        while(std::getline(fields, f, ',')) cols.push_back(f);
        ASSERT_EQ(cols.size(), 5u);
        EXPECT_EQ(std::stol(cols[0]), rows);
        EXPECT_EQ(std::stod(cols[1]), c.mean[rows]);  // 17 significant digits: exact
        EXPECT_EQ(std::stod(cols[2]), c.gaussian[rows]);
        EXPECT_EQ(std::stod(cols[3]), c.k1[rows]);
        EXPECT_EQ(std::stod(cols[4]), c.k2[rows]);
        ++rows;
      }
      EXPECT_EQ(rows, c.mean.size());
    }
}

TEST(Cli, CurvaturePlyAndCoffOutputs)
{
  const std::string in = write_mesh_file("sphere.obj", lapmesh::icosphere(2, 2.0));
  Cli_result r = run_lapmesh("curvature " + in + " -o " + tmp("sphere.ply") + " --area mixed --quantity gaussian --colormap viridis");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("162 vertices"), std::string::npos) << r.out;
  const std::string ply = read_file(tmp("sphere.ply"));
  for(const char* prop : {"property double mean", "property double gaussian", "property double k1", "property double k2",
                          "property uchar red", "element vertex 162", "element face 320"})
    EXPECT_NE(ply.find(prop), std::string::npos) << prop;
  r = run_lapmesh("curvature " + in + " -o " + tmp("sphere.off") + " --range 0:1 --colormap gray --area mixed");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string off = read_file(tmp("sphere.off"));
  EXPECT_EQ(off.rfind("COFF\n162 320 0\n", 0), 0u);
  // H = 0.5 on this sphere (mixed area), range [0, 1] in gray: mid-grey (barycentric would
  // give 145 here: the 14% error at the valence-5 vertex 0)
  std::istringstream lines(off);
  std::string line;
  std::getline(lines, line);
  std::getline(lines, line);
  std::getline(lines, line);
  double x, y, z;
  int red, green, blue, alpha;
  std::istringstream(line) >> x >> y >> z >> red >> green >> blue >> alpha;
  EXPECT_NEAR(red, 128, 4);
  EXPECT_EQ(alpha, 255);
}

TEST(Cli, HelpForEverySubcommandAndVersion)
{
  EXPECT_EQ(run_lapmesh("--help").status, 0);
  const Cli_result r = run_lapmesh("curvature --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("--laplacian"), std::string::npos);
  EXPECT_NE(r.out.find("not scale-correct"), std::string::npos);
  EXPECT_NE(run_lapmesh("--version").out.find("lapmesh"), std::string::npos);
}

TEST(Cli, BadInputsGiveOneLineNamingTheFileAndNoOutput)
{
  const std::string good = write_mesh_file("good.off", lapmesh::icosphere(1));
  auto file = [](const std::string& name, const std::string& text) {
    std::ofstream(tmp(name), std::ios::binary) << text;
    return tmp(name);
  };
  const std::string tri = "0 0 0\n1 0 0\n0 1 0\n";
  struct Case
  {
    std::string args, file_in_message, problem;
  };
  const std::string out = tmp("never_written.csv");
  const std::vector<Case> cases = {
    {tmp("missing.off"), tmp("missing.off"), "no such file"},
    {file("empty.off", ""), tmp("empty.off"), "empty file"},
    {file("trunc.off", "OFF\n3 1 0\n0 0 0\n"), tmp("trunc.off"), "truncated"},
    {file("counts.off", "OFF\n-3 1 0\n"), tmp("counts.off"), "bad counts"},
    {file("range.off", "OFF\n3 1 0\n" + tri + "3 0 1 9\n"), tmp("range.off"), "out of range"},
    {file("nan.off", "OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"), tmp("nan.off"), "vertex 1 has a non-finite"},
    {file("zero.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n"), tmp("zero.off"), "face 0 has zero area"},
    {file("nonmanifold.off", "OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n3 0 1 2\n3 1 0 3\n3 0 1 4\n"),
     tmp("nonmanifold.off"), "non-manifold"},
    {file("format.xyz", "1 2 3\n"), tmp("format.xyz"), "unsupported mesh format"},
  };
  run_test_cases(cases, [](const Case& c) { return c.args; }, [&](const Case& c) {
    const Cli_result r = run_lapmesh("curvature " + c.args + " -o " + out);
    EXPECT_NE(r.status, 0) << c.args;
    EXPECT_EQ(count_lines(r.err), 1u) << r.err;
    EXPECT_NE(r.err.find(c.file_in_message), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(c.problem), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out)) << c.args;
  });
  // usage errors: unknown option, bad values, bad output format
  run_test_cases(std::vector<std::string>{"curvature " + good + " -o " + out + " --bogus",
                                          "curvature " + good + " -o " + out + " --laplacian cotan",
                                          "curvature " + good + " -o " + out + " --range 2:1",
                                          "curvature " + good + " -o " + tmp("x.stl"),
                                          "curvature " + good, std::string("frobnicate")},
                 [&](const std::string& args) {
    const Cli_result r = run_lapmesh(args);
    EXPECT_NE(r.status, 0) << args;
    EXPECT_EQ(count_lines(r.err), 1u) << args << ": " << r.err;
    EXPECT_FALSE(std::filesystem::exists(out)) << args;
  });
  // a failure never clobbers an existing output file
  std::ofstream(out) << "keep me\n";
  EXPECT_NE(run_lapmesh("curvature " + tmp("zero.off") + " -o " + out).status, 0);
  EXPECT_EQ(read_file(out), "keep me\n");
  std::remove(out.c_str());
}

TEST(Cli, RealMeshFromCgalDataSet)
{
  const Cli_result r = run_lapmesh("curvature " + cgal_mesh("cow.off") + " -o " + tmp("cow.csv") + " --area mixed");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("2904 vertices, 5804 faces"), std::string::npos) << r.out;
  EXPECT_EQ(count_lines(read_file(tmp("cow.csv"))), 2905u);
}

// ---- messages ----------------------------------------------------------------------------

TEST(CliMessages, HugeCountsAreReportedAsGivenWithTheValidRange)
{
  const std::string in = write_mesh_file("msg_sphere.off", lapmesh::icosphere(1));  // 42 vertices
  const std::string out = tmp("msg_never.csv"), mesh_out = tmp("msg_never.off");
  struct Case
  {
    std::string args, expected;
  };
  const std::vector<Case> cases = {
    {"spectrum " + in + " -o " + out + " -k 18446744073709551615",
     "-k '18446744073709551615' is out of range (expected 1 <= k <= 42, the number of vertices)"},
    {"reconstruct " + in + " -o " + mesh_out + " -k 18446744073709551615",
     "-k '18446744073709551615' is out of range (expected 1 <= k <= 42, the number of vertices)"},
    {"spectrum " + in + " -o " + out + " -k 99999999999999999999999999",
     "-k '99999999999999999999999999' is out of range (expected 1 <= k <= 42"},
    {"spectrum " + in + " -o " + out + " -k -1", "-k '-1' is out of range (expected 1 <= k <= 42"},
    {"spectrum " + in + " -o " + out + " -k 43", "-k '43' is out of range (expected 1 <= k <= 42"},
    {"spectrum " + in + " -o " + out + " -k 0", "-k '0' is out of range (expected 1 <= k <= 42"},
    {"spectrum " + in + " -o " + out + " -k 5x", "-k '5x' is not an integer (expected 1 <= k <= 42"},
    {"spectrum " + in + " -o " + out + " -k ' 5'", "-k ' 5' is not an integer (expected 1 <= k <= 42"},
    {"reconstruct " + in + " -o " + mesh_out + " -k 5 --basis-size 18446744073709551615",
     "--basis-size '18446744073709551615' is out of range (expected 0 <= basis-size <= 42, the number of vertices)"},
    {"reconstruct " + in + " -o " + mesh_out + " -k 5 --basis-size -1",
     "--basis-size '-1' is out of range (expected 0 <= basis-size <= 42"},
  };
  run_test_cases(cases, [](const Case& c) { return c.args; }, [&](const Case& c) {
    const Cli_result r = run_lapmesh(c.args);
    EXPECT_EQ(r.status, 1) << c.args;
    EXPECT_EQ(count_lines(r.err), 1u) << r.err;
    EXPECT_NE(r.err.find(in + ": " + c.expected), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_EQ(r.err.find("-1)"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out) || std::filesystem::exists(mesh_out)) << c.args;
  });
  // The largest valid values still work.
  const Cli_result r = run_lapmesh("spectrum " + in + " -o " + out + " -k 0042 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(count_lines(read_file(out)), 43u);
  std::remove(out.c_str());
}

TEST(CliMessages, ChoiceErrorsListExactlyTheDocumentedNames)
{
  const std::string in = write_mesh_file("msg_sphere.off", lapmesh::icosphere(1));
  const std::string out = tmp("msg_never.ply");
  // --quantity: four names, none empty.
  Cli_result r = run_lapmesh("curvature " + in + " -o " + out + " --quantity bogus");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(count_lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find("bogus not in {mean,gaussian,k1,k2}"), std::string::npos) << r.err;
  // --colormap: the names of lapmesh::colormap_names(), which doc/cli.md lists too.
  const std::string names = lapmesh::colormap_name_list(",");
  EXPECT_EQ(names, "jet,viridis,coolwarm,gray");
  r = run_lapmesh("curvature " + in + " -o " + out + " --colormap bogus");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(count_lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find("bogus not in {" + names + "}"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("diverging"), std::string::npos) << r.err;
  const std::string cli_doc = read_file(std::string(LAPMESH_DATA_DIR) + "/../doc/cli.md");
  EXPECT_NE(cli_doc.find("[--colormap " + lapmesh::colormap_name_list("|") + "]"), std::string::npos);
  EXPECT_EQ(cli_doc.find("diverging|"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(out));
  // Every listed name is accepted.
  for(const auto& n : lapmesh::colormap_names()) {
    r = run_lapmesh("curvature " + in + " -o " + out + " -q --colormap " + n.name);
    EXPECT_EQ(r.status, 0) << n.name << ": " << r.err;
  }
  std::remove(out.c_str());
}

TEST(CliMessages, AComponentShrunkToAPointIsAWarningAndTheRunGoesOn)
{
  // A unit sphere and one of radius 0.01 beside it: at lambda 0.01 the implicit flow shrinks the
  // small one to nearly a point at step 2, holds it there and smooths the large one on.
  const std::size_t offset = lapmesh::icosphere(3).points.size();
  const std::size_t small = lapmesh::icosphere(2).points.size();
  const std::string in = write_mesh_file("two_spheres.off", spheres({1.0, 0.01}));
  const std::string out = tmp("two_spheres_smoothed.off");
  std::filesystem::remove(out);
  const Cli_result r =
    run_lapmesh("smooth " + in + " -o " + out + " --scheme implicit --lambda 0.01 --lambda-unit absolute --iterations 6 -q");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(count_lines(r.err), 1u) << r.err;
  EXPECT_EQ(r.err, in + ": warning: the flow shrank the connected component of vertex " + std::to_string(offset) + " (" +
                     std::to_string(small) +
                     " vertices) at iteration 2 to nearly a point; it was held there for the remaining steps while "
                     "the other components went on (use --fixed-operator)\n");
  EXPECT_TRUE(std::filesystem::exists(out));
}

TEST(CliMessages, TheStudyMarksARunThatHeldAComponent)
{
  // The flow of the test above inside the study: its steps from the hold on are `held`, and
  // the summary counts the run and names the component.
  const std::string offset = std::to_string(lapmesh::icosphere(3).points.size());
  const std::string small = std::to_string(lapmesh::icosphere(2).points.size());
  const std::string in = write_mesh_file("two_spheres_study.off", spheres({1.0, 0.01}));
  const std::string out = tmp("two_spheres_study.csv");
  std::filesystem::remove(out);
  const Cli_result r = run_lapmesh("denoise-study " + in + " -o " + out +
                                   " --levels 0 --schemes implicit --laplacians cotangent --lambdas 0.01"
                                   " --lambda-unit absolute --iterations 4 --area mixed --no-progress");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string held = "held: the connected component of vertex " + offset + " (" + small + " vertices) since iteration 2";
  EXPECT_NE(r.out.find("  1 of 1 runs shrank a connected component to nearly a point and held it there (status 'held', "
                       "left out of the best), e.g. cotangent lambda 0.01: " + held + "\n"),
            std::string::npos)
    << r.out;
  const std::string csv = read_file(out);
  std::size_t held_rows = 0;
  const std::string row_end = ",held,\"" + held + "\"\n";
  for(std::size_t at = csv.find(row_end); at != std::string::npos; at = csv.find(row_end, at + 1))
    ++held_rows;
  EXPECT_EQ(held_rows, 3u) << csv;  // iterations 2, 3 and 4
  EXPECT_EQ(count_lines(csv), 1u + 5u) << csv;
}

TEST(CliMessages, ACollapseDuringSmoothingNamesTheIteration)
{
  // The cotangent flow (operator rebuilt every step) pinches the cow's thin parts; the input
  // itself is valid, so the message must say when the face collapsed.
  const std::string in = cgal_mesh("cow.off");
  const std::string out = tmp("msg_never_smoothed.off");
  const Cli_result r = run_lapmesh("smooth " + in + " -o " + out + " --scheme implicit --lambda 1e-5 --iterations 40");
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(count_lines(r.err), 1u) << r.err;
  const std::string prefix = "lapmesh: " + in + ": iteration ";
  ASSERT_EQ(r.err.rfind(prefix, 0), 0u) << r.err;
  const int iteration = std::stoi(r.err.substr(prefix.size()));
  EXPECT_GE(iteration, 2);
  EXPECT_LT(iteration, 40);
  EXPECT_NE(r.err.find(": face "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(" has zero area (the flow collapsed it"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
}
