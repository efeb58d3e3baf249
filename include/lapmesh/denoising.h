// lapmesh — denoising: how far a mesh is from a clean reference with the same connectivity,
// and a study driver that adds seeded noise, smooths, and measures after every iteration.
//
// Deviation from the reference (all lengths divided by the reference's bounding-box diagonal):
//   rms_distance        sqrt(mean_i |p_i - q_i|^2), vertex to corresponding vertex
//   hausdorff_distance  symmetric: the largest distance from a grid sample of either mesh
//                       (vertices, edges and faces, CGAL's grid sampling) to the other mesh,
//                       at spacing `hausdorff_spacing` x the larger mean edge length of the two
//                       meshes, coarsened where the grid would exceed 16 samples per corner
//                       (and 2^20 samples)
//   normal_angle_error  mean over vertices of the angle (degrees) between the area-weighted
//                       vertex normals (the normalised sum of the face cross products)
//   volume_change       (V - V_ref) / |V_ref| of the enclosed volume; NaN for open meshes
//
// The study runs every (noise level, scheme, Laplacian, time step) once for the full number
// of iterations and measures inside the per-iteration callback of the smoothing engine, so an
// error-versus-iteration curve costs one smoothing run, not one per iteration count.
#ifndef LAPMESH_DENOISING_H
#define LAPMESH_DENOISING_H

#include <lapmesh/internal/geometry.h>
#include <lapmesh/internal/laplacian_assembly.h>
#include <lapmesh/internal/mesh_extraction.h>
#include <lapmesh/internal/shape_restoration.h>
#include <lapmesh/internal/smoothing_engine.h>
#include <lapmesh/internal/stability_bound.h>
#include <lapmesh/internal/surface_distance.h>
#include <lapmesh/laplacian.h>
#include <lapmesh/noise.h>
#include <lapmesh/parameters.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace lapmesh {

/// double; default 1: grid spacing of the Hausdorff sampling, in units of the reference's
/// mean edge length (vertices are always sampled). A grid that would hold more than 16 samples
/// per corner (and more than 2^20 samples) is coarsened until it does not.
LAPMESH_NAMED_PARAMETER(hausdorff_spacing)

namespace internal {

/// Measures positions P (same topology as the reference) against the reference.
class Deviation_meter
{
public:
  /// `parallel`: the Hausdorff samples are searched by several threads (same results).
  Deviation_meter(const Mesh_topology& t, const Positions& reference, double hausdorff_spacing = 1.0,
                  bool parallel = false)
      : m_t(&t), m_reference(reference), m_parallel(parallel)
  {
    if(reference.rows() != t.num_vertices) throw std::invalid_argument("the reference has the wrong number of vertices");
    if(!(hausdorff_spacing > 0) || !std::isfinite(hausdorff_spacing))
      throw std::invalid_argument("the Hausdorff grid spacing must be a positive number");
    const Eigen::RowVector3d lo = reference.colwise().minCoeff(), hi = reference.colwise().maxCoeff();
    m_diagonal = (hi - lo).norm();
    if(!(m_diagonal > 0)) throw Mesh_error("the reference mesh has a zero bounding box");
    m_closed = t.manifold && t.num_boundary_edges == 0;
    if(m_closed) {
      Eigen::Vector3d c;
      volume_and_centroid(t, reference, m_volume, c);
    }
    m_reference_normals = unit_normals(reference);
    m_spacing_factor = hausdorff_spacing;
    m_spacing = hausdorff_spacing * mean_edge_length(t, reference);
    m_reference_surface = Surface_distance(reference, t.triangles);
    m_surface = m_reference_surface;
    m_samples = Grid_samples(t, reference);
  }

  double diagonal() const { return m_diagonal; }
  bool closed() const { return m_closed; }

  /// RMS vertex distance / diagonal (cheap: no sampling).
  double rms_distance(const Positions& P) const
  {
    return std::sqrt((P - m_reference).rowwise().squaredNorm().mean()) / m_diagonal;
  }

