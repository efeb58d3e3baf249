// Real-world meshes: a corpus of defective meshes made here from CGAL's data set (needles and
// caps, collapsed edges, duplicated vertices and faces, non-manifold joins of two meshes,
// vertices in no face, faces with flipped orientation), run through every subcommand. With the
// intrinsic Delaunay Laplacian every mesh is processed with finite outputs; the cotangent
// Laplacian refuses exactly the meshes with zero-area faces or non-manifold edges, with a
// message that names the way out.
#include "test_helpers.h"

#include <lapmesh/io.h>

#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>

using namespace lapmesh_test;

namespace {

using Soup = lapmesh::io::Polygon_soup;

struct Dirty_mesh
{
  std::string name;
  Soup soup;
  bool cotangent_refuses = false;     ///< zero-area faces or non-manifold edges
  std::set<std::size_t> in_no_face;   ///< vertices whose curvature is NaN by policy (set by make_dirty)
};

// The triangles of a base mesh (polygons are left out so that every face is a triangle).
Soup triangles_of(const Soup& s)
{
  Soup out{s.points, {}};
  for(const auto& p : s.polygons)
    if(p.size() == 3) out.polygons.push_back(p);
  return out;
}

std::array<double, 3> lerp(const std::array<double, 3>& a, const std::array<double, 3>& b, double t)
{
  return {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])};
}

// Every `stride`-th face gets a defect; the rng picks corners.
std::vector<Dirty_mesh> make_dirty(const std::string& base_name, const Soup& base)
{
  std::vector<Dirty_mesh> out;
  const std::size_t m = base.polygons.size(), n = base.points.size();
  const std::size_t stride = std::max<std::size_t>(7, m / 40);
  std::mt19937_64 rng(std::hash<std::string>{}(base_name));

  {  // needles (a vertex pulled almost onto a neighbour) and caps (a vertex pulled onto the opposite side)
    Dirty_mesh d{base_name + "+needles-caps", base, false, {}};
    std::set<std::size_t> moved;
    for(std::size_t f = 0; f < m; f += stride) {
      const auto& t = d.soup.polygons[f];
      if(moved.count(t[0]) || moved.count(t[1]) || moved.count(t[2])) continue;
      moved.insert(t[0]);
      d.soup.points[t[0]] = (f / stride) % 2 ? lerp(d.soup.points[t[1]], d.soup.points[t[0]], 1e-4)
                                             : lerp(d.soup.points[t[0]], lerp(d.soup.points[t[1]], d.soup.points[t[2]], 0.5), 0.999);
    }
    out.push_back(std::move(d));
  }
  {  // collapsed edges: one end moved onto the other (zero-area faces)
    Dirty_mesh d{base_name + "+collapsed-edges", base, false, {}};
    d.cotangent_refuses = true;
    for(std::size_t f = 0; f < m; f += 2 * stride) {
      const auto& t = d.soup.polygons[f];
      d.soup.points[t[1]] = d.soup.points[t[0]];
    }
    out.push_back(std::move(d));
  }
  {  // duplicated vertices: faces re-pointed to copies (cracks), and unused copies
    Dirty_mesh d{base_name + "+duplicated-vertices", base, false, {}};
    for(std::size_t f = 0; f < m; f += stride) {
      auto& t = d.soup.polygons[f];
      d.soup.points.push_back(d.soup.points[t[0]]);
      t[0] = d.soup.points.size() - 1;
    }
    for(std::size_t k = 0; k < 5; ++k) d.soup.points.push_back(d.soup.points[rng() % n]);
    out.push_back(std::move(d));
  }
  {  // duplicated faces: the same triangle twice (non-manifold edges)
    Dirty_mesh d{base_name + "+duplicated-faces", base, false, {}};
    d.cotangent_refuses = true;
    for(std::size_t f = 0; f < m; f += stride) d.soup.polygons.push_back(d.soup.polygons[f]);
    out.push_back(std::move(d));
  }
  {  // two copies joined along one interior edge (four faces on it)
    Dirty_mesh d{base_name + "+non-manifold-join", base, false, {}};
    d.cotangent_refuses = true;
    std::map<std::pair<std::size_t, std::size_t>, int> faces_on;
    for(const auto& t : base.polygons)
      for(int k = 0; k < 3; ++k) ++faces_on[std::minmax(t[k], t[(k + 1) % 3])];
    std::size_t a = 0, b = 0;
    for(const auto& [edge, count] : faces_on)
      if(count == 2) {
        std::tie(a, b) = edge;
        break;
      }
    // The copy turned by a half turn about the edge a-b, so that it leaves the edge on the other side.
    const Eigen::Vector3d pa(base.points[a].data()), pb(base.points[b].data());
    const Eigen::AngleAxisd turn(M_PI / 2, (pb - pa).normalized());
    std::vector<std::size_t> index(n);
    for(std::size_t i = 0; i < n; ++i) {
      if(i == a || i == b) {
        index[i] = i;
        continue;
      }
      const Eigen::Vector3d q = pa + turn * (Eigen::Vector3d(base.points[i].data()) - pa);
      d.soup.points.push_back({q.x(), q.y(), q.z()});
      index[i] = d.soup.points.size() - 1;
    }
    for(const auto& t : base.polygons) d.soup.polygons.push_back({index[t[0]], index[t[1]], index[t[2]]});
    out.push_back(std::move(d));
  }
  {  // vertices in no face
    Dirty_mesh d{base_name + "+isolated-vertices", base, false, {}};
    for(std::size_t k = 0; k < 7; ++k) d.soup.points.push_back(lerp(base.points[rng() % n], base.points[rng() % n], 0.3));
    out.push_back(std::move(d));
  }
  {  // random orientation flips
    Dirty_mesh d{base_name + "+flipped-faces", base, false, {}};
    for(auto& t : d.soup.polygons)
      if(rng() % 4 == 0) std::swap(t[1], t[2]);
    out.push_back(std::move(d));
  }
  for(Dirty_mesh& d : out) {  // the vertices in no face (also those whose faces all moved to copies)
    std::vector<char> used(d.soup.points.size(), 0);
    for(const auto& t : d.soup.polygons)
      for(std::size_t v : t) used[v] = 1;
    d.in_no_face.clear();
    for(std::size_t v = 0; v < used.size(); ++v)
      if(!used[v]) d.in_no_face.insert(v);
  }
  return out;
}

