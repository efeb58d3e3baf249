// lapmesh — the vocabulary of the public API: every enumeration, each with one name table,
// and the option and report structures of the solvers.
//
// The name tables are the only place where a kind is spelled: the library's to_string() and
// parse functions, the command line's choices and --help, the viewer's dropdowns (served by
// GET /api/info) and the error messages all read them. A name is the command line's spelling.
//
//   lapmesh::names<lapmesh::Laplacian>()            // {"uniform", "cotangent"}
//   lapmesh::parse<lapmesh::Laplacian>("uniform")   // std::optional<Laplacian>
//   lapmesh::to_string(lapmesh::Laplacian::uniform) // "uniform"
//   lapmesh::name_list<lapmesh::Laplacian>()        // "uniform, cotangent"
//
// The result and settings structures of the operations are declared here too, so that a front
// end (or a binding) can hold them without the algorithms' headers.
#ifndef LAPMESH_TYPES_H
#define LAPMESH_TYPES_H

#include <array>
#include <cmath>
#include <cstdint>
#include <cstddef>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace lapmesh {

/// One entry of an enumeration's name table.
template <typename Enum>
struct Named
{
  Enum value;               ///< the enumerator
  const char* name;         ///< as the command line, the viewer and the bindings spell it
  const char* description;  ///< one line for --help and the viewer
};

/// The name table of `Enum`: specialised for every public enumeration below. `table` lists the
/// enumerators in the order the documentation and the front ends show them.
template <typename Enum>
struct Enum_names
{};

// ---- operators ------------------------------------------------------------------------

/// n x 3 per-vertex vectors (positions, normals, Laplacians), row i = vertex i.
using Vertex_vectors = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// The discretisation of the Laplacian (doc/conventions.md).
enum class Laplacian {
  uniform,   ///< graph Laplacian: stiffness W = A - D, mass D = diag(degree)
  cotangent,  ///< Laplace–Beltrami: stiffness C (halved cotangent weights), mass diag(A_i)
  /// the cotangent Laplacian of the intrinsic Delaunay triangulation of the (mollified) edge
  /// lengths: every off-diagonal weight >= 0; mass from the intrinsic triangles
  intrinsic_delaunay
};
/// The name table of Laplacian.
template <>
struct Enum_names<Laplacian>
{
  /// The names of the Laplacian enumerators, in display order.
  static constexpr std::array<Named<Laplacian>, 3> table{{
    {Laplacian::uniform, "uniform", "graph Laplacian (adjacency minus degrees)"},
    {Laplacian::cotangent, "cotangent", "Laplace-Beltrami (cotangent weights, vertex areas)"},
    {Laplacian::intrinsic_delaunay, "intrinsic-delaunay",
     "Laplace-Beltrami on the intrinsic Delaunay triangulation (weights >= 0; slivers, obtuse meshes)"},
  }};
};

/// The intrinsic Delaunay Laplacian's default mollification margin delta, in mean edge lengths
/// (named parameter `lapmesh::parameters::mollification_factor`).
constexpr double default_mollification_factor = 1e-5;

/// The symmetric generalized pair (S, M) of a Laplacian: L = M^-1 S (doc/conventions.md).
struct Laplacian_pencil
{
  Eigen::SparseMatrix<double> stiffness;  ///< S: C (cotangent) or W (uniform); negative semidefinite
  Eigen::VectorXd mass;                   ///< diagonal of M: A_i (cotangent) or degree (uniform)

  // Eigen 3.4's sparse matrix has no move operations (std::move copies it): a pencil moves by
  // swapping its storage, so returning or assigning one never copies the matrix.

  /// An empty pencil.
  Laplacian_pencil() = default;
  /// The pencil (S, M).
  Laplacian_pencil(Eigen::SparseMatrix<double> S, Eigen::VectorXd M) : mass(std::move(M)) { stiffness.swap(S); }
  /// A copy.
  Laplacian_pencil(const Laplacian_pencil&) = default;
  /// Copies `other`.
  Laplacian_pencil& operator=(const Laplacian_pencil&) = default;
  /// Takes the storage of `other`, which is left empty.
  Laplacian_pencil(Laplacian_pencil&& other) noexcept { swap(other); }
  /// Exchanges the storage with `other`, which is destroyed or reassigned next.
  Laplacian_pencil& operator=(Laplacian_pencil&& other) noexcept
  {
    swap(other);
    return *this;
  }
  /// Exchanges the matrices and masses of two pencils without copying them.
  void swap(Laplacian_pencil& other) noexcept
  {
    stiffness.swap(other.stiffness);
    mass.swap(other.mass);
  }
};

