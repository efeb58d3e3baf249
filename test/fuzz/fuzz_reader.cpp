// libFuzzer target of one mesh reader: the bytes go through the same in-memory parser and
// soup validation as `lapmesh` (io::internal::parse_mesh, then io::soup_to_triangles).
// A clean Io_error or Mesh_error is the expected end of bad input; anything else (another
// exception, a crash, a sanitizer report, a huge allocation, a hang) is a finding.
// LAPMESH_FUZZ_FORMAT ("off", "obj", "ply" or "stl") picks the reader at compile time.
#include <lapmesh/internal/io_soup.h>

#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    const lapmesh::io::Polygon_soup soup = lapmesh::io::internal::parse_mesh(bytes, LAPMESH_FUZZ_FORMAT);
    lapmesh::io::Soup_report report;
    const auto triangles = lapmesh::io::soup_to_triangles(soup, &report);
    // Every triangle refers to a point: what triangles_to_mesh() relies on.
    for(const auto& t : triangles)
      for(std::size_t v : t)
        if(v >= soup.points.size()) __builtin_trap();
  } catch(const lapmesh::Io_error&) {
  } catch(const lapmesh::Mesh_error&) {
  }
  return 0;
}
