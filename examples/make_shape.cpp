// Writes one of lapmesh's generated shapes (include/lapmesh/shapes.h) as a mesh file, so that
// scripts and the command line can use them like any other mesh.
// Usage: make_shape bumpy-box OUT [SEED]        rounded box with six cylindrical bumps (~1.2k vertices)
//        make_shape bumpy-sphere OUT [LEVEL]    icosphere with radial bumps (level 4: 2562 vertices)
//        make_shape icosphere OUT [LEVEL]
// OUT: .off, .obj, .ply or .stl. The same arguments give the same file on every platform.
#include <lapmesh/io.h>
#include <lapmesh/shapes.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <iostream>
#include <string>

using Mesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;

int main(int argc, char** argv)
{
  if(argc < 3 || argc > 4) {
    std::cerr << "usage: make_shape bumpy-box|bumpy-sphere|icosphere OUT [SEED|LEVEL]\n";
    return 2;
  }
  const std::string shape = argv[1], out = argv[2];
  try {
    long parameter = -1;
    if(argc == 4) {
      std::size_t used = 0;
      parameter = std::stol(argv[3], &used);
      if(used != std::string(argv[3]).size() || parameter < 0) throw std::invalid_argument("bad number");
    }
    lapmesh::Triangle_soup soup;
    if(shape == "bumpy-box") soup = lapmesh::bumpy_box(parameter < 0 ? 1 : std::uint64_t(parameter));
    else if(shape == "bumpy-sphere" || shape == "icosphere") {
      const int level = parameter < 0 ? 4 : int(parameter);
      if(level > 7) throw std::invalid_argument("level above 7");
      soup = shape == "icosphere" ? lapmesh::icosphere(level) : lapmesh::bumpy_sphere(level);
    } else {
      std::cerr << "make_shape: unknown shape '" << shape << "' (bumpy-box, bumpy-sphere, icosphere)\n";
      return 2;
    }
    Mesh mesh;
    if(!lapmesh::make_mesh(soup, mesh)) throw std::runtime_error("the generated soup is not a manifold");
    const auto [P, tris] = lapmesh::io::mesh_arrays(mesh);
    lapmesh::io::write_mesh(out, P, tris);
  } catch(const std::exception& e) {
    std::cerr << "make_shape " << shape << ' ' << out << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