/// The vertex area A_i, i.e. the diagonal of the lumped mass matrix (doc/conventions.md).
enum class Vertex_area {
  barycentric,  ///< one third of the incident face areas (default)
  voronoi,      ///< circumcentric cells; can be zero or negative on obtuse meshes
  mixed         ///< Meyer et al. 2003 mixed cells; positive, sums to the surface area
};
/// The name table of Vertex_area.
template <>
struct Enum_names<Vertex_area>
{
  /// The names of the Vertex_area enumerators, in display order.
  static constexpr std::array<Named<Vertex_area>, 3> table{{
    {Vertex_area::barycentric, "barycentric", "one third of the incident face areas"},
    {Vertex_area::voronoi, "voronoi", "circumcentric cells (can be <= 0 on obtuse meshes)"},
    {Vertex_area::mixed, "mixed", "Voronoi cells clipped at obtuse triangles (Meyer et al.)"},
  }};
};

// ---- smoothing ------------------------------------------------------------------------

/// The time discretisation of the Laplacian flow.
enum class Smoothing_scheme {
  explicit_euler,  ///< P <- P + lambda L P (forward Euler); stable only below the bound
  implicit_euler,  ///< (M - lambda S) P' = M P (backward Euler); unconditionally stable
  conformal        ///< conformalized mean curvature flow (Kazhdan et al. 2012): S of the input, M updated
};
/// The name table of Smoothing_scheme.
template <>
struct Enum_names<Smoothing_scheme>
{
  /// The names of the Smoothing_scheme enumerators, in display order.
  static constexpr std::array<Named<Smoothing_scheme>, 3> table{{
    {Smoothing_scheme::explicit_euler, "explicit", "forward Euler, stable below the stability bound"},
    {Smoothing_scheme::implicit_euler, "implicit", "backward Euler, stable at any time step"},
    {Smoothing_scheme::conformal, "conformal", "conformalized mean curvature flow"},
  }};
};

/// The unit in which a time step is given (smoothing, the denoising study, the viewer).
enum class Time_step_unit {
  absolute,                  ///< lambda itself
  mean_edge_length_squared,  ///< lambda = tau x (mean edge length)^2 (cotangent), tau (uniform): scale_free_time_step()
  stability_bound            ///< lambda = tau x the explicit stability bound 2 / mu_max of the mesh
};
/// The name table of Time_step_unit.
template <>
struct Enum_names<Time_step_unit>
{
  /// The names of the Time_step_unit enumerators, in display order.
  static constexpr std::array<Named<Time_step_unit>, 3> table{{
    {Time_step_unit::absolute, "absolute", "lambda itself"},
    {Time_step_unit::mean_edge_length_squared, "edge2", "times the mean edge length squared (cotangent)"},
    {Time_step_unit::stability_bound, "bound", "times the explicit stability bound"},
  }};
};

/// A connected component that a smoothing flow shrank to nearly a point.
struct Collapsed_component
{
  int iteration = 0;             ///< steps done when it was found (0: the input)
  std::size_t first_vertex = 0;  ///< its smallest vertex index
  std::size_t vertices = 0;      ///< its vertex count
  double area_over_lambda = 0;   ///< its area (the sum of its vertex areas) / lambda then
};

