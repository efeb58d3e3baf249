// The operations layer: one function per user-level operation, shared by every front end
// (the `lapmesh` command line, the viewer's HTTP server and, next, the Python module).
//
// A front end parses its own syntax into the plain settings below, calls one function and
// presents the result. Everything between is here: the time step resolved from its unit,
// the limits applied, the named-parameter chains built, the warnings worded. Settings errors
// are lapmesh::Parameter_error naming the settings field (its parameter()), so that each front
// end can point at its own spelling of it (spelling() of the front end); library and I/O
// errors pass through unchanged, without a file name (the front end knows which file).
//
// The mesh is a CGAL Surface_mesh over doubles, vertex i being the i-th vertex of the input.
#ifndef LAPMESH_SRC_OPERATIONS_OPERATIONS_H
#define LAPMESH_SRC_OPERATIONS_OPERATIONS_H

#include <lapmesh/colormap.h>
#include <lapmesh/errors.h>
#include <lapmesh/types.h>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <array>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <limits>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace lapmesh {
class Spectral_basis;
}

namespace lapmesh_ops {

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
using Triangles = std::vector<std::array<std::size_t, 3>>;

/// A change of a setting that would remove a warning or an error: set `parameter` (a
/// settings field) to `value`. Front ends spell it in their own syntax.
struct Suggestion
{
  std::string parameter;
  std::string value;
};

/// Something the user should know about a result that is still returned.
struct Warning
{
  std::string message;                  ///< one line, no front end's spelling
  std::vector<Suggestion> suggestions;  ///< ways out, possibly none
};

// ---- meshes -----------------------------------------------------------------------------

/// A mesh read from a file, with the notes of the repairs the reader made.
struct Loaded_mesh
{
  Mesh mesh;
  std::vector<std::string> notes;  ///< "triangulated N polygon(s)", "re-oriented N face(s) consistently"
};

/// Reads and validates a mesh (OFF, OBJ, PLY, STL). Real-world defects are processed and
/// noted rather than refused: zero-area faces, vertices in no face, non-manifold edges and
/// vertices, faces that disagree in orientation (io::soup_to_triangles()). A mesh that a
/// Surface_mesh cannot hold as it is gets its faces stored apart and welded back by vertex
/// number in every operation below. Throws lapmesh::Io_error, Mesh_error.
Loaded_mesh load_mesh(const std::string& path);

/// Validates a polygon soup as load_mesh() validates a file, triangulates polygons and
/// orients the faces consistently where possible: for meshes that come as arrays (the
/// Python module). Throws lapmesh::Mesh_error.
Loaded_mesh mesh_from_soup(const lapmesh::io::Polygon_soup& soup);

/// The mesh formats written by write_mesh(), by extension (lower case, no dot).
const std::vector<std::string>& mesh_output_formats();

/// Writes `mesh` to `path` (format by extension, atomically), with optional named per-vertex
/// values (PLY) and colours (PLY, OFF). Throws lapmesh::Io_error.
void write_mesh(const std::string& path, const Mesh& mesh,
                const std::vector<std::pair<std::string, std::vector<double>>>& scalars = {},
                const std::vector<lapmesh::Rgb>& colors = {});

/// Writes a text file (a table, a plot) atomically through `write`. Throws lapmesh::Io_error.
void write_text(const std::string& path, const std::function<void(std::ostream&)>& write);

/// Writes a double with 17 significant digits (it reads back exactly).
void put_double(std::ostream& os, double x);

/// The lower-case extension of a path without the dot ("off", "csv", ...).
std::string extension_of(const std::string& path);

/// The number of vertices of the input (rows of every per-vertex result).
std::size_t vertex_count(const Mesh& mesh);
/// Vertex positions, row i = vertex i.
lapmesh::Vertex_vectors positions(const Mesh& mesh);
/// Overwrites the vertex positions with the rows of `P` (as many as vertices).
void set_positions(Mesh& mesh, const lapmesh::Vertex_vectors& P);
/// The triangles as vertex indices.
Triangles triangles(const Mesh& mesh);
/// |p_i - q_i| per vertex of two meshes with the same vertices.
std::vector<double> displacement(const Mesh& from, const Mesh& to);

// ---- curvature --------------------------------------------------------------------------

struct Curvature_settings
{
  lapmesh::Laplacian laplacian = lapmesh::Laplacian::cotangent;
  lapmesh::Vertex_area area = lapmesh::Vertex_area::barycentric;
  double mollification = lapmesh::default_mollification_factor;  ///< intrinsic Delaunay only
};

/// Mean, Gaussian and principal curvatures per vertex (in parallel where TBB is available).
lapmesh::Vertex_curvatures curvature(const Mesh& mesh, const Curvature_settings& settings);

// ---- spectrum and reconstruction ----------------------------------------------------------

struct Spectral_settings
{
  long long k = 1;  ///< eigenpairs wanted, 1 <= k <= number of vertices
  lapmesh::Laplacian laplacian = lapmesh::Laplacian::cotangent;
  lapmesh::Vertex_area area = lapmesh::Vertex_area::barycentric;
  double mollification = lapmesh::default_mollification_factor;  ///< intrinsic Delaunay only
  std::function<void(const lapmesh::Spectral_progress&)> progress;  ///< optional; may throw to cancel
};

/// The k smallest eigenpairs of -S phi = lambda M phi. Throws Parameter_error("k") for k
/// outside [1, number of vertices].
std::shared_ptr<const lapmesh::Spectral_basis> spectral_basis(const Mesh& mesh, const Spectral_settings& settings);

/// Checks that `basis` can serve `mesh`: as many vertices, the same vertex masses (a basis
/// of another mesh with as many vertices is refused), and the Laplacian and area asked for
/// when given. Throws Parameter_error ("basis", or "laplacian"/"area" for a kind mismatch).
void check_basis_fits(const lapmesh::Spectral_basis& basis, const Mesh& mesh,
                      std::optional<lapmesh::Laplacian> laplacian = std::nullopt,
                      std::optional<lapmesh::Vertex_area> area = std::nullopt);

/// Eigenbases by (mesh key, geometry key, Laplacian, vertex area), least recently used first
/// out, within a byte budget. A basis of m pairs serves every k <= m on the geometry it was
/// computed from. Thread-safe.
class Basis_cache
{
public:
  explicit Basis_cache(std::size_t budget_bytes) : m_budget(budget_bytes) {}