  Mesh_deviation measure(const Positions& P)
  {
    if(P.rows() != m_t->num_vertices) throw std::invalid_argument("positions of the wrong size");
    Mesh_deviation d;
    d.rms_distance = rms_distance(P);
    if(!P.allFinite()) {
      d.hausdorff_distance = d.normal_angle_error = d.volume_change = std::numeric_limits<double>::quiet_NaN();
      d.rms_distance = std::numeric_limits<double>::infinity();
      return d;
    }
    const Positions N = unit_normals(P);
    double angle_sum = 0;
    for(Index i = 0; i < P.rows(); ++i) {
      const Eigen::Vector3d a = N.row(i), b = m_reference_normals.row(i);
      angle_sum += std::atan2(a.cross(b).norm(), a.dot(b));
    }
    d.normal_angle_error = angle_sum / double(P.rows()) * 180.0 / M_PI;
    if(m_closed) {
      double V;
      Eigen::Vector3d c;
      volume_and_centroid(*m_t, P, V, c);
      d.volume_change = (V - m_volume) / std::abs(m_volume);
    }
    // The grid follows the larger of the two meshes' mean edge lengths, so that a blown-up
    // mesh (explicit steps above the stability bound) is not sampled with millions of points.
    const double spacing = std::max(m_spacing, m_spacing_factor * mean_edge_length(*m_t, P));
    m_surface.refit(P, m_parallel);
    // The reference does not move: its grid is bounded again only for another spacing.
    if(spacing != m_reference_spacing_asked) {
      m_reference_spacing_asked = spacing;
      m_reference_spacing = m_samples.bounded_spacing(m_reference, spacing, m_parallel);
    }
    const double spacing_ab = m_samples.bounded_spacing(P, spacing, m_parallel);
    const double spacing_ba = m_reference_spacing;
    const double ab = m_samples.largest_distance(P, spacing_ab, m_reference_surface, m_parallel);
    const double ba = m_samples.largest_distance(m_reference, spacing_ba, m_surface, m_parallel);
    d.hausdorff_distance = std::max(ab, ba) / m_diagonal;
    d.hausdorff_coarsening = std::max(spacing_ab, spacing_ba) / spacing;
    return d;
  }

private:
  /// Area-weighted unit vertex normals of P. Unlike the curvatures' and the noise's, no face is
  /// refused: a smoothing may have collapsed or blown up the faces this measures.
  Positions unit_normals(const Positions& P) const
  {
    return vertex_normals_of_faces(*m_t, m_parallel, [&](Index f, Eigen::Vector3d& cross) {
      const auto [pa, pb, pc] = face_points(*m_t, P, f);
      cross = (pb - pa).cross(pc - pa);
      return true;
    });
  }

  const Mesh_topology* m_t;
  Positions m_reference, m_reference_normals;
  double m_diagonal = 0, m_volume = 0, m_spacing = 0, m_spacing_factor = 1;
  double m_reference_spacing_asked = std::numeric_limits<double>::quiet_NaN(), m_reference_spacing = 0;
  bool m_closed = false, m_parallel = false;
  Surface_distance m_reference_surface;  // the reference does not move: its search is built once
  Surface_distance m_surface;            // the measured mesh's: the reference's, refitted each time
  Grid_samples m_samples;                // of either mesh, in an order of the reference's faces
};

} // namespace internal

/// \ingroup PkgLapmeshDenoising
/// @brief returns how far `tm` is from `reference`, which must have the same connectivity
/// (same vertex order and faces): RMS vertex distance, symmetric approximate Hausdorff distance
/// (both divided by the reference's bounding-box diagonal), mean normal-angle error in degrees
/// (area-weighted vertex normals) and relative volume change (closed meshes; NaN otherwise).
///
/// @param reference the clean mesh
/// @param tm the mesh to measure, with the connectivity of `reference`
/// @param np_reference named parameters of `reference`: `vertex_point_map`, `vertex_index_map`
/// @param np named parameters of `tm`: `vertex_point_map`, `vertex_index_map`, and
///   `lapmesh::parameters::hausdorff_spacing` (default 1 mean edge length)
/// @tparam ConcurrencyTag `CGAL::Parallel_tag` searches the Hausdorff samples in parallel (TBB);
///   the result is the same.
/// @throws std::invalid_argument when the connectivities differ; Mesh_error for invalid meshes.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters1 = CGAL::parameters::Default_named_parameters,
          typename NamedParameters2 = CGAL::parameters::Default_named_parameters>
Mesh_deviation mesh_deviation(const TriangleMesh& reference, const TriangleMesh& tm,
                              const NamedParameters1& np_reference = CGAL::parameters::default_values(),
                              const NamedParameters2& np = CGAL::parameters::default_values())
{
  const auto ref = internal::extract_mesh(reference, np_reference);
  const auto cur = internal::extract_mesh(tm, np);
  if(ref.topology.num_vertices != cur.topology.num_vertices || ref.topology.triangles != cur.topology.triangles)
    throw std::invalid_argument("the mesh and the reference do not have the same connectivity");
  const double spacing =
    CGAL::parameters::choose_parameter(CGAL::parameters::get_parameter(np, internal_np::hausdorff_spacing), 1.0);
  internal::Deviation_meter meter(ref.topology, ref.positions, spacing, internal::is_parallel<ConcurrencyTag>());
  return meter.measure(cur.positions);
}