/// What a smoothing run did. Times are wall-clock seconds spent in each phase.
struct Smoothing_report
{
  int iterations = 0;              ///< iterations done
  std::size_t free_vertices = 0;  ///< vertices that moved (neither boundary nor constrained)
  /// For the explicit scheme: 2 / mu_max, mu_max the largest eigenvalue of -L on the free
  /// vertices of the input mesh; the scheme is stable for lambda below it (NaN otherwise).
  /// When lambda is below the (cheap) Gershgorin bound the Lanczos estimate is skipped
  /// (stability is proven) unless requested: then this holds the Gershgorin bound and
  /// `stability_bound_exact` is false.
  double stability_bound = std::numeric_limits<double>::quiet_NaN();
  bool stability_bound_exact = false;  ///< the bound is the Lanczos estimate, not Gershgorin's
  bool above_stability_bound = false;  ///< lambda exceeds the bound: the explicit scheme may diverge
  /// "eigen-ldlt", "cholmod-supernodal" or "sparse_linear_solver" (implicit schemes).
  std::string solver;
  double assembly_seconds = 0;       ///< building the operator
  double analysis_seconds = 0;       ///< the symbolic analysis of the implicit system
  double factorization_seconds = 0;  ///< numeric factorisations
  double solve_seconds = 0;          ///< solves and explicit steps
  int factorizations = 0;            ///< numeric factorisations done
  int preconditioned_solves = 0;  ///< steps solved by CG with a previous factor
  int cg_iterations = 0;          ///< total CG iterations (all three coordinates)
  /// Implicit flows whose operator follows the positions, without shape restoration: the
  /// connected components that the flow shrank to nearly a point (area below 1e-12 x lambda,
  /// where their part of M is lost beside lambda S), in the order found. Each is held where the
  /// flow left it for the remaining steps while the other components go on; they are counted in
  /// `free_vertices`.
  std::vector<Collapsed_component> collapsed_components;
};

// ---- noise ----------------------------------------------------------------------------

/// The direction of the displacements: a Gaussian 3-vector, or a Gaussian scalar times the vertex normal.
enum class Noise_direction { isotropic, normal };
/// The name table of Noise_direction.
template <>
struct Enum_names<Noise_direction>
{
  /// The names of the Noise_direction enumerators, in display order.
  static constexpr std::array<Named<Noise_direction>, 2> table{{
    {Noise_direction::isotropic, "isotropic", "a Gaussian 3-vector per vertex"},
    {Noise_direction::normal, "normal", "a Gaussian scalar times the unit vertex normal"},
  }};
};

/// The length that the noise level multiplies to give sigma.
enum class Noise_scale { mean_edge_length, bounding_box_diagonal };
/// The name table of Noise_scale.
template <>
struct Enum_names<Noise_scale>
{
  /// The names of the Noise_scale enumerators, in display order.
  static constexpr std::array<Named<Noise_scale>, 2> table{{
    {Noise_scale::mean_edge_length, "mean-edge", "sigma = level x mean edge length"},
    {Noise_scale::bounding_box_diagonal, "bbox", "sigma = level x bounding-box diagonal"},
  }};
};

// ---- curvature ------------------------------------------------------------------------

/// Per-vertex curvature quantities, entry i = vertex i of the vertex numbering.
struct Vertex_curvatures
{
  Eigen::VectorXd mean;          ///< H, signed (outward normals: sphere has +1/r)
  Eigen::VectorXd gaussian;      ///< K, angle deficit over the vertex area
  Eigen::VectorXd k1;            ///< larger principal curvature, k1 = H + sqrt(max(H^2 - K, 0))
  Eigen::VectorXd k2;            ///< smaller principal curvature, k2 = H - sqrt(max(H^2 - K, 0)) <= k1
  Eigen::VectorXd area;          ///< A_i of the chosen kind (the denominator of K)
  Vertex_vectors normal;         ///< unit area-weighted vertex normals
  Vertex_vectors laplacian;      ///< (L x)_i, the Laplacian of the positions (= -2 H n on smooth parts)
};


// ---- denoising study ------------------------------------------------------------------

/// How far a mesh is from a reference with the same connectivity. Lengths are relative to the
/// bounding-box diagonal of the reference.
struct Mesh_deviation
{
  double rms_distance = 0;        ///< RMS of the vertex-to-vertex distances / diagonal
  double hausdorff_distance = 0;  ///< symmetric approximate Hausdorff distance / diagonal
  double normal_angle_error = 0;  ///< mean angle between area-weighted vertex normals, degrees
  double volume_change = std::numeric_limits<double>::quiet_NaN();  ///< (V - V_ref)/|V_ref|; NaN if open
  /// How many times coarser than asked the Hausdorff grid was sampled, at most over the two
  /// directions: 1 when as asked, above 1 where the grid would have held more than 16 samples
  /// per corner (and more than 2^20 samples).
  double hausdorff_coarsening = 1;
};