  /// A basis of this geometry and operator (the mollification counts for intrinsic Delaunay
  /// only) with at least k pairs, or nullptr.
  std::shared_ptr<const lapmesh::Spectral_basis> find(const std::string& mesh, long long geometry,
                                                      lapmesh::Laplacian laplacian, lapmesh::Vertex_area area,
                                                      double mollification, long long k);
  /// Replaces the basis of the same key; a basis larger than the budget is not kept.
  void insert(const std::string& mesh, long long geometry, double mollification,
              std::shared_ptr<const lapmesh::Spectral_basis> basis);
  /// Drops the bases of `mesh` on geometries other than `keep_a` and `keep_b`.
  void forget(const std::string& mesh, long long keep_a, long long keep_b);

  struct Stats
  {
    std::size_t bytes = 0, budget_bytes = 0, entries = 0;
  };
  Stats stats();

  static std::size_t bytes_of(const lapmesh::Spectral_basis& basis);

private:
  struct Entry
  {
    std::string mesh;
    long long geometry;
    lapmesh::Laplacian laplacian;
    lapmesh::Vertex_area area;
    double mollification;
    std::shared_ptr<const lapmesh::Spectral_basis> basis;
    std::size_t bytes;

    bool same_operator(lapmesh::Laplacian l, lapmesh::Vertex_area a, double m) const
    {
      return laplacian == l && area == a && (l != lapmesh::Laplacian::intrinsic_delaunay || mollification == m);
    }
  };
  std::mutex m_mutex;
  std::list<Entry> m_lru;  // most recently used first
  std::size_t m_bytes = 0, m_budget;
};

struct Reconstruct_settings
{
  long long k = 1;           ///< eigenvectors used, 1 <= k <= number of vertices
  long long basis_size = 0;  ///< pairs to compute when no basis is given (at least k)
  lapmesh::Laplacian laplacian = lapmesh::Laplacian::cotangent;
  lapmesh::Vertex_area area = lapmesh::Vertex_area::barycentric;
  double mollification = lapmesh::default_mollification_factor;  ///< intrinsic Delaunay only
  std::function<void(const lapmesh::Spectral_progress&)> progress;  ///< optional; may throw to cancel
};

struct Reconstruction
{
  lapmesh::Vertex_vectors positions;                    ///< the rebuilt vertex positions
  std::shared_ptr<const lapmesh::Spectral_basis> basis;  ///< the basis used (computed or given)
  bool basis_from_cache = false;                        ///< found in the cache (reconstruct() with a cache)
  double eigenvalue_k_minus_1 = 0;                      ///< the largest eigenvalue used
  std::vector<Warning> warnings;                        ///< e.g. k splits an eigenspace
};

/// The positions rebuilt from the k smallest eigenvectors, x <- sum_{i<k} (x^T M phi_i) phi_i.
/// Uses `basis` when given (it must hold at least k pairs and fit the mesh: Parameter_error
/// otherwise), else computes max(k, basis_size) pairs.
Reconstruction reconstruct(const Mesh& mesh, const Reconstruct_settings& settings,
                           std::shared_ptr<const lapmesh::Spectral_basis> basis = nullptr);

/// Which geometry a cached basis belongs to: the front end's mesh id and a number that
/// changes whenever the positions change.
struct Basis_key
{
  std::string mesh;
  long long geometry = 0;
};

/// As above, with the basis taken from `cache` when it holds one for `key` with at least k
/// pairs (trusted: the key says it was computed from these positions), else computed and
/// inserted.
Reconstruction reconstruct(const Mesh& mesh, const Reconstruct_settings& settings, Basis_cache& cache,
                           const Basis_key& key);

// ---- smoothing --------------------------------------------------------------------------

/// A time step as a user gives it: automatic, or a value in a unit.
struct Time_step
{
  bool automatic = true;  ///< 0.9 x the stability bound (explicit), one mean edge length squared (else)
  double value = 0;       ///< in `unit`, when not automatic
  lapmesh::Time_step_unit unit = lapmesh::Time_step_unit::absolute;
};

/// Reads "auto" or a positive finite number. Throws Parameter_error("lambda").
Time_step parse_time_step(const std::string& text, lapmesh::Time_step_unit unit);

/// What a front end allows (the viewer is a shared server: it bounds the work of a request).
struct Smoothing_limits
{
  long long max_iterations = 100'000'000;
  double max_lambda = std::numeric_limits<double>::infinity();  ///< on the value as given
};

struct Smooth_settings
{
  lapmesh::Smoothing_scheme scheme = lapmesh::Smoothing_scheme::implicit_euler;
  Time_step lambda;
  long long iterations = 1;
  lapmesh::Laplacian laplacian = lapmesh::Laplacian::cotangent;
  lapmesh::Vertex_area area = lapmesh::Vertex_area::barycentric;
  double mollification = lapmesh::default_mollification_factor;  ///< intrinsic Delaunay only
  bool fixed_operator = false;       ///< keep the input's operator for every iteration
  bool restore_volume = false;       ///< rescale to the input's enclosed volume after each step
  bool restore_area = false;         ///< rescale to the input's surface area after each step
  bool fix_boundary = true;          ///< boundary vertices stay where they are
  bool reuse_factorization = false;  ///< implicit: CG preconditioned by the previous factor
  std::function<void(int done, int total)> progress;  ///< after each iteration; may throw to cancel
};

/// Checks what does not need the mesh (time step, iterations), so that a front end refuses
/// bad settings before reading anything. Throws Parameter_error.
void check(const Smooth_settings& settings, const Smoothing_limits& limits = {});

struct Smooth_result
{
  lapmesh::Smoothing_report report;
  double lambda = 0;  ///< the absolute time step used
  /// The explicit scheme's stability bound 2 / mu_max of the input's free vertices (NaN for the
  /// other schemes): the one figure behind the automatic step, the bound unit and the warning.
  double stability_bound = std::numeric_limits<double>::quiet_NaN();
  std::vector<Warning> warnings;
};

/// Smooths `mesh` in place; on an exception it is left as it was. check()s the settings first.
Smooth_result smooth(Mesh& mesh, const Smooth_settings& settings, const Smoothing_limits& limits = {});

// ---- noise ------------------------------------------------------------------------------

struct Noise_settings
{
  double level = 0.1;  ///< sigma = level x the scale's length, >= 0
  std::uint64_t seed = 0;
  lapmesh::Noise_direction direction = lapmesh::Noise_direction::isotropic;
  lapmesh::Noise_scale scale = lapmesh::Noise_scale::mean_edge_length;
};

/// Throws Parameter_error("level") for a negative or non-finite level.
void check(const Noise_settings& settings);

/// Adds seeded Gaussian noise in place; returns sigma.
double add_noise(Mesh& mesh, const Noise_settings& settings);

// ---- denoising study --------------------------------------------------------------------

/// Throws Parameter_error for settings the study cannot run (before any mesh is read).
void check(const lapmesh::Denoising_study_settings& settings);

/// Noise, smoothing and measurement for every combination of the settings (denoising.h).
lapmesh::Denoising_study denoise_study(const Mesh& mesh, const lapmesh::Denoising_study_settings& settings);

/// One line per noise level and scheme: the best run, whether it beat the noisy mesh, the
/// runs that stopped early and those that held a collapsed component.
struct Study_summary_line
{
  double noise_level = 0;
  lapmesh::Smoothing_scheme scheme = lapmesh::Smoothing_scheme::implicit_euler;
  double noisy_rms = 0;                              ///< RMS distance of the noisy mesh
  std::optional<lapmesh::Denoising_record> best;     ///< the best bounded run, if any
  bool best_is_worse_than_noisy = false;
  std::size_t runs = 0, stopped_runs = 0, held_runs = 0;
  std::string first_stop_reason;                     ///< "LAPLACIAN lambda TAU: message"
  std::string first_hold;                            ///< the same for the first held run
};
std::vector<Study_summary_line> summarize(const lapmesh::Denoising_study& study,
                                          const lapmesh::Denoising_study_settings& settings);

} // namespace lapmesh_ops

#endif