namespace internal {

struct Stop_run {};

/// Marks `held` the `ok` records [first, last) of one run (one per step, in order) from the step
/// at which a component collapsed on, each naming the components held by then.
template <typename RecordIterator>
void mark_held_records(RecordIterator first, RecordIterator last, const std::vector<Collapsed_component>& held)
{
  for(; first != last; ++first) {
    if(first->status != Run_status::ok) continue;
    for(const Collapsed_component& c : held)
      if(c.iteration <= first->iteration) {
        if(first->message.empty()) first->message = "held:";
        else first->message += ';';
        first->message += " the connected component of vertex " + std::to_string(c.first_vertex) + " (" +
                          std::to_string(c.vertices) + " vertices) since iteration " + std::to_string(c.iteration);
        first->status = Run_status::held;
      }
  }
}

inline Denoising_study run_denoising_study(const Mesh_topology& t, const Positions& clean,
                                           const Denoising_study_settings& s, bool parallel = false)
{
  if(s.iterations <= 0) throw std::invalid_argument("the number of iterations must be positive (got " + std::to_string(s.iterations) + ")");
  for(double l : s.noise_levels)
    if(!(l >= 0) || !std::isfinite(l)) throw std::invalid_argument("noise levels must be finite numbers >= 0");
  for(double tau : s.time_steps)
    if(!(tau > 0) || !std::isfinite(tau)) throw std::invalid_argument("time steps must be positive finite numbers");
  if(s.noise_levels.empty() || s.schemes.empty() || s.laplacians.empty() || s.time_steps.empty())
    throw std::invalid_argument("the study needs at least one noise level, scheme, Laplacian and time step");
  if(s.restore_volume && t.num_boundary_edges != 0)
    throw Parameter_error("restore_volume", "volume restoration needs a closed mesh");
  checked_mollification(s.mollification, "mollification");

  Deviation_meter meter(t, clean, s.hausdorff_spacing, parallel);
  Denoising_study study;
  const std::size_t total_runs = s.noise_levels.size() * s.schemes.size() * s.laplacians.size() * s.time_steps.size();
  study.records.reserve(total_runs * std::size_t(s.iterations + 1));
  std::size_t runs_done = 0;
  const std::vector<char> no_constraints(std::size_t(t.num_vertices), 0);
  const std::vector<char> free_mask = free_vertex_mask(t, true);

  for(double level : s.noise_levels) {
    Positions noisy = clean;
    const double sigma = add_noise(t, noisy, level, s.noise_direction, s.noise_scale, s.seed);
    const Mesh_deviation noisy_deviation = meter.measure(noisy);
    const double h = mean_edge_length(t, noisy);
    // The explicit bound of the noisy mesh (what a user would compute), once per Laplacian: the
    // rows of every scheme report it.
    std::vector<double> bounds(s.laplacians.size(), std::numeric_limits<double>::quiet_NaN());
    std::vector<std::string> bound_errors(s.laplacians.size());
    for(std::size_t l = 0; l < s.laplacians.size(); ++l) {
      try {
        Laplacian_pencil pencil;
        assemble_pencil(t, noisy, s.laplacians[l], s.area, false, pencil, s.mollification);
        require_positive_mass(s.laplacians[l], pencil.mass, s.area);
        bounds[l] = explicit_stability_bound(pencil, free_mask, false);
      } catch(const std::exception& e) {
        bound_errors[l] = std::string("the noisy mesh: ") + e.what();
      }
    }
    for(Smoothing_scheme scheme : s.schemes)
      for(std::size_t l = 0; l < s.laplacians.size(); ++l) {
        const Laplacian lap = s.laplacians[l];
        const double bound = bounds[l];
        const std::string& bound_error = bound_errors[l];
        for(double tau : s.time_steps) {
          Denoising_record base;
          base.noise_level = level;
          base.sigma = sigma;
          base.scheme = scheme;
          base.laplacian = lap;
          base.time_step = tau;
          base.stability_bound = bound;
          base.lambda = lambda_of_time_step(tau, s.unit, lap, [&] { return h; }, [&] { return bound; });
          Denoising_record r0 = base;
          r0.iteration = 0;
          r0.deviation = noisy_deviation;
          study.records.push_back(r0);

          Positions P = noisy;
          Smoothing_settings settings;
          settings.scheme = scheme;
          settings.laplacian = lap;
          settings.area = s.area;
          settings.mollification = s.mollification;
          settings.lambda = base.lambda;
          settings.iterations = s.iterations;
          settings.fixed_operator = s.fixed_operator;
          settings.restore_volume = s.restore_volume;
          settings.known_stability_bound = bound;  // of the same operator and free vertices
          Run_status status = Run_status::ok;
          std::string message;
          int done = 0;
          // Collected as they happen: a run that fails after a hold keeps its held steps.
          std::vector<Collapsed_component> held;
          settings.held_components = &held;
          Denoising_progress where;
          where.runs_done = runs_done;
          where.total_runs = total_runs;
          where.noise_level = level;
          where.scheme = scheme;
          where.laplacian = lap;
          where.time_step = tau;
          where.iterations = s.iterations;
          // P is smoothed in place: the callback sees the state after each iteration.
          settings.progress = [&](int it, int) {
            Denoising_record r = base;
            r.iteration = it;
            done = it;
            // A diverging explicit run can grow by orders of magnitude in one step: check the
            // cheap RMS first, and do not sample a huge mesh for the Hausdorff distance.
            const double rms = meter.rms_distance(P);
            if(!(rms <= 1.0)) {
              const double nan = std::numeric_limits<double>::quiet_NaN();
              r.deviation = Mesh_deviation{rms, nan, nan, nan};
              r.status = status = Run_status::diverged;
              r.message = message = "iteration " + std::to_string(it) + ": the RMS distance " +
                                    (std::isfinite(rms) ? "exceeded one bounding-box diagonal" : "is not finite");
            } else {
              r.deviation = meter.measure(P);
            }
            study.records.push_back(r);
            where.iteration = it;
            if(s.progress) s.progress(where);
            if(status != Run_status::ok) throw Stop_run{};
          };
          try {
            if(!bound_error.empty()) throw Mesh_error(bound_error);
            if(!(base.lambda > 0) || !std::isfinite(base.lambda))
              throw std::invalid_argument("the time step is not a positive finite number");
            smooth_positions(t, P, no_constraints, settings);
          } catch(const Stop_run&) {
          } catch(const Numerical_error& e) {
            // The explicit scheme's divergence check (non-finite positions) lands here too.
            status = scheme == Smoothing_scheme::explicit_euler && !P.allFinite() ? Run_status::diverged : Run_status::failed;
            message = e.what();
          } catch(const std::exception& e) {
            status = Run_status::failed;
            message = e.what();
          }
          mark_held_records(study.records.end() - done, study.records.end(), held);
          for(int it = done + 1; it <= s.iterations; ++it) {
            Denoising_record r = base;
            r.iteration = it;
            const double nan = std::numeric_limits<double>::quiet_NaN();
            r.deviation = Mesh_deviation{nan, nan, nan, nan};
            r.status = status;
            r.message = message;
            study.records.push_back(r);
          }
          ++runs_done;
          where.runs_done = runs_done;
          if(s.progress) s.progress(where);
        }
      }
  }
  return study;
}

} // namespace internal