/// How a run of the denoising study ended.
enum class Run_status {
  ok,        ///< finite and within one bounding-box diagonal of the clean mesh
  diverged,  ///< the RMS distance exceeded one bounding-box diagonal or became non-finite
  failed,    ///< the smoothing stopped with an error (e.g. a face collapsed to zero area)
  /// finite and bounded, but the flow shrank a connected component to nearly a point and it is
  /// held there (Smoothing_report::collapsed_components): from the step that shrank it on
  held
};
/// The name table of Run_status.
template <>
struct Enum_names<Run_status>
{
  /// The names of the Run_status enumerators, in display order.
  static constexpr std::array<Named<Run_status>, 4> table{{
    {Run_status::ok, "ok", "finite and within one bounding-box diagonal"},
    {Run_status::diverged, "diverged", "the RMS distance exceeded one diagonal or is not finite"},
    {Run_status::failed, "failed", "the smoothing stopped with an error"},
    {Run_status::held, "held", "a component shrunk to nearly a point is held where the flow left it"},
  }};
};

/// Where a denoising study stands, passed to `Denoising_study_settings::progress`.
struct Denoising_progress
{
  std::size_t runs_done = 0;   ///< runs finished
  std::size_t total_runs = 0;  ///< levels x schemes x Laplacians x time steps
  double noise_level = 0;      ///< of the current (or just finished) run
  Smoothing_scheme scheme = Smoothing_scheme::implicit_euler;  ///< of the current run
  Laplacian laplacian = Laplacian::cotangent;                  ///< of the current run
  double time_step = 0;  ///< of the current run, in the settings' unit
  int iteration = 0;     ///< steps measured in the current run
  int iterations = 0;    ///< steps per run
};

/// What the denoising study runs. Every combination of level, scheme, Laplacian and time step
/// is one run of `iterations` steps on the same noisy mesh (per level).
struct Denoising_study_settings
{
  std::vector<double> noise_levels{0.02, 0.05, 0.1};  ///< noise levels (sigma = level x noise_scale)
  std::vector<Smoothing_scheme> schemes{Smoothing_scheme::explicit_euler,
                                        Smoothing_scheme::implicit_euler};  ///< schemes compared
  std::vector<Laplacian> laplacians{Laplacian::uniform, Laplacian::cotangent};  ///< Laplacians compared
  std::vector<double> time_steps{0.03, 0.1, 0.3, 1.0, 3.0};  ///< time steps, in `unit`
  Time_step_unit unit = Time_step_unit::mean_edge_length_squared;  ///< unit of `time_steps`
  int iterations = 20;  ///< smoothing steps per run (one record after each)
  std::uint64_t seed = 1;  ///< the same seed for every level: the noise differs only in scale
  Noise_direction noise_direction = Noise_direction::isotropic;  ///< isotropic or along the normals
  Noise_scale noise_scale = Noise_scale::mean_edge_length;        ///< what the level multiplies
  Vertex_area area = Vertex_area::barycentric;                    ///< vertex area of the operators
  double mollification = default_mollification_factor;  ///< intrinsic Delaunay only (mollification_factor)
  bool restore_volume = false;  ///< closed meshes only
  bool fixed_operator = false;  ///< keep the noisy mesh's operator for all iterations
  double hausdorff_spacing = 1.0;  ///< in mean edge lengths of the clean mesh
  /// Called after each measured iteration and after each run (then `runs_done` has grown).
  std::function<void(const Denoising_progress&)> progress;
};