void write_off(const std::string& path, const Soup& s)
{
  std::ofstream os(path);
  os.precision(17);
  os << "OFF\n" << s.points.size() << ' ' << s.polygons.size() << " 0\n";
  for(const auto& p : s.points) os << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
  for(const auto& t : s.polygons) os << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
}

// The numbers of a CSV or OFF file, by line (header words skipped).
std::vector<std::vector<double>> numbers_by_line(const std::string& text)
{
  std::vector<std::vector<double>> lines;
  std::istringstream in(text);
  std::string line;
  while(std::getline(in, line)) {
    for(char& c : line)
      if(c == ',') c = ' ';
    std::istringstream words(line);
    std::vector<double> values;
    std::string w;
    while(words >> w) {
      if(w == "nan" || w == "-nan") {
        values.push_back(std::nan(""));
        continue;
      }
      char* end = nullptr;
      const double x = std::strtod(w.c_str(), &end);
      if(end && *end == '\0') values.push_back(x);
    }
    lines.push_back(values);
  }
  return lines;
}

const std::vector<std::string> base_meshes = {"sphere.off", "joint.off", "anchor.off", "nefertiti.off",
                                              "eight.off", "pipe.off", "blob.off", "mushroom.off", "cow.off"};

} // namespace

TEST(DirtyMeshes, EverySubcommandProcessesTheCorpusWithTheIntrinsicLaplacian)
{
  std::vector<Dirty_mesh> corpus;
  for(const std::string& name : base_meshes) {
    const Soup base = triangles_of(lapmesh::io::read_polygon_soup(cgal_mesh(name)));
    ASSERT_GT(base.polygons.size(), 50u) << name;
    for(auto& d : make_dirty(name, base)) corpus.push_back(std::move(d));
  }
  ASSERT_GE(corpus.size(), 50u);
  const std::string dir = scratch_dir();
  std::size_t processed = 0, refused_as_expected = 0;
  run_test_cases(corpus, [](const Dirty_mesh& d) { return d.name; }, [&](const Dirty_mesh& d) {
    const std::string in = dir + "/dirty.off";
    write_off(in, d.soup);
    const std::string L = " --laplacian intrinsic-delaunay";
    const std::vector<std::pair<std::string, std::string>> runs = {
      {"curvature " + in + " -o " + dir + "/curv.csv" + L, dir + "/curv.csv"},
      {"spectrum " + in + " -o " + dir + "/spec.csv -k 10" + L, dir + "/spec.csv"},
      {"reconstruct " + in + " -o " + dir + "/rec.off -k 10" + L, dir + "/rec.off"},
      {"smooth " + in + " -o " + dir + "/exp.off --scheme explicit --lambda auto --iterations 3" + L, dir + "/exp.off"},
      {"smooth " + in + " -o " + dir + "/imp.off --scheme implicit --lambda 1 --lambda-unit edge2 --iterations 3" + L,
       dir + "/imp.off"},
      {"denoise-study " + in + " -o " + dir + "/study.csv --levels 0.05 --schemes implicit --laplacians "
                                              "intrinsic-delaunay --lambdas 1 --iterations 2 -q",
       dir + "/study.csv"},
    };
    bool all = true;
    for(const auto& [args, output] : runs) {
      std::filesystem::remove(output);
      const Cli_result r = run_lapmesh(args);
      EXPECT_EQ(r.status, 0) << args << "\n" << r.err;
      all = all && r.status == 0;
      const std::string text = read_file(output);
      EXPECT_FALSE(text.empty()) << args;
      if(args.rfind("denoise-study", 0) == 0) {  // every run ok, its distances finite
        EXPECT_EQ(text.find(",failed,"), std::string::npos) << text;
        EXPECT_EQ(text.find(",diverged,"), std::string::npos) << text;
        std::istringstream rows(text);
        std::string row;
        std::getline(rows, row);  // header: ...,iteration,rms_distance,hausdorff_distance,normal_angle_error_deg,...
        while(std::getline(rows, row)) {
          std::vector<std::string> cells;
          std::istringstream cut(row);
          for(std::string cell; std::getline(cut, cell, ',');) cells.push_back(cell);
          ASSERT_GE(cells.size(), 11u) << row;
          for(int c : {8, 9, 10}) EXPECT_TRUE(std::isfinite(std::strtod(cells[c].c_str(), nullptr))) << row;
        }
        continue;
      }
      const auto lines = numbers_by_line(text);
      // Curvature rows are "vertex,H,K,..." after a header: NaN only for vertices in no face.
      const bool curvature = args.rfind("curvature", 0) == 0;
      for(std::size_t l = 0; l < lines.size(); ++l)
        for(double x : lines[l]) {
          if(curvature && std::isnan(x) && !lines[l].empty() && d.in_no_face.count(std::size_t(lines[l][0]))) continue;
          if(!std::isfinite(x)) {
            ADD_FAILURE() << args << ": line " << l + 1 << " has " << x;
            break;
          }
        }
    }
    processed += all;
    const Cli_result cot = run_lapmesh("curvature " + in + " -o " + dir + "/cot.csv --laplacian cotangent");
    if(d.cotangent_refuses) {
      EXPECT_NE(cot.status, 0);
      EXPECT_NE(cot.err.find("dirty.off"), std::string::npos) << cot.err;
      EXPECT_NE(cot.err.find("intrinsic-delaunay"), std::string::npos) << cot.err;
      std::istringstream lines(cot.err);
      std::string line;
      int error_lines = 0;
      while(std::getline(lines, line)) error_lines += line.find(": note: ") == std::string::npos;
      EXPECT_EQ(error_lines, 1) << cot.err;  // one line besides the reader's notes
      refused_as_expected += cot.status != 0;
    } else {
      EXPECT_EQ(cot.status, 0) << cot.err;
    }
  });
  std::cout << "processed " << processed << " of " << corpus.size() << " defective meshes with every subcommand; "
            << refused_as_expected << " refused by the cotangent Laplacian as expected\n";
  EXPECT_EQ(processed, corpus.size());
}
