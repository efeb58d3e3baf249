// Internal: the connectivity of a triangle mesh as flat arrays, built once per mesh.
//
// Why arrays and not halfedge circulation in the hot loops: every operator of lapmesh is a
// streaming pass over the faces (per-corner geometry) followed by a gather per vertex. The
// sparsity pattern of the Laplacians is known from the connectivity (a vertex's row is its
// one-ring plus itself), so it is built here once, already sorted and compressed, and each
// assembly only writes values into it: no triplets, no sort, no duplicate collapsing.
//
// Conventions. Face f has corners 3f, 3f+1, 3f+2 at the vertices triangles[3f + a], in the
// face's orientation. The edge opposite corner c = 3f+a runs from the vertex of corner
// next(c) to the vertex of corner prev(c); it is the halfedge of face f on that edge.
#ifndef LAPMESH_INTERNAL_TOPOLOGY_H
#define LAPMESH_INTERNAL_TOPOLOGY_H

#include <lapmesh/errors.h>
#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/parallel.h>
#include <lapmesh/internal/row_sort.h>
#include <lapmesh/internal/union_find.h>

#include <algorithm>
#include <array>
#include <iterator>
#include <utility>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace lapmesh {
namespace internal {

/// Index type of vertices, corners and matrix slots; Eigen's default StorageIndex.
using Index = int;

inline Index next_corner(Index c) { return c % 3 == 2 ? c - 2 : c + 1; }
inline Index prev_corner(Index c) { return c % 3 == 0 ? c + 2 : c - 1; }

/// A face whose doubled area is at most this fraction of its longest squared edge has
/// numerically undefined angles (its smallest angle is below ~1e-12 rad): lapmesh reports
/// it instead of letting infinite cotangents turn into NaN.
constexpr double degenerate_face_tolerance = 1e-12;

/// The range of a face's longest squared edge in which its squared lengths, dot products,
/// areas and their sums over a vertex's faces are finite normal doubles with room to spare
/// (edge lengths between 1e-145 and 1e145). Outside it a face is refused as "out of the
/// representable range" rather than computed wrong (overflow) or called degenerate
/// (underflow).
constexpr double min_squared_edge = 1e-290;
constexpr double max_squared_edge = 1e290;

/// |c| for a cross product c of two edges, without the overflow or underflow of squaring
/// its components when they are beyond 1e154 or below 1e-154.
inline double cross_norm(double x, double y, double z)
{
  const double sq = x * x + y * y + z * z;
  if(sq >= 2.2250738585072014e-308 && sq <= 1.7976931348623157e308) return std::sqrt(sq);
  const double s = std::max(std::abs(x), std::max(std::abs(y), std::abs(z)));
  if(!(s > 0) || !std::isfinite(s)) return std::sqrt(sq);  // 0, or NaN/inf: nothing to rescue
  const double a = x / s, b = y / s, c = z / s;
  return s * std::sqrt(a * a + b * b + c * c);
}

/// What is wrong with a face.
enum class Face_defect { none, zero_area, too_large, too_small };

/// True when a face with this longest squared edge and doubled area is fine: the test of
/// the hot loops; face_defect() says what is wrong with one that is not.
inline bool face_in_range(double longest_squared_edge, double doubled_area)
{
  return longest_squared_edge <= max_squared_edge && longest_squared_edge >= min_squared_edge &&
         doubled_area > degenerate_face_tolerance * longest_squared_edge;
}

/// What is wrong with the triangle (p0, p1, p2), if anything. A face too large (an edge
/// above 1e145, or an overflowing coordinate difference) or too small (every edge below
/// about 1e-145, however well shaped) is out of the representable range; a face in range
/// whose angles are numerically undefined (also one with a NaN) has zero area.
inline Face_defect face_defect(const double* p0, const double* p1, const double* p2)
{
  double longest = 0, extent = 0, e[3][3];
  for(int c = 0; c < 3; ++c) {
    e[0][c] = p1[c] - p0[c];
    e[1][c] = p2[c] - p1[c];
    e[2][c] = p0[c] - p2[c];
  }
  for(const auto& v : e) {
    longest = std::max(longest, v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for(double x : v) extent = std::max(extent, std::abs(x));
  }
  if(longest > max_squared_edge) return Face_defect::too_large;  // also +inf
  if(extent > 0 && extent * extent < min_squared_edge) return Face_defect::too_small;
  const double cx = e[0][1] * -e[2][2] - e[0][2] * -e[2][1], cy = e[0][2] * -e[2][0] - e[0][0] * -e[2][2],
               cz = e[0][0] * -e[2][1] - e[0][1] * -e[2][0];
  if(!(cross_norm(cx, cy, cz) > degenerate_face_tolerance * longest)) return Face_defect::zero_area;  // NaN too
  return longest < min_squared_edge ? Face_defect::too_small : Face_defect::none;
}

/// The message of a face that is not zero-area but out of the representable range.
inline std::string out_of_range_message(std::int64_t f, Face_defect d)
{
  return "face " + std::to_string(f) + " has coordinates out of the representable range (" +
         (d == Face_defect::too_large ? "an edge longer than 1e145" : "all edges shorter than about 1e-145") +
         "; rescale the mesh)";
}

struct Mesh_topology
{
  Index num_vertices = 0;
  Index num_faces = 0;
  Index num_edges = 0;
  Index num_boundary_edges = 0;

  /// 3 vertex indices per face, in the face's orientation.
  Working_array<Index> triangles;

  /// The corners incident to vertex v are vertex_corners[corner_begin[v] .. corner_begin[v+1]).
  Working_array<Index> corner_begin;
  Working_array<Index> vertex_corners;

  /// Symmetric sparsity pattern, diagonal included, sorted within each row. Because it is
  /// symmetric, it is at once the CSR and the CSC (Eigen column-major) structure.
  Working_array<Index> outer;  // num_vertices + 1
  Working_array<Index> inner;  // number of non-zeros
  Working_array<Index> diagonal_slot;

  /// For the slot (i, j), j != i: the corner opposite the halfedge i->j and the corner
  /// opposite the halfedge j->i (-1 where that side has no face, i.e. on the boundary).
  /// The diagonal slots hold {-1, -1}.
  Working_array<std::array<Index, 2>> slot_corners;

  std::vector<char> on_boundary;

  /// False when some edge has more than two faces, or two faces on the same side (faces
  /// that disagree in orientation). The slots of such an edge hold the first face of each
  /// side; `fan_corners` holds all of them. Only the intrinsic Delaunay Laplacian, through the
  /// tufted cover, takes such a mesh (require_manifold()).
  bool manifold = true;
  /// For each non-manifold edge (i < j): its slot in row i, then the corners opposite every
  /// halfedge on it. Flattened: fan_begin[e] .. fan_begin[e+1] index fan_corners.
  std::vector<Index> fan_slot, fan_begin{0}, fan_corners;

  Index num_nonzeros() const { return static_cast<Index>(inner.size()); }
  /// Hands the corner lists back to the system (release_to_system()), for a caller that reads
  /// none of them any more.
  void release_corner_lists()
  {
    release_to_system(corner_begin);
    release_to_system(vertex_corners);
  }
  /// Hands the pattern and its corner slots back to the system, likewise.
  void release_pattern()
  {
    release_to_system(outer);
    release_to_system(inner);
    release_to_system(diagonal_slot);
    release_to_system(slot_corners);
  }
  /// False for a topology of corners only (build_corner_topology()): no pattern, no slots.
  bool has_pattern() const { return !outer.empty(); }
  Index degree(Index v) const { return outer[v + 1] - outer[v] - 1; }
};

/// Throws Mesh_error for the first face of `tri` with a vertex index out of [0, n) or a
/// repeated vertex.
inline void require_valid_faces(Index n, const Working_array<Index>& tri, bool parallel)
{
  const Index m = static_cast<Index>(tri.size() / 3);
  const auto valid = [&](Index f) {
    const Index a = tri[3 * f], b = tri[3 * f + 1], c = tri[3 * f + 2];
    return a >= 0 && b >= 0 && c >= 0 && a < n && b < n && c < n && a != b && b != c && a != c;
  };
  First_index<Index> invalid;
  for_each_index(m, parallel, [&](Index f) {
    if(!valid(f)) invalid.record(f);
  });
  if(invalid.empty()) return;
  const Index f = invalid.get(), a = tri[3 * f], b = tri[3 * f + 1], c = tri[3 * f + 2];
  if(a < 0 || b < 0 || c < 0 || a >= n || b >= n || c >= n)
    throw Mesh_error("face " + std::to_string(f) + " has a vertex index out of range [0, " + std::to_string(n) + ")",
                     Mesh_error::Element::face, f);
  throw Mesh_error("face " + std::to_string(f) + " uses the same vertex twice", Mesh_error::Element::face, f);
}

/// How many ranges of vertices sort_corners_by_vertex() splits the work into: one serially,
/// one per thread (of at least 16384 vertices) in parallel.
inline Index vertex_range_count(Index n, bool parallel)
{
  return std::max(1, std::min(thread_count(parallel), n / 16384));
}

/// From how many ranges on sort_corners_by_vertex() sorts the corners into the ranges first.
/// Reading every corner costs each range a pass over all of them; the sort costs about four
/// passes in all, shared by the threads, and the faults of an array of (vertex, corner) pairs.
constexpr Index min_ranges_sorted_into = 4;

/// Each vertex's incident corners in ascending order: those of vertex v are
/// vertex_corners[corner_begin[v] .. corner_begin[v + 1]); a vertex in no face has none.
struct Corner_incidence
{
  Working_array<Index> corner_begin;
  Working_array<Index> vertex_corners;

  bool empty() const { return corner_begin.empty(); }
  /// The first vertex with no corner, or -1.
  Index first_vertex_in_no_face(bool parallel) const
  {
    First_index<Index> in_no_face;
    const Index n = Index(corner_begin.size()) - 1;
    for_each_index(n, parallel, [&](Index v) {
      if(corner_begin[v + 1] == corner_begin[v]) in_no_face.record(v);
    }, Index(16384));
    return in_no_face.empty() ? -1 : in_no_face.get();
  }
};

/// Turns the corner counts of vertices first .. last - 1 at cursor[v] into the starts of their
/// lists, the first one at `start`.
inline void counts_to_cursors(Index* cursor, Index first, Index last, std::size_t start)
{
  for(Index v = first; v < last; ++v) {
    const Index count = cursor[v];
    cursor[v] = Index(start);
    start += std::size_t(count);
  }
}

/// Each vertex's corners in ascending order, serially: vertex v's are
/// vertex_corners[begin[v] .. begin[v + 1]), where `begin` holds n + 1 entries and
/// `vertex_corners` one per corner; vertex_of(c) is corner c's vertex, in 0..n-1. A counting
/// sort: each vertex's count is kept at begin[v + 1] and turned, by an exclusive prefix sum in
/// place, into the cursor of its list, which ends as its end.
template <typename VertexOf>
void counting_sort_corners(Index n, std::size_t corners, const VertexOf& vertex_of, Index* begin, Index* vertex_corners)
{
  Index* const cursor = begin + 1;
  begin[0] = 0;
  std::fill(cursor, cursor + n, Index(0));
  for(std::size_t c = 0; c < corners; ++c) ++cursor[vertex_of(c)];
  counts_to_cursors(cursor, 0, n, 0);
  for(std::size_t c = 0; c < corners; ++c) vertex_corners[std::size_t(cursor[vertex_of(c)]++)] = Index(c);
}

/// Each vertex's incident corners, after checking the faces (require_valid_faces()): serially
/// counting_sort_corners().
///
/// In parallel each thread counts, sums and fills the lists of one range of vertices, and the
/// ranges' corners start where the ranges before them end. A range finds its corners by
/// reading all of them, or, from min_ranges_sorted_into ranges on, from its share of an array
/// of (vertex, corner) pairs sorted into the ranges beforehand: each thread counts the corners
/// of a chunk of the faces per range and, after a prefix sum over (range, chunk), scatters the
/// chunk's pairs, so that each range's pairs are in ascending corner order.
inline Corner_incidence sort_corners_by_vertex(Index n, const Working_array<Index>& tri, bool parallel)
{
  Corner_incidence out;
  const std::size_t corners = tri.size(), faces = corners / 3;
  const Index ranges = vertex_range_count(n, parallel);
  const bool sorted_into_ranges = ranges >= min_ranges_sorted_into;
  require_valid_faces(n, tri, parallel);
  out.corner_begin.resize(std::size_t(n) + 1);
  out.corner_begin[0] = 0;
  out.vertex_corners.resize(corners);
  Index* const cursor = out.corner_begin.data() + 1;
  if(ranges == 1) {
    counting_sort_corners(n, corners, [&tri](std::size_t c) { return tri[c]; }, out.corner_begin.data(),
                          out.vertex_corners.data());
    return out;
  }
  // range_of(v) = floor(v * scale / 2^32) is monotone and below `ranges` for v < n, and needs no
  // division; range r's first vertex is the smallest v with v * scale >= r * 2^32.
  const std::uint64_t scale = (std::uint64_t(ranges) << 32) / std::uint64_t(n);
  const auto range_of = [scale](Index v) { return std::size_t((std::uint64_t(v) * scale) >> 32); };
  const std::size_t width = std::size_t(ranges);
  std::vector<Index> range_first(width + 1, n);
  for(std::size_t r = 0; r < width; ++r)
    range_first[r] = Index(std::min<std::uint64_t>(std::uint64_t(n), ((std::uint64_t(r) << 32) + scale - 1) / scale));
  // Range r's corners are vertex_corners[range_start[r] .. range_start[r + 1]).
  std::vector<std::size_t> range_start(width + 1, 0);
  Working_array<std::array<Index, 2>> pairs;  // (vertex, corner), sorted into ranges at range_start
  if(sorted_into_ranges) {
    // As many chunks of faces as ranges; offsets[k * width + r]: where chunk k's pairs of range r
    // go. A face whose corners are in one range, as most are, moves its range's counter once.
    const auto chunk_begin = [&](Index k) { return faces * std::size_t(k) / width; };
    std::vector<std::size_t> offsets(width * width);
    for_each_part(ranges, Index(1), true, [&](Index k, Index, Index) {
      std::vector<std::size_t> histogram(width, 0);
      for(std::size_t f = chunk_begin(k), end = chunk_begin(k + 1); f < end; ++f) {
        const Index* t = tri.data() + 3 * f;
        const std::size_t r0 = range_of(t[0]), r1 = range_of(t[1]), r2 = range_of(t[2]);
        if(r0 == r1 && r1 == r2) {
          histogram[r0] += 3;
        } else {
          ++histogram[r0];
          ++histogram[r1];
          ++histogram[r2];
        }
      }
      std::copy(histogram.begin(), histogram.end(), offsets.begin() + std::ptrdiff_t(std::size_t(k) * width));
    });
    std::size_t total = 0;
    for(std::size_t r = 0; r < width; ++r) {
      range_start[r] = total;
      for(std::size_t k = 0; k < width; ++k) {
        const std::size_t count = offsets[k * width + r];
        offsets[k * width + r] = total;
        total += count;
      }
    }
    range_start[width] = total;
    pairs.resize(corners);
    for_each_part(ranges, Index(1), true, [&](Index k, Index, Index) {
      std::size_t* next = offsets.data() + std::size_t(k) * width;
      for(std::size_t f = chunk_begin(k), end = chunk_begin(k + 1); f < end; ++f) {
        const Index* t = tri.data() + 3 * f;
        const Index c = Index(3 * f);
        const std::size_t r0 = range_of(t[0]), r1 = range_of(t[1]), r2 = range_of(t[2]);
        if(r0 == r1 && r1 == r2) {
          std::array<Index, 2>* p = pairs.data() + next[r0];
          next[r0] += 3;
          p[0] = {t[0], c};
          p[1] = {t[1], c + 1};
          p[2] = {t[2], c + 2};
        } else {
          pairs[next[r0]++] = {t[0], c};
          pairs[next[r1]++] = {t[1], c + 1};
          pairs[next[r2]++] = {t[2], c + 2};
        }
      }
    });
  }
  // Calls body(v, c) for the corners c of range r's vertices v, in ascending order: from the
  // range's pairs, or by reading every corner.
  const auto for_each_corner_of_range = [&](Index r, const auto& body) {
    if(sorted_into_ranges) {
      for(std::size_t e = range_start[std::size_t(r)], end = range_start[std::size_t(r) + 1]; e < end; ++e)
        body(pairs[e][0], pairs[e][1]);
      return;
    }
    const Index first = range_first[std::size_t(r)], last = range_first[std::size_t(r) + 1];
    for(std::size_t c = 0; c < corners; ++c)
      if(tri[c] >= first && tri[c] < last) body(tri[c], Index(c));
  };
  std::vector<std::size_t> range_count(width);
  for_each_part(ranges, Index(1), true, [&](Index r, Index, Index) {
    std::fill(cursor + range_first[std::size_t(r)], cursor + range_first[std::size_t(r) + 1], Index(0));
    std::size_t count = 0;
    for_each_corner_of_range(r, [&](Index v, Index) {
      ++cursor[v];
      ++count;
    });
    range_count[std::size_t(r)] = count;
  });
  // The sorted ranges get the starts their histogram gave them; the others learn theirs here.
  for(std::size_t r = 0; r < width; ++r) range_start[r + 1] = range_start[r] + range_count[r];
  for_each_part(ranges, Index(1), true, [&](Index r, Index, Index) {
    counts_to_cursors(cursor, range_first[std::size_t(r)], range_first[std::size_t(r) + 1], range_start[std::size_t(r)]);
    for_each_corner_of_range(r, [&](Index v, Index c) { out.vertex_corners[std::size_t(cursor[v]++)] = c; });
  });
  return out;
}

/// The part of every topology that a pass over the corners needs: the triangles, checked, and
/// each vertex's incident corners (sort_corners_by_vertex()). Throws Mesh_error for an index out
/// of range, a face with a repeated vertex and a vertex in no face (the first of each, as
/// serially). `incidence`: sort_corners_by_vertex() of the same triangles when the caller has
/// it, or empty.
inline Mesh_topology build_corner_incidence(Index num_vertices, Working_array<Index> triangles, bool parallel = false,
                                            Corner_incidence incidence = {})
{
  Mesh_topology t;
  t.num_vertices = num_vertices;
  t.num_faces = static_cast<Index>(triangles.size() / 3);
  t.triangles = std::move(triangles);
  if(incidence.empty()) incidence = sort_corners_by_vertex(num_vertices, t.triangles, parallel);
  const Index v = incidence.first_vertex_in_no_face(parallel);
  if(v >= 0) throw Mesh_error("vertex " + std::to_string(v) + " is in no face", Mesh_error::Element::vertex, v);
  t.corner_begin = std::move(incidence.corner_begin);
  t.vertex_corners = std::move(incidence.vertex_corners);
  return t;
}

/// How many vertices ahead a pass over each vertex's corners prefetches their triangles.
constexpr Index corner_prefetch_distance = 3;

/// How many vertices a part of a parallel pass over the vertices takes: enough to amortise
/// the part's set-up, few enough to balance the threads' load.
constexpr Index vertices_per_part = 16384;

/// Where the row of vertex i would start in the pattern if every vertex before it were an interior
/// vertex of a manifold mesh, whose row has as many neighbours as corners, plus its diagonal: the
/// slice of the pattern that a part of a parallel build writes from its first vertex on. Exact on
/// a closed manifold mesh.
inline std::size_t interior_row_start(const Mesh_topology& t, Index i)
{
  return std::size_t(t.corner_begin[i]) + std::size_t(i);
}

/// What build_pattern_rows() counts while it writes rows, whatever they are written into: the
/// entries written, the edges (each at its lower end) and the non-manifold edges' fans.
struct Pattern_row_counts
{
  std::size_t size = 0;
  std::vector<Index> fan_slot, fan_begin{0}, fan_corners;
  Index num_edges = 0;
  Index num_boundary_edges = 0;
  bool manifold = true;
};

/// Rows of the one-ring pattern built by one part of build_topology(), with slot numbers that
/// start at zero. They are written into a slice of the topology's arrays reserved for the part
/// (write_into()), which spares the copy of joining the parts, and the rows that do not fit in
/// it into arrays of the part's own (all of them without a slice). Each row's end and diagonal
/// slot go to the topology's `outer` and `diagonal_slot`, its boundary flag to `on_boundary`.
struct Pattern_rows : Pattern_row_counts
{
  explicit Pattern_rows(Mesh_topology& t) : outer(t.outer.data()), diagonal_slot(t.diagonal_slot.data()),
                                            on_boundary(t.on_boundary.data()) {}
  Index* outer;
  Index* diagonal_slot;
  char* on_boundary;
  Index* slice_inner = nullptr;
  std::array<Index, 2>* slice_slot_corners = nullptr;
  std::size_t slice_capacity = 0;
  std::size_t in_slice = 0;  // the first in_slice entries are in the slice, the others in own_*
  Working_array<Index> own_inner;
  Working_array<std::array<Index, 2>> own_slot_corners;

  struct Entries
  {
    Index* inner;
    std::array<Index, 2>* slot_corners;
    /// Entry `slot` of the appended ones: the neighbour j and the corners opposite i->j, j->i.
    void set(Index slot, Index j, std::array<Index, 2> corners) const
    {
      inner[slot] = j;
      slot_corners[slot] = corners;
    }
  };

  /// Row i ends at the current size; its diagonal is at slot `diagonal`.
  void end_row(Index i, Index diagonal)
  {
    outer[i + 1] = static_cast<Index>(size);
    diagonal_slot[i] = diagonal;
  }
  void mark_boundary(Index i) { on_boundary[i] = 1; }
  void prefetch_corner(Index) const {}

  /// Rows go to the `count` entries at `inner` and `slot_corners` until they are full.
  void write_into(Index* inner, std::array<Index, 2>* slot_corners, std::size_t count)
  {
    slice_inner = inner;
    slice_slot_corners = slot_corners;
    slice_capacity = count;
  }

  /// True when the rows fill the slice of write_into() exactly.
  bool fill_their_slice() const { return slice_inner && in_slice == slice_capacity && size == in_slice; }

  /// Room for `count` entries in the part's own arrays.
  void reserve(std::size_t count)
  {
    own_inner.reserve(count);
    own_slot_corners.reserve(count);
  }

  /// Appends `count` consecutive entries, left unset.
  Entries append(std::size_t count)
  {
    if(size == in_slice && size + count <= slice_capacity) {
      const std::size_t at = size;
      size += count;
      in_slice = size;
      return {slice_inner + at, slice_slot_corners + at};
    }
    const std::size_t at = size - in_slice;
    size += count;
    own_inner.resize(size - in_slice);
    own_slot_corners.resize(size - in_slice);
    return {own_inner.data() + at, own_slot_corners.data() + at};
  }

  void push_back(Index vertex, std::array<Index, 2> corners)
  {
    const Entries e = append(1);
    *e.inner = vertex;
    *e.slot_corners = corners;
  }

  /// Copies the rows to `inner` and `slot_corners`.
  void copy_to(Index* inner, std::array<Index, 2>* slot_corners) const
  {
    std::copy(slice_inner, slice_inner + in_slice, inner);
    std::copy(slice_slot_corners, slice_slot_corners + in_slice, slot_corners);
    std::copy(own_inner.begin(), own_inner.end(), inner + in_slice);
    std::copy(own_slot_corners.begin(), own_slot_corners.end(), slot_corners + in_slice);
  }

  /// Frees the part's own arrays once the rows are joined.
  void release()
  {
    Working_array<Index>().swap(own_inner);
    Working_array<std::array<Index, 2>>().swap(own_slot_corners);
  }
};

/// Appends the row of vertex i to `rows` when i is an interior vertex whose edges are all
/// manifold (each neighbour is reached once by an outgoing and once by an incoming halfedge of
/// its d <= Width corners) and returns true; otherwise returns false with `rows` unchanged.
/// The same row as the general path of build_pattern_rows(), without its sort: each
/// neighbour's place is the number of smaller ones, counted over a fixed width with no branch.
template <int Width, typename Rows>
bool interior_pattern_row(const Index* tri, const Index* corners, Index d, Index i, Rows& rows)
{
  static_assert(Width < 32, "a set of corners is a 32-bit mask");
  constexpr Index none = std::numeric_limits<Index>::max();  // above every vertex: counts as no smaller one
  Index out_vertex[Width], in_vertex[Width], out_corner[Width], in_corner[Width];
  for(int a = 0; a < Width; ++a) {
    const bool real = a < d;
    const Index c = real ? corners[a] : 0;
    // Corner c at i: the halfedge i->q is opposite the corner at r (prev), r->i opposite q (next).
    out_corner[a] = prev_corner(c);
    in_corner[a] = next_corner(c);
    out_vertex[a] = real ? tri[in_corner[a]] : none;
    in_vertex[a] = real ? tri[out_corner[a]] : none;
  }
  Index neighbour[Width], side0[Width], side1[Width];
  std::uint32_t placed = 0, matched = 0;
  for(int a = 0; a < d; ++a) {
    Index rank = 0;
    for(int b = 0; b < Width; ++b) rank += out_vertex[b] < out_vertex[a];
    placed |= std::uint32_t(1) << rank;
    neighbour[rank] = out_vertex[a];
    side0[rank] = out_corner[a];
  }
  const std::uint32_t all = (std::uint32_t(1) << d) - 1;
  if(placed != all) return false;  // two outgoing halfedges to one neighbour
  for(int a = 0; a < d; ++a) {
    Index rank = 0;
    for(int b = 0; b < Width; ++b) rank += out_vertex[b] < in_vertex[a];
    if(rank >= d || neighbour[rank] != in_vertex[a]) return false;  // a boundary edge
    matched |= std::uint32_t(1) << rank;
    side1[rank] = in_corner[a];
  }
  if(matched != all) return false;  // two incoming halfedges from one neighbour
  Index below = 0;
  for(int a = 0; a < Width; ++a) below += out_vertex[a] < i;
  const std::size_t at = rows.size;
  const auto entries = rows.append(std::size_t(d) + 1);
  for(Index k = 0; k < d; ++k) entries.set(k + (k >= below), neighbour[k], {side0[k], side1[k]});
  entries.set(below, i, {-1, -1});
  rows.num_edges += d - below;
  rows.end_row(i, static_cast<Index>(at) + below);
  return true;
}

/// Builds rows [first, last) of t's pattern into `rows` (Pattern_rows, or another writer with
/// its members): each row's entries with the corners opposite each of its edges' halfedges,
/// then its end and diagonal slot, relative to the part's first slot (end_row()), and whether
/// i is on the boundary (mark_boundary()).
template <typename Rows>
void build_pattern_rows(const Mesh_topology& t, Index first, Index last, Rows& rows)
{
  const Working_array<Index>& tri = t.triangles;
  // Each incident corner of i contributes two halfedges: i->q (its face's halfedge leaving
  // i, opposite the corner at r) and r->i (opposite q). They are packed as
  // (neighbour << 33 | side << 32 | corner) so that sorting them as integers orders them by
  // neighbour, then side.
  std::vector<std::uint64_t> ring;
  for(Index i = first; i < last; ++i) {
    if(i + corner_prefetch_distance < last)
      for(Index k = t.corner_begin[i + corner_prefetch_distance]; k < t.corner_begin[i + corner_prefetch_distance + 1]; ++k) {
        prefetch(&tri[t.vertex_corners[k]]);
        rows.prefetch_corner(t.vertex_corners[k]);
      }
    const Index degree = t.corner_begin[i + 1] - t.corner_begin[i];
    const Index* corners = &t.vertex_corners[t.corner_begin[i]];
    if(degree <= 8 ? interior_pattern_row<8>(tri.data(), corners, degree, i, rows)
                   : degree <= 16 && interior_pattern_row<16>(tri.data(), corners, degree, i, rows))
      continue;
    // A boundary vertex, a non-manifold edge or more than 16 corners: sort the halfedges.
    ring.clear();
    for(Index k = t.corner_begin[i]; k < t.corner_begin[i + 1]; ++k) {
      const Index c = t.vertex_corners[k];
      const Index cq = next_corner(c), cr = prev_corner(c);
      ring.push_back(std::uint64_t(tri[cq]) << 33 | std::uint64_t(cr));
      ring.push_back(std::uint64_t(tri[cr]) << 33 | std::uint64_t(1) << 32 | std::uint64_t(cq));
    }
    sort_row(ring.data(), ring.size());
    Index diagonal = -1;
    auto emit_diagonal = [&] {
      diagonal = static_cast<Index>(rows.size);
      rows.push_back(i, {-1, -1});
    };
    for(std::size_t k = 0; k < ring.size();) {
      const Index j = static_cast<Index>(ring[k] >> 33);
      if(diagonal < 0 && j > i) emit_diagonal();
      std::array<Index, 2> corners = {-1, -1};
      const std::size_t first_key = k;
      bool fan = false;
      for(; k < ring.size() && static_cast<Index>(ring[k] >> 33) == j; ++k) {
        const Index corner = static_cast<Index>(ring[k] & 0xffffffffu);
        Index& slot = corners[(ring[k] >> 32) & 1u];
        if(slot != -1)
          fan = true;
        else
          slot = corner;
      }
      if(fan) {
        rows.manifold = false;
        if(j > i) {
          rows.fan_slot.push_back(static_cast<Index>(rows.size));
          for(std::size_t r = first_key; r < k; ++r)
            rows.fan_corners.push_back(static_cast<Index>(ring[r] & 0xffffffffu));
          rows.fan_begin.push_back(static_cast<Index>(rows.fan_corners.size()));
        }
      }
      if(corners[0] == -1 || corners[1] == -1) {
        rows.mark_boundary(i);
        if(j > i) ++rows.num_boundary_edges;
      }
      if(j > i) ++rows.num_edges;
      rows.push_back(j, corners);
    }
    if(diagonal < 0) emit_diagonal();
    rows.end_row(i, diagonal);
  }
}

/// Builds the topology from a triangle list over vertices 0..n-1.
/// Throws Mesh_error for an index out of range, a face with a repeated vertex and a vertex
/// in no face. An edge with two faces on the same side (three or more faces around an edge,
/// or two neighbouring faces with opposite orientations) makes the topology non-manifold
/// (`manifold` false, the edge in `fan_slot`). In parallel (TBB) the rows are built in parts
/// and joined in order: the result equals the serial one.
inline Mesh_topology build_topology(Index num_vertices, Working_array<Index> triangles, bool parallel = false,
                                   Corner_incidence incidence = {})
{
  Mesh_topology t = build_corner_incidence(num_vertices, std::move(triangles), parallel, std::move(incidence));
  const Index n = num_vertices;
  t.outer.resize(n + 1);
  t.outer[0] = 0;
  t.diagonal_slot.resize(n);
  t.on_boundary.assign(n, 0);
  // One thread (TBB limited to one, say) gains nothing from parts: a single part takes all rows.
  const bool in_parts = thread_count(parallel) > 1;
  const Index rows_per_part = in_parts ? vertices_per_part : std::max<Index>(n, 1);
  std::vector<Pattern_rows> parts(in_parts ? std::size_t(part_count(n, rows_per_part)) : 1, Pattern_rows(t));
  if(in_parts) {
    // Each part writes straight into its slice of the pattern (interior_row_start()). A part
    // with a boundary or non-manifold vertex overflows its slice, or leaves it short, and is
    // copied into place afterwards.
    const std::size_t interior_slots = interior_row_start(t, n);
    t.inner.resize(interior_slots);
    t.slot_corners.resize(interior_slots);
    for_each_part(n, rows_per_part, true, [&](Index p, Index first, Index last) {
      const std::size_t base = interior_row_start(t, first);
      const std::size_t count = interior_row_start(t, last) - base;
      Pattern_rows& part = parts[std::size_t(p)];
      part.write_into(t.inner.data() + base, t.slot_corners.data() + base, count);
      build_pattern_rows(t, first, last, part);
    });
  } else {
    parts[0].reserve(7 * std::size_t(n));
    build_pattern_rows(t, 0, n, parts[0]);
  }
  // Join the parts: slot numbers and fans move by what the parts before them hold.
  std::vector<Index> slot_base(parts.size() + 1, 0);
  bool all_in_place = true;
  for(std::size_t p = 0; p < parts.size(); ++p) {
    const Pattern_rows& part = parts[p];
    slot_base[p + 1] = slot_base[p] + static_cast<Index>(part.size);
    all_in_place = all_in_place && part.fill_their_slice();
    t.num_edges += part.num_edges;
    t.num_boundary_edges += part.num_boundary_edges;
    t.manifold = t.manifold && part.manifold;
    for(Index s : part.fan_slot) t.fan_slot.push_back(s + slot_base[p]);
    const Index fan_base = static_cast<Index>(t.fan_corners.size());
    for(std::size_t e = 1; e < part.fan_begin.size(); ++e) t.fan_begin.push_back(part.fan_begin[e] + fan_base);
    t.fan_corners.insert(t.fan_corners.end(), part.fan_corners.begin(), part.fan_corners.end());
  }
  // Each part numbered its rows' slots from its own first one.
  for_each_part(n, rows_per_part, parts.size() > 1, [&](Index p, Index first, Index last) {
    const Index base = slot_base[std::size_t(p)];
    for(Index i = first; i < last && base > 0; ++i) {
      t.outer[i + 1] += base;
      t.diagonal_slot[i] += base;
    }
  });
  if(all_in_place) return t;
  if(parts.size() == 1 && parts[0].in_slice == 0) {  // all rows in the part's own arrays
    t.inner = std::move(parts[0].own_inner);
    t.slot_corners = std::move(parts[0].own_slot_corners);
    return t;
  }
  Working_array<Index> inner(std::size_t(slot_base.back()));
  Working_array<std::array<Index, 2>> slot_corners(std::size_t(slot_base.back()));
  for_each_part(n, rows_per_part, true, [&](Index p, Index, Index) {
    Pattern_rows& part = parts[std::size_t(p)];
    part.copy_to(inner.data() + slot_base[std::size_t(p)], slot_corners.data() + slot_base[std::size_t(p)]);
    part.release();
  });
  t.inner = std::move(inner);
  t.slot_corners = std::move(slot_corners);
  return t;
}

/// The edge counts around one vertex i of at most Width corners, from the far ends of its
/// outgoing and incoming halfedges (`out`, `in`, d of each), by comparing every pair rather than
/// sorting: where a vertex's neighbours come in no particular order, a sort mispredicts a
/// branch at nearly every step. Padding takes distinct negative values, which match nothing.
/// Returns false when a neighbour repeats in either list (two faces on one side of an edge).
template <int Width>
bool corner_ring_counts(const Index* out, const Index* in, Index d, Index i, Index& out_above, Index& in_above,
                        Index& shared, Index& shared_above)
{
  Index o[Width], n[Width];
  for(int a = 0; a < Width; ++a) {
    o[a] = a < d ? out[a] : -1 - a;
    n[a] = a < d ? in[a] : -1 - Width - a;
  }
  Index repeats = 0;
  out_above = in_above = shared = shared_above = 0;
  for(int a = 0; a < Width; ++a) {
    Index matches = 0;
    for(int b = 0; b < Width; ++b) {
      repeats += (b > a) & ((o[a] == o[b]) | (n[a] == n[b]));
      matches += n[a] == o[b];
    }
    shared += matches;
    shared_above += matches & Index(n[a] > i);
    out_above += o[a] > i;
    in_above += n[a] > i;
  }
  return repeats == 0;
}

/// The topology that per-corner passes and their gathers need (angles, areas, Gaussian
/// curvature, the cotangent sums of the mean curvature): build_corner_incidence(), the boundary
/// vertices and the edge counts, without the sparsity pattern and its slots (has_pattern()
/// false), which cost most of build_topology(). Every field it fills equals build_topology()'s.
/// A non-manifold mesh gets the full topology, whose edge fans name the edge in
/// require_manifold()'s message.
inline Mesh_topology build_corner_topology(Index num_vertices, Working_array<Index> triangles, bool parallel = false,
                                          Corner_incidence incidence = {})
{
  Mesh_topology t = build_corner_incidence(num_vertices, std::move(triangles), parallel, std::move(incidence));
  const Index n = num_vertices;
  const Working_array<Index>& tri = t.triangles;
  t.on_boundary.assign(n, 0);
  // Around vertex i each corner gives a halfedge i->q (out) and one r->i (in). An edge is on
  // the boundary when only one of its halfedges exists; a halfedge seen twice (two faces on one
  // side of an edge) is what build_topology calls non-manifold. Each vertex sorts its few out-
  // and in-neighbours and intersects the two lists, so the parts share no state and are as many
  // and as small as build_topology()'s; their counts are summed in order. Each edge i-j is
  // counted at its lower end i, once whether it has one halfedge or two.
  struct Counts
  {
    Index edges = 0, boundary_edges = 0;
    bool manifold = true;
  };
  std::vector<Counts> parts(std::size_t(part_count(n, vertices_per_part)));
  for_each_part(n, vertices_per_part, parallel, [&](Index p, Index first, Index last) {
    Counts counts;  // written to parts[p] at the end: neighbouring parts share cache lines
    std::vector<Index> out, in, shared;
    for(Index i = first; i < last; ++i) {
      if(i + corner_prefetch_distance < last)
        for(Index k = t.corner_begin[i + corner_prefetch_distance]; k < t.corner_begin[i + corner_prefetch_distance + 1]; ++k)
          prefetch(&tri[t.vertex_corners[k]]);
      const Index begin = t.corner_begin[i], end = t.corner_begin[i + 1];
      out.resize(std::size_t(end - begin));
      in.resize(std::size_t(end - begin));
      for(Index k = begin; k < end; ++k) {
        out[std::size_t(k - begin)] = tri[next_corner(t.vertex_corners[k])];
        in[std::size_t(k - begin)] = tri[prev_corner(t.vertex_corners[k])];
      }
      if(end - begin <= 8) {
        Index out_above, in_above, shared_count, shared_above;
        if(!corner_ring_counts<8>(out.data(), in.data(), end - begin, i, out_above, in_above, shared_count, shared_above)) {
          counts.manifold = false;
          break;
        }
        if(shared_count != end - begin) t.on_boundary[i] = 1;
        counts.edges += out_above + in_above - shared_above;
        counts.boundary_edges += out_above + in_above - 2 * shared_above;
        continue;
      }
      std::sort(out.begin(), out.end());
      std::sort(in.begin(), in.end());
      if(std::adjacent_find(out.begin(), out.end()) != out.end() || std::adjacent_find(in.begin(), in.end()) != in.end()) {
        counts.manifold = false;
        break;
      }
      shared.clear();
      std::set_intersection(out.begin(), out.end(), in.begin(), in.end(), std::back_inserter(shared));
      const auto above_i = [i](const std::vector<Index>& sorted) {
        return Index(sorted.end() - std::upper_bound(sorted.begin(), sorted.end(), i));
      };
      const Index out_above = above_i(out), in_above = above_i(in), shared_above = above_i(shared);
      if(Index(shared.size()) != end - begin) t.on_boundary[i] = 1;
      counts.edges += out_above + in_above - shared_above;
      counts.boundary_edges += out_above + in_above - 2 * shared_above;
    }
    parts[std::size_t(p)] = counts;
  });
  for(const Counts& counts : parts) {
    if(!counts.manifold) return build_topology(n, std::move(t.triangles), parallel);
    t.num_edges += counts.edges;
    t.num_boundary_edges += counts.boundary_edges;
  }
  return t;
}

/// Throws Mesh_error naming the first non-manifold edge: the operators built on the edge
/// slots (cotangent, uniform) need at most one face on each side of an edge.
inline void require_manifold(const Mesh_topology& t, const char* operator_name)
{
  if(t.manifold) return;
  const Index slot = t.fan_slot.front();
  const Index j = t.inner[slot];
  const Index i = Index(std::upper_bound(t.outer.begin(), t.outer.end(), slot) - t.outer.begin()) - 1;
  const Index faces = t.fan_begin[1] - t.fan_begin[0], f = t.fan_corners.front() / 3;
  throw Mesh_error("edge (" + std::to_string(i) + ", " + std::to_string(j) + ") at face " + std::to_string(f) +
                     " is non-manifold (" + std::to_string(faces) +
                     " faces, or two faces with opposite orientations): the " + operator_name +
                     " Laplacian needs a manifold mesh; the intrinsic-delaunay Laplacian takes it",
                   Mesh_error::Element::face, f);
}

/// The connected component (through edges) of each vertex, by union–find over the faces,
/// numbered from 0 in the order of their first vertices; a vertex in no face is a component of
/// its own. `count`, if given, receives the number of components.
inline std::vector<Index> connected_component_labels(const Mesh_topology& t, Index* count = nullptr)
{
  Smallest_root_sets<Index> sets(t.num_vertices);
  for(Index f = 0; f < t.num_faces; ++f)
    for(int a = 1; a < 3; ++a) sets.join(t.triangles[3 * f], t.triangles[3 * f + a]);
  Index components = 0;
  std::vector<Index> label = sets.labels(components);
  if(count) *count = components;
  return label;
}

/// Number of connected components (through edges).
inline Index count_connected_components(const Mesh_topology& t)
{
  Index count = 0;
  connected_component_labels(t, &count);
  return count;
}

} // namespace internal
} // namespace lapmesh

#endif