/// One measurement: the state after `iteration` steps (0: the noisy mesh).
struct Denoising_record
{
  double noise_level = 0;  ///< the noise level of this run
  double sigma = 0;  ///< the noise's standard deviation (absolute)
  Smoothing_scheme scheme = Smoothing_scheme::implicit_euler;  ///< the scheme of this run
  Laplacian laplacian = Laplacian::cotangent;                  ///< the Laplacian of this run
  double time_step = 0;        ///< in the settings' unit
  double lambda = 0;           ///< absolute
  double stability_bound = 0;  ///< 2 / mu_max of the noisy mesh for this Laplacian (absolute)
  int iteration = 0;                   ///< steps done (0: the noisy mesh)
  Mesh_deviation deviation;            ///< the metrics against the clean mesh
  Run_status status = Run_status::ok;  ///< how the run stands after this step
  std::string message;  ///< the error of failed and diverged runs; the held components of held ones
};

/// The records of a denoising study, and the best run per noise level and scheme.
struct Denoising_study
{
  std::vector<Denoising_record> records;  ///< level-major, then scheme, Laplacian, time step, iteration

  /// Whether a record can be a best one: an `ok` state after at least one step with a finite RMS
  /// distance. `held` records are left out: one of their components has collapsed to a point.
  static bool counts_for_best(const Denoising_record& r)
  {
    return r.iteration > 0 && r.status == Run_status::ok && std::isfinite(r.deviation.rms_distance);
  }

  /// The record with the smallest RMS distance among those that counts_for_best() for this
  /// level and scheme (all Laplacians and time steps), if any.
  std::optional<Denoising_record> best(double level, Smoothing_scheme scheme) const
  {
    return best_where([&](const Denoising_record& r) { return r.noise_level == level && r.scheme == scheme; });
  }
  /// The same for the one run of this level, scheme, Laplacian and time step (in the settings'
  /// unit): its best iteration.
  std::optional<Denoising_record> best(double level, Smoothing_scheme scheme, Laplacian laplacian,
                                       double time_step) const
  {
    return best_where([&](const Denoising_record& r) { return in_run(r, level, scheme, laplacian, time_step); });
  }

  /// The records of the run of this level, scheme, Laplacian and time step (in the settings'
  /// unit), in iteration order from iteration 0 (the noisy mesh); empty when there is no such run.
  /// A run has a record for every iteration, whatever its status: the last one is the run's end.
  std::vector<Denoising_record> run(double level, Smoothing_scheme scheme, Laplacian laplacian, double time_step) const
  {
    std::vector<Denoising_record> out;
    for(const auto& r : records)
      if(in_run(r, level, scheme, laplacian, time_step)) out.push_back(r);
    return out;
  }

  /// The largest Mesh_deviation::hausdorff_coarsening of the records (1: every grid as asked).
  double largest_hausdorff_coarsening() const
  {
    double largest = 1;
    for(const auto& r : records)
      if(r.deviation.hausdorff_coarsening > largest) largest = r.deviation.hausdorff_coarsening;
    return largest;
  }

private:
  static bool in_run(const Denoising_record& r, double level, Smoothing_scheme scheme, Laplacian laplacian,
                     double time_step)
  {
    return r.noise_level == level && r.scheme == scheme && r.laplacian == laplacian && r.time_step == time_step;
  }

  template <typename Selected>
  std::optional<Denoising_record> best_where(const Selected& selected) const
  {
    std::optional<Denoising_record> out;
    for(const auto& r : records)
      if(selected(r) && counts_for_best(r) && (!out || r.deviation.rms_distance < out->deviation.rms_distance))
        out = r;
    return out;
  }
};

// ---- colour maps ----------------------------------------------------------------------

/// A colour map for per-vertex scalars (colormap.h).
enum class Colormap { jet, viridis, coolwarm, gray };
/// The name table of Colormap.
template <>
struct Enum_names<Colormap>
{
  /// The names of the Colormap enumerators, in display order.
  static constexpr std::array<Named<Colormap>, 4> table{{
    {Colormap::jet, "jet", "rainbow, blue to red"},
    {Colormap::viridis, "viridis", "perceptually uniform, dark blue to yellow"},
    {Colormap::coolwarm, "coolwarm", "diverging, for signed values"},
    {Colormap::gray, "gray", "black to white"},
  }};
};

// ---- spectral solver ------------------------------------------------------------------

