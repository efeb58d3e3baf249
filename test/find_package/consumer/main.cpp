// A downstream project: installed headers, find_package(lapmesh), a curvature on a sphere.
#include <lapmesh/curvature.h>
#include <lapmesh/shapes.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>
#include <iostream>

int main()
{
  CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3> mesh;
  lapmesh::make_mesh(lapmesh::icosphere(3, 2.0), mesh);
  const auto c = lapmesh::vertex_curvatures(mesh, lapmesh::parameters::vertex_area(lapmesh::Vertex_area::mixed));
  const double mean_H = c.mean.mean();
  std::cout << "mean curvature of a radius-2 sphere: " << mean_H << '\n';
  return std::abs(mean_H - 0.5) < 0.01 ? 0 : 1;
}