/// \ingroup PkgLapmeshDenoising
/// @brief runs a denoising study on the clean mesh `tm`: for each noise level, adds seeded
/// noise (`add_noise`, same seed for every level), then for each scheme, Laplacian and time
/// step smooths for `settings.iterations` steps and measures the deviation from `tm` after
/// every step (and once before the first, iteration 0).
///
/// Runs whose RMS distance exceeds one bounding-box diagonal are stopped and marked
/// `diverged`; runs stopped by an error (a collapsed face, a failed factorisation) are marked
/// `failed`; their remaining records hold NaN. Records after a step that shrank one of several
/// connected components to nearly a point are marked `held`: the flow held it there and went
/// on with the others (Smoothing_report::collapsed_components). Named parameters: `vertex_point_map`,
/// `vertex_index_map`. `tm` is not modified. With `CGAL::Parallel_tag` the Hausdorff samples of
/// each measurement are searched in parallel (TBB); the records are the same.
template <typename ConcurrencyTag = CGAL::Sequential_tag, typename TriangleMesh,
          typename NamedParameters = CGAL::parameters::Default_named_parameters>
Denoising_study run_denoising_study(const TriangleMesh& tm, const Denoising_study_settings& settings,
                                    const NamedParameters& np = CGAL::parameters::default_values())
{
  const auto mesh = internal::extract_mesh(tm, np);
  return mesh.naming_input_vertices([&] {
    return internal::run_denoising_study(mesh.topology, mesh.positions, settings, internal::is_parallel<ConcurrencyTag>());
  });
}

} // namespace lapmesh

#endif