/// The sparse Cholesky factorisation used by the spectral solver.
enum class Sparse_cholesky {
  simplicial,  ///< Eigen's SimplicialLLT (AMD ordering); always available
  cholmod      ///< SuiteSparse CHOLMOD, supernodal LL^T (needs LAPMESH_HAS_CHOLMOD and linking
               ///< cholmod); the default when available: with an optimised BLAS its block solves
               ///< cost less per vector than single ones
};
/// The name table of Sparse_cholesky.
template <>
struct Enum_names<Sparse_cholesky>
{
  /// The names of the Sparse_cholesky enumerators, in display order.
  static constexpr std::array<Named<Sparse_cholesky>, 2> table{{
    {Sparse_cholesky::simplicial, "simplicial", "Eigen's SimplicialLLT"},
    {Sparse_cholesky::cholmod, "cholmod", "CHOLMOD's supernodal LL^T"},
  }};
};

/// The Krylov eigen-solver run on the shift-invert operator.
enum class Krylov_method {
  block_lanczos,  ///< lapmesh's thick-restart block Lanczos (default)
  spectra         ///< Spectra's SymEigsShiftSolver (implicitly restarted Lanczos)
};
/// The name table of Krylov_method.
template <>
struct Enum_names<Krylov_method>
{
  /// The names of the Krylov_method enumerators, in display order.
  static constexpr std::array<Named<Krylov_method>, 2> table{{
    {Krylov_method::block_lanczos, "block-lanczos", "lapmesh's thick-restart block Lanczos"},
    {Krylov_method::spectra, "spectra", "Spectra's implicitly restarted Lanczos"},
  }};
};

/// The default factorisation: CHOLMOD when compiled in.
constexpr Sparse_cholesky default_sparse_cholesky =
#ifdef LAPMESH_HAS_CHOLMOD
  Sparse_cholesky::cholmod;
#else
  Sparse_cholesky::simplicial;
#endif

/// What the spectral solver is doing, for progress reports.
struct Spectral_progress
{
  const char* stage;       ///< "factorising", "lanczos", "checking completeness", "lanczos band",
                           ///< "locating the crowded eigenvalues"
  long long operations;    ///< shift-invert solves so far (in the current attempt)
  int attempt;             ///< 1 for the first run; more after a completeness retry
  double elapsed_seconds;  ///< since the solve started
};

/// Options of the spectral solver (filled from named parameters by Spectral_basis).
struct Spectral_options
{
  double tolerance = 1e-10;        ///< relative residual of the shift-invert operator A:
                                   ///< ||A y - theta y|| <= tolerance |theta|; it does not bound the
                                   ///< pencil's ||S phi + lambda M phi|| (doc/spectral.md)
  int max_restarts = 1000;         ///< Lanczos restarts per attempt
  int extra = -1;                  ///< extra pairs for the completeness check; -1: max(6, k/10)
  double shift_factor = 1e-2;      ///< sigma = -shift_factor / sum(M)
  bool check_completeness = true;  ///< Sylvester inertia count (one more numeric factorisation)
  Sparse_cholesky cholesky = default_sparse_cholesky;   ///< the factorisation of the shift-invert operator
  Krylov_method method = Krylov_method::block_lanczos;  ///< the eigensolver
  int block_size = 0;              ///< block Lanczos: vectors per block; 0: 4 below 250 pairs, else 8
  int dense_limit = 2500;          ///< use a dense solver when n <= this and k + extra >= n / 2
  int band_size = -1;              ///< > 0: spectrum slicing in bands of this many pairs, widened
                                   ///< by the solver past wider clusters (`method` inside);
                                   ///< 0: one run; -1: 40 when k >= 200 and either k > n / 175
                                   ///< or k > 1000
  bool solve_copies_once = true;   ///< components that are copies of one another (an assembly's
                                   ///< repeated parts) solved once, on one copy
  double ncv_factor = 0;           ///< Krylov subspace size max(ncv_factor * m + 1, m + 20) (Spectra)
                                   ///< or max(ncv_factor * m, m + 6 block_size) (block Lanczos);
                                   ///< 0: the method's own, 2 (Spectra) or, for block Lanczos,
                                   ///< 2.5 up to 48 pairs and 1.75 beyond
  std::function<void(const Spectral_progress&)> progress;  ///< optional
};

