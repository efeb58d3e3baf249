#include "cli_common.h"

#include <lapmesh/io.h>

#include <filesystem>
#include <iostream>
#include <memory>

namespace lapmesh_cli {

Mesh load_mesh(const std::string& path)
{
  Mesh mesh;
  try {
    const lapmesh::io::Soup_report report = lapmesh::io::read_triangle_mesh(path, mesh);
    if(report.triangulated_polygons > 0)
      std::cerr << path << ": note: triangulated " << report.triangulated_polygons << " polygon(s)\n";
    if(report.flipped_faces > 0)
      std::cerr << path << ": note: re-oriented " << report.flipped_faces << " face(s) consistently\n";
  } catch(const std::exception& e) {
    throw Failure(path + ": " + e.what());
  }
  return mesh;
}

void check_output_path(const std::string& out, std::initializer_list<const char*> allowed)
{
  const std::string ext = lapmesh::io::extension_of(out);
  std::string list;
  for(const char* a : allowed) {
    if(ext == a) return;
    list += std::string(list.empty() ? "." : ", .") + a;
  }
  throw Failure(out + ": unsupported output format '." + ext + "' (expected " + list + ")");
}

void check_output_target(const std::string& input, const std::string& output, bool force)
{
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(output, ec);
  if(ec || !fs::exists(st)) return;  // a new file
  if(fs::equivalent(input, output, ec) && !ec && !force)
    throw Failure(output + ": is the input file " + input +
                  " (also through a link); refusing to overwrite the input (use --force to overwrite it)");
  if(fs::is_directory(st)) return;  // write_atomically() says "it is a directory"
  if(!fs::is_regular_file(st)) throw Failure(output + ": exists and is not a regular file; refusing to replace it");
  const auto writable = fs::perms::owner_write | fs::perms::group_write | fs::perms::others_write;
  if((st.permissions() & writable) == fs::perms::none && !force)
    throw Failure(output + ": the file is read-only; refusing to replace it (use --force to replace it)");
}

void add_input_output(CLI::App& cmd, std::string& input, std::string& output, const std::string& output_help)
{
  cmd.add_option("IN", input, "input mesh (.off, .obj, .ply, .stl)")->required();
  cmd.add_option("-o,--output", output, output_help)->required();
  // Checked once the subcommand's options are parsed, before it reads anything.
  auto force = std::make_shared<bool>(false);
  cmd.add_flag("--force", *force,
               "replace OUT even when it is the input file (same file, also through links) or read-only");
  cmd.parse_complete_callback([&input, &output, force] { check_output_target(input, output, *force); });
}

void add_laplacian_option(CLI::App& cmd, std::string& value)
{
  cmd.add_option("--laplacian", value, "Laplacian: cotangent (Laplace-Beltrami) or uniform (graph)")
    ->check(CLI::IsMember({"uniform", "cotangent"}))
    ->capture_default_str();
}

void add_area_option(CLI::App& cmd, std::string& value)
{
  cmd.add_option("--area", value, "vertex area (mass): barycentric, voronoi or mixed")
    ->check(CLI::IsMember({"barycentric", "voronoi", "mixed"}))
    ->capture_default_str();
}

lapmesh::Laplacian laplacian_from(const std::string& value) { return *lapmesh::parse_laplacian(value); }
lapmesh::Vertex_area area_from(const std::string& value) { return *lapmesh::parse_vertex_area(value); }

namespace {
// The option's text as given, bounded (it goes into a one-line message).
std::string quoted_excerpt(const std::string& text)
{
  return "'" + (text.size() <= 40 ? text : text.substr(0, 40) + "...") + "'";
}
} // namespace

long long parse_count_option(const std::string& input, const std::string& option, const std::string& text,
                             long long lo, long long hi, const std::string& range_note)
{
  const std::string expected = "expected " + std::to_string(lo) + " <= " + option.substr(option.find_first_not_of('-')) +
                               " <= " + std::to_string(hi) + range_note;
  // Digits only, read without a width limit: a number past 2^64 is out of range, never wrapped.
  const bool negative = !text.empty() && text[0] == '-';
  const std::string digits = negative ? text.substr(1) : text;
  if(digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos)
    throw Failure(input + ": " + option + " " + quoted_excerpt(text) + " is not an integer (" + expected + ")");
  const std::size_t first = std::min(digits.find_first_not_of('0'), digits.size());
  const std::string significant = digits.substr(first);
  const bool fits = significant.size() < 19;  // below 10^18 < 2^63
  const long long magnitude = fits ? (significant.empty() ? 0 : std::stoll(significant)) : 0;
  const long long value = negative ? -magnitude : magnitude;
  if(!fits || value < lo || value > hi)
    throw Failure(input + ": " + option + " " + quoted_excerpt(text) + " is out of range (" + expected + ")");
  return value;
}

} // namespace lapmesh_cli