/// The computed eigenpairs: values ascending, vectors M-orthonormal (one per column).
struct Spectral_pairs
{
  Eigen::VectorXd values;   ///< eigenvalues, ascending
  Eigen::MatrixXd vectors;  ///< M-orthonormal eigenvectors, one per column
  double shift = 0;           ///< sigma used by the shift-invert solver (0 for the dense path)
  long long operations = 0;   ///< shift-invert solves, all attempts
  int attempts = 0;         ///< solver runs (more than one after a completeness retry)
  bool dense = false;       ///< solved by the dense path (small meshes)
};

// ---- reading meshes -------------------------------------------------------------------

namespace io {

/// A mesh as read from a file, before triangulation and validation.
struct Polygon_soup
{
  std::vector<std::array<double, 3>> points;       ///< vertex positions, in file order
  std::vector<std::vector<std::size_t>> polygons;  ///< faces as indices into `points`
};

/// What soup_to_triangles() did besides copying.
struct Soup_report
{
  std::size_t triangulated_polygons = 0;  ///< input faces with more than 3 vertices
  std::size_t flipped_faces = 0;          ///< faces re-oriented for consistency
  std::size_t dropped_faces = 0;          ///< faces that use a vertex twice (no triangle), left out
  std::size_t zero_area_faces = 0;        ///< triangles with numerically undefined angles
  std::size_t isolated_vertices = 0;      ///< vertices in no face
  std::size_t non_manifold_edges = 0;     ///< edges with more than two faces
  bool non_orientable = false;            ///< no consistent orientation exists
  /// When the mesh cannot be held as it is (non-manifold edges or vertices, no consistent
  /// orientation), its faces are stored apart, each with vertices of its own: the input
  /// vertex of each vertex of the graph, in `vertices(g)` order, to weld them back (the
  /// `vertex_index_map` of lapmesh's functions). Empty when vertex i is input vertex i.
  std::vector<std::size_t> input_vertex;
};

} // namespace io

// ---- names ----------------------------------------------------------------------------

/// @brief returns the name table of `Enum` (value, name, description), in display order.
template <typename Enum>
constexpr const auto& name_table()
{
  return Enum_names<Enum>::table;
}

/// @brief returns the names of `Enum`'s enumerators, in display order.
template <typename Enum>
std::vector<std::string> names()
{
  std::vector<std::string> out;
  for(const auto& entry : name_table<Enum>()) out.emplace_back(entry.name);
  return out;
}

/// @brief returns the names of `Enum` joined by `separator` (for help texts and messages).
template <typename Enum>
std::string name_list(const std::string& separator = ", ")
{
  std::string out;
  for(const auto& entry : name_table<Enum>()) out += (out.empty() ? "" : separator) + std::string(entry.name);
  return out;
}

/// @brief returns the enumerator named `name`, or nothing for an unknown name.
template <typename Enum>
std::optional<Enum> parse(std::string_view name)
{
  for(const auto& entry : name_table<Enum>())
    if(name == entry.name) return entry.value;
  return std::nullopt;
}

/// @brief returns the name of `value`, as the command line spells it.
template <typename Enum, typename = decltype(Enum_names<Enum>::table)>
const char* to_string(Enum value)
{
  for(const auto& entry : name_table<Enum>())
    if(entry.value == value) return entry.name;
  return "unknown";
}

/// @brief returns the Laplacian named `s`, or nothing for an unknown name.
inline std::optional<Laplacian> parse_laplacian(const std::string& s) { return parse<Laplacian>(s); }
/// @brief returns the vertex area named `s`, or nothing for an unknown name.
inline std::optional<Vertex_area> parse_vertex_area(const std::string& s) { return parse<Vertex_area>(s); }
/// @brief returns the scheme named `s` ("explicit", "implicit", "conformal"), or nothing.
inline std::optional<Smoothing_scheme> parse_smoothing_scheme(const std::string& s) { return parse<Smoothing_scheme>(s); }
/// @brief returns the time-step unit named `s` ("absolute", "edge2", "bound"), or nothing.
inline std::optional<Time_step_unit> parse_time_step_unit(const std::string& s) { return parse<Time_step_unit>(s); }

} // namespace lapmesh

#endif
