// lapmesh — CHOLMOD's supernodal Cholesky as lapmesh uses it (needs LAPMESH_HAS_CHOLMOD and
// linking libcholmod).
//
// Why a wrapper around Eigen::CholmodSupernodalLLT. SuiteSparse 5 compiles CHOLMOD's supernodal
// numeric factorisation with OpenMP regions of a fixed 4 threads (CHOLMOD_OMP_NUM_THREADS in
// cholmod_core.h). The supernodes of a surface mesh are small, so these regions cost their
// fork/join and, next to OpenBLAS's own threads, oversubscribe the cores: on a small machine the
// numeric factorisation is about twice as slow with them as without. The wrapper makes
// CHOLMOD's OpenMP regions inactive for the
// duration of each call (max-active-levels 0), then restores the caller's setting; BLAS threads
// are left alone. The OpenMP entry points are looked up at run time (dlsym) in the runtime that
// CHOLMOD itself loads, so lapmesh neither links an OpenMP runtime nor redeclares its functions
// (a weak redeclaration would turn a user's own calls into weak references); the guard does
// nothing when no OpenMP runtime is loaded.
//
// CHOLMOD prints its warnings and errors itself (on stdout, by default): every
// Cholmod_supernodal_llt routes them into last_cholmod_message() instead, which the callers
// turn into lapmesh exceptions.
//
// CHOLMOD allocates its factor (hundreds of MiB on large meshes) through SuiteSparse's
// configured malloc and calloc, and glibc maps such blocks afresh at every call, where they fault
// in one 4 KiB page at a time as CHOLMOD zeroes them. The first Cholmod_supernodal_llt replaces
// SuiteSparse's default malloc and calloc by the same functions followed by huge-page advice
// (internal/memory.h: blocks of 32 MiB or more), once per process; an allocator that the
// application configured itself is left alone.
#ifndef LAPMESH_INTERNAL_CHOLMOD_H
#define LAPMESH_INTERNAL_CHOLMOD_H

#ifdef LAPMESH_HAS_CHOLMOD

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>

#include <lapmesh/internal/memory.h>
#include <lapmesh/internal/subnormals.h>
#include <lapmesh/internal/supernodal_ldlt.h>
#include <lapmesh/internal/supernodal_solve.h>

#include <dlfcn.h>

#include <cstddef>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

namespace lapmesh {
namespace internal {

/// CHOLMOD's last warning or error on this thread. CHOLMOD reports through a C callback
/// without user data, so the message is kept per thread until the caller turns it into a
/// lapmesh exception.
inline std::string& last_cholmod_message()
{
  static thread_local std::string message;
  return message;
}
inline void record_cholmod_message(int status, const char* /*file*/, int /*line*/, const char* message)
{
  last_cholmod_message() = std::string(status > 0 ? "warning " : "error ") + std::to_string(status) + ": " +
                           (message ? message : "(no message)");
}
/// CHOLMOD prints its warnings itself (on stdout, by default) unless told not to: lapmesh
/// reports them in its own exceptions instead.
inline void route_cholmod_messages(cholmod_common& common)
{
  common.print = 0;
  common.error_handler = &record_cholmod_message;
}

/// std::malloc, then huge-page advice for a large block (which glibc has just mapped, untouched).
inline void* malloc_with_huge_page_advice(std::size_t bytes)
{
  void* p = std::malloc(bytes);
  if(p) advise_huge_pages(p, bytes);
  return p;
}
/// std::calloc, then huge-page advice for a large block (glibc does not write a fresh mapping).
inline void* calloc_with_huge_page_advice(std::size_t count, std::size_t size)
{
  void* p = std::calloc(count, size);
  if(p && size > 0 && count <= std::size_t(-1) / size) advise_huge_pages(p, count * size);
  return p;
}

/// Points SuiteSparse's malloc and calloc to the two functions above, where they are still the C
/// library's (once per process). The configuration is found at run time in the SuiteSparse that
/// CHOLMOD loaded, so that programs need not link SuiteSparse_config themselves. SuiteSparse 7
/// reaches it through functions instead: there nothing changes yet. SuiteSparse asks
/// applications to change it before threads start: the change is one pointer store each, to
/// functions that allocate as the ones they replace do, so that a CHOLMOD call in another thread
/// gets a valid allocator either way.
inline void advise_huge_pages_for_cholmod()
{
#if defined(SUITESPARSE_MAIN_VERSION) && SUITESPARSE_MAIN_VERSION < 7
  static const bool installed = [] {
    auto* config = static_cast<SuiteSparse_config_struct*>(dlsym(RTLD_DEFAULT, "SuiteSparse_config"));
    if(!config) return false;
    if(config->malloc_func == &std::malloc) config->malloc_func = &malloc_with_huge_page_advice;
    if(config->calloc_func == &std::calloc) config->calloc_func = &calloc_with_huge_page_advice;
    return true;
  }();
  (void)installed;
#endif
}

/// Makes OpenMP parallel regions inactive in its scope (this thread's setting; with runtimes
/// that keep the setting process-wide, OpenMP regions started meanwhile by other threads run
/// serially too).
class Serial_openmp_scope
{
public:
  Serial_openmp_scope()
  {
    const Entry_points& omp = entry_points();
    if(omp.get && omp.set) {
      m_saved = omp.get();
      omp.set(0);
    }
  }
  ~Serial_openmp_scope()
  {
    if(m_saved >= 0) entry_points().set(m_saved);
  }
  Serial_openmp_scope(const Serial_openmp_scope&) = delete;
  Serial_openmp_scope& operator=(const Serial_openmp_scope&) = delete;

private:
  struct Entry_points
  {
    int (*get)() = nullptr;
    void (*set)(int) = nullptr;
  };
  static const Entry_points& entry_points()
  {
    static const Entry_points omp = [] {
      Entry_points e;
      e.get = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "omp_get_max_active_levels"));
      e.set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"));
      return e;
    }();
    return omp;
  }
  int m_saved = -1;
};

/// CHOLMOD supernodal LL^T of a symmetric matrix given by its lower triangle, with CHOLMOD's
/// OpenMP regions serialised (see above) and access to the fill-reducing permutation.
class Cholmod_supernodal_llt : public Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower>
{
  using Base = Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower>;

public:
  using MatrixType = Eigen::SparseMatrix<double>;

  /// How the fill-reducing ordering is chosen.
  enum class Ordering {
    amd,        ///< AMD only: cheap, the best for a factorisation used once
    amd_or_metis,  ///< AMD, and METIS too where it pays: for memory, when AMD's factor is large
                   ///< (large_factor_entries()) and meets metis_min_flops_per_entry, as such a
                   ///< factor is most of a call's memory and METIS's is much smaller (the smaller
                   ///< of the two is kept); for time, when the planned factorisations
                   ///< (set_planned_factorizations()) of AMD's ordering would take longer than
                   ///< METIS's analysis (metis_min_planned_flops_per_entry) and their time goes
                   ///< into flops (metis_min_flops_per_entry_for_time); the one of fewer flops is
                   ///< kept. METIS's analysis costs several times AMD's.
    metis,      ///< METIS only (analyzePattern() fails where CHOLMOD was built without it)
    given       ///< none: the matrix is already in a fill-reducing, postordered order (the
                ///< permutation() of an earlier analysis applied to it). CHOLMOD then factorises
                ///< the lower triangle as it is; with any other ordering it first makes two
                ///< permuted copies of the matrix, at every factorisation.
  };

  /// Who computes the numeric factor.
  enum class Numeric {
    cholmod,  ///< CHOLMOD's supernodal LL^T
    fastest   ///< where the analysis predicts small supernodes (at most
              ///< lapmesh_max_flops_per_entry() flops per factor entry for the analysed
              ///< supernodes, factorises_by_lapmesh_on()), lapmesh's supernodal
              ///< LDL^T (internal/supernodal_ldlt.h) turned into L L^T in CHOLMOD's factor:
              ///< CHOLMOD calls the BLAS for every supernode, which costs more than the work on
              ///< small ones. CHOLMOD's otherwise.
  };
  /// Takes effect at the next factorize().
  void set_numeric(Numeric numeric) { m_numeric = numeric; }
  /// Whether the last factorize() was lapmesh's (Numeric::fastest chose it).
  bool factorised_by_lapmesh() const { return m_factorised_by_lapmesh; }

  /// How freely columns are merged into supernodes, at the price of explicit zeros in the factor.
  enum class Supernodes {
    merged,  ///< CHOLMOD's default: the largest supernodes, the fastest factorisation
    compact  ///< fewer explicit zeros: a smaller factor, which every solve reads faster; for a
             ///< factorisation that serves many solves (shift-invert Krylov methods), and for
             ///< lapmesh's numeric factorisation of a smoothing step, whose factor is most of
             ///< the step's memory
  };
  /// Above this many flops per factor entry (large supernodes, as on a regular grid or a mesh of
  /// a million vertices) CHOLMOD's BLAS-based numeric factorisation is the faster one. Merged
  /// supernodes are larger for the same flops: the bar is lower for them.
  static double lapmesh_max_flops_per_entry(Supernodes supernodes) { return supernodes == Supernodes::compact ? 600 : 300; }
  /// Whether factorize() makes the factor by lapmesh's numeric factorisation on an analysis with
  /// `supernodes`, by the flops per entry of the last analysis (the supernodes do not change them).
  bool factorises_by_lapmesh_on(Supernodes supernodes)
  {
    return m_numeric == Numeric::fastest && cholmod().fl <= lapmesh_max_flops_per_entry(supernodes) * cholmod().lnz;
  }

  explicit Cholmod_supernodal_llt(Ordering ordering = Ordering::amd)
  {
    advise_huge_pages_for_cholmod();
    route_cholmod_messages(cholmod());
    set_ordering(ordering);
  }
  /// Takes effect at the next analyzePattern().
  void set_supernodes(Supernodes supernodes)
  {
    m_supernodes = supernodes;
    // CHOLMOD merges two adjacent supernodes of ns columns in all when ns <= nrelax[0], when no
    // zero is added, or when the merged share of zeros is below zrelax[0] (ns <= nrelax[1]),
    // zrelax[1] (ns <= nrelax[2]) or zrelax[2].
    const bool merged = supernodes == Supernodes::merged;
    cholmod().nrelax[0] = 4;
    cholmod().nrelax[1] = merged ? 16 : 8;
    cholmod().nrelax[2] = merged ? 48 : 16;
    cholmod().zrelax[0] = merged ? 0.8 : 0.2;
    cholmod().zrelax[1] = merged ? 0.1 : 0.02;
    cholmod().zrelax[2] = merged ? 0.05 : 0.01;
  }
  void set_ordering(Ordering ordering)
  {
    m_ordering = ordering;
    // A postorder of the given order would be a permutation again, and the copies with it.
    cholmod().postorder = ordering != Ordering::given;
    cholmod().nmethods = 1;
    cholmod().method[0].ordering = ordering == Ordering::metis ? CHOLMOD_METIS
                                   : ordering == Ordering::given ? CHOLMOD_NATURAL
                                                                 : CHOLMOD_AMD;
  }
  /// Whether the factor is of the matrix as given (Ordering::given): no permutation to apply.
  bool in_given_order() const { return m_cholmodFactor && m_cholmodFactor->ordering == CHOLMOD_NATURAL; }

  /// CHOLMOD's own bar for trying METIS after AMD: below it METIS's factor is barely smaller.
  static constexpr double metis_min_flops_per_entry = 500;
  /// The factor entries from which Ordering::amd_or_metis tries METIS (256 MiB of values unless set).
  double large_factor_entries() const { return m_large_factor_entries; }
  void set_large_factor_entries(double entries) { m_large_factor_entries = entries; }
  /// METIS's analysis takes about as long as the factorisations it spares where AMD's ordering
  /// would need this many flops, summed over the planned factorisations, per entry of the
  /// matrix's lower triangle: on surface meshes METIS's factor needs far fewer flops than AMD's,
  /// and its analysis costs several AMD analyses. The bar sits above the break-even points
  /// measured on subdivided and CAD meshes (doc/smoothing.md).
  static constexpr double metis_min_planned_flops_per_entry = 6e4;
  /// Below this many flops per factor entry METIS's fewer flops did not always make a
  /// factorisation faster (doc/smoothing.md): the time rule leaves such factors to AMD.
  static constexpr double metis_min_flops_per_entry_for_time = 300;
  /// The entries of A's lower triangle, diagonal included: the size against which the time rule
  /// weighs the planned flops.
  static double lower_entries(const MatrixType& A)
  {
    double entries = 0;
    for(Eigen::Index j = 0; j < A.outerSize(); ++j)
      for(MatrixType::InnerIterator it(A, j); it; ++it) entries += it.row() >= j ? 1 : 0;
    return entries;
  }
  /// The numeric factorisations that the next analysis will serve (Ordering::amd_or_metis).
  void set_planned_factorizations(int factorizations) { m_planned_factorizations = std::max(factorizations, 1); }

  void analyzePattern(const MatrixType& A)
  {
    analyze_once(A);
    if(m_ordering != Ordering::amd_or_metis || info() != Eigen::Success) return;
    const cholmod_common& common = cholmod();
    const bool for_memory = common.lnz >= m_large_factor_entries && common.fl >= metis_min_flops_per_entry * common.lnz;
    const bool for_time = common.fl >= metis_min_flops_per_entry_for_time * common.lnz &&
                          double(m_planned_factorizations) * common.fl >= metis_min_planned_flops_per_entry * lower_entries(A);
    if(!for_memory && !for_time) return;
    const double amd_entries = common.lnz, amd_flops = common.fl;
    cholmod().method[0].ordering = CHOLMOD_METIS;
    analyze_once(A);
    cholmod().method[0].ordering = CHOLMOD_AMD;
    const bool better = (for_memory && common.lnz < amd_entries) || (for_time && common.fl < amd_flops);
    if(info() != Eigen::Success || !better) analyze_once(A);  // missing, or no better
  }
  void factorize(const MatrixType& A)
  {
    Subnormals_flushed_scope flushed;
    m_factorised_by_lapmesh = m_analysisIsOk && m_cholmodFactor->is_super && factorises_by_lapmesh_on(m_analysed_supernodes);
    // The first factorisation of an analysis writes the factor's values, the largest block of
    // the call. Allocated first, they come from glibc's free blocks where those hold them (warm,
    // as in a repeated call) and from fresh pages otherwise; then what else lies free goes back
    // to the system before the values are written, rather than stay resident beside them.
    if(m_analysisIsOk && m_cholmodFactor->xtype == CHOLMOD_PATTERN) {
      if(m_cholmodFactor->is_super &&
         !cholmod_change_factor(CHOLMOD_REAL, true, true, true, true, m_cholmodFactor, &cholmod())) {
        m_factorizationIsOk = true;
        m_info = Eigen::NumericalIssue;  // out of memory, in CHOLMOD's message
        return;
      }
      hand_back_idle_memory();
    }
    if(m_factorised_by_lapmesh) {
      factorize_by_lapmesh(A);
      // Its work space (the update blocks, the per-column lists) lies freed in the heap:
      // handed back, it is not resident beside the next assembly of a smoothing run.
      release_free_heap(std::size_t(16) << 20);
      return;
    }
    Serial_openmp_scope serial;
    Base::factorize(A);
  }
  Cholmod_supernodal_llt& compute(const MatrixType& A)
  {
    analyzePattern(A);
    factorize(A);
    return *this;
  }
  /// Y = D K^-1 D X for a diagonal D = diag(scale) (the shift-invert operator of a standardised
  /// pencil). CHOLMOD's solve allocates its result and work space at every call, permutes blocks
  /// of more than a few columns slowly, and calls the BLAS on every small supernode. Here the
  /// rows are gathered, scaled, into a buffer kept between calls; blocks of 2 to 8 columns are
  /// solved by lapmesh's supernodal kernels (internal/supernodal_solve.h), others by CHOLMOD's
  /// two supernodal triangular solves in place.
  void scaled_solve(const Eigen::VectorXd& scale, const Eigen::Ref<const Eigen::MatrixXd>& X,
                    Eigen::MatrixXd& Y) const
  {
    const int* perm = permutation();
    scaled_solve_by_rows([perm](Eigen::Index i) { return Eigen::Index(perm[i]); }, scale, X, Y);
  }
  /// scaled_solve() for X and Y in the factor's order (row i is row permutation()[i] of the
  /// matrix's order) and `scale` in that order too: no rows to gather. A Krylov run that works
  /// in this order reads its blocks front to back instead of one cache line per value.
  void scaled_solve_in_factor_order(const Eigen::VectorXd& scale, const Eigen::Ref<const Eigen::MatrixXd>& X,
                                    Eigen::MatrixXd& Y) const
  {
    scaled_solve_by_rows([](Eigen::Index i) { return i; }, scale, X, Y);
  }

  /// Solves L L^T X = B in place for a factor in_given_order(): `data` holds the `cols`
  /// right-hand sides column after column. CHOLMOD's solve would allocate the solution and a
  /// permuted copy of the block. A few columns (the three coordinates of a smoothing step) go
  /// through lapmesh's supernodal kernels, in a block of rows made for the solve and freed after
  /// it, so that it is not held beside the next step's assembly.
  bool solve_in_place(double* data, Eigen::Index rows, Eigen::Index cols) const
  {
    if(!supernodal_kernels_fit(std::size_t(cols))) return cholmod_solve_in_place(data, rows, cols);
    const std::size_t width = supernodal_row_width(std::size_t(cols)), n = std::size_t(rows);
    std::vector<double> by_rows(n * width, 0.0);
    for(std::size_t j = 0; j < std::size_t(cols); ++j)
      for(std::size_t i = 0; i < n; ++i) by_rows[i * width + j] = data[j * n + i];
    solve_rows_in_place(by_rows.data(), width);
    for(std::size_t j = 0; j < std::size_t(cols); ++j)
      for(std::size_t i = 0; i < n; ++i) data[j * n + i] = by_rows[i * width + j];
    return true;
  }
  /// Solves L L^T X = B in place for a factor in_given_order() and B held row by row (row i at
  /// rows + i * width), `width` a supernodal_row_width() and the columns past B's zero: no copy.
  void solve_rows_in_place(double* rows, std::size_t width) const { supernodal_solve_rows(factor_view(), rows, width); }

  /// solve_in_place() by CHOLMOD's supernodal solves, for any number of columns.
  bool cholmod_solve_in_place(double* data, Eigen::Index rows, Eigen::Index cols) const
  {
    m_work.resize(Eigen::Index(m_cholmodFactor->maxesize), cols);
    cholmod_dense rhs = dense_view(data, rows, cols), work = dense_view(m_work.data(), m_work.rows(), cols);
    cholmod_common* common = &const_cast<Cholmod_supernodal_llt*>(this)->cholmod();  // its status only
    return cholmod_super_lsolve(m_cholmodFactor, &rhs, &work, common) &&
           cholmod_super_ltsolve(m_cholmodFactor, &rhs, &work, common);
  }

  /// The numeric values of the factor, for a caller that reuses their memory once the factor is
  /// no longer needed (it must factorize() again before the next solve).
  double* values_to_overwrite() { return static_cast<double*>(m_cholmodFactor->x); }

  /// The factor's supernodes and values, for lapmesh's supernodal kernels (after factorize()).
  Supernodal_factor_view factor_view() const
  {
    const cholmod_factor& L = *m_cholmodFactor;
    Supernodal_factor_view view;
    view.super = static_cast<const int*>(L.super);
    view.pi = static_cast<const int*>(L.pi);
    view.px = static_cast<const int*>(L.px);
    view.rows = static_cast<const int*>(L.s);
    view.nsuper = L.nsuper;
    view.values = static_cast<const double*>(L.x);
    return view;
  }
  /// CHOLMOD's factor (its supernodal structure and ordering; nullptr before analyzePattern).
  const cholmod_factor* factor() const { return m_cholmodFactor; }
  /// The fill-reducing ordering: row i of the factor is row perm[i] of the matrix (nullptr
  /// before analyzePattern).
  const int* permutation() const
  {
    return m_cholmodFactor ? static_cast<const int*>(m_cholmodFactor->Perm) : nullptr;
  }

private:
  /// The numeric factor by lapmesh's supernodal L D L^T on CHOLMOD's structure, written into
  /// CHOLMOD's factor as L |D|^1/2, which is CHOLMOD's L D^1/2 when D > 0: the state CHOLMOD's
  /// own factorisation leaves (a failure at a pivot <= 0 included, as CHOLMOD's "not positive
  /// definite"). The factor holds values already (factorize() allocates them first).
  void factorize_by_lapmesh(const MatrixType& A)
  {
    cholmod_factor* L = m_cholmodFactor;
    m_factorizationIsOk = true;
    m_info = Eigen::NumericalIssue;
    // On a view of the factor's structure. Kept for the next factorisation where the analysis
    // serves several (a smoothing run): made afresh, its arrays fault in their pages again at
    // every step. Made for this factorisation alone otherwise: kept, its work space would add
    // to the memory of the solves.
    std::optional<Supernodal_ldlt> single_use;
    std::optional<Supernodal_ldlt>& slot = m_planned_factorizations > 1 ? m_kept_ldlt : single_use;
    if(!slot) slot.emplace(*L, Supernodal_ldlt::Structure_use::view);
    Supernodal_ldlt& ldlt = *slot;
    // A matrix in the given order is already in the factor's order: no permuted copy.
    const MatrixType permuted = in_given_order() ? MatrixType() : ldlt.permuted_lower(A);
    const MatrixType& lower = in_given_order() ? A : permuted;
    if(!ldlt.factorize_in(static_cast<double*>(L->x), lower, Eigen::VectorXd(), 0.0) ||
       !ldlt.positive_definite()) {
      L->minor = 0;  // which pivot failed matters to no caller
      return;
    }
    L->minor = L->n;
    m_info = Eigen::Success;
  }

  void analyze_once(const MatrixType& A)
  {
    m_kept_ldlt.reset();  // it views the structure of the factor that the analysis replaces
    {
      Serial_openmp_scope serial;
      Base::analyzePattern(A);
    }
    // The analysis's work space (a few integers per row, kept in the common block for the next
    // call) is read neither by lapmesh's factorisation nor by its solves: freed, it is not
    // resident beside the factor; a CHOLMOD routine that needs it allocates it again.
    cholmod_free_work(&cholmod());
    m_analysed_supernodes = m_supernodes;
    release_free_heap(std::size_t(64) << 20);  // the analysis's work space, before the factor
  }

  Ordering m_ordering = Ordering::amd;
  Numeric m_numeric = Numeric::cholmod;
  Supernodes m_supernodes = Supernodes::merged, m_analysed_supernodes = Supernodes::merged;
  bool m_factorised_by_lapmesh = false;
  double m_large_factor_entries = double((std::size_t(256) << 20) / sizeof(double));
  int m_planned_factorizations = 1;

  /// Y = D K^-1 D X with row i of the factor's system taken from (and written to) row
  /// row_of(i) of X, Y and scale.
  template <typename RowOf>
  void scaled_solve_by_rows(const RowOf& row_of, const Eigen::VectorXd& scale, const Eigen::Ref<const Eigen::MatrixXd>& X,
                            Eigen::MatrixXd& Y) const
  {
    // The kernels take the values of a row side by side, CHOLMOD a column-major block.
    if(supernodal_kernels_fit(std::size_t(X.cols()))) {
      supernodal_scaled_solve(factor_view(), row_of, scale.data(), X, Y, m_rhs);
      return;
    }
    const Eigen::Index n = X.rows(), nrhs = X.cols();
    m_rhs.resize(std::size_t(n) * std::size_t(nrhs));
    for(Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index r = row_of(i);
      for(Eigen::Index j = 0; j < nrhs; ++j) m_rhs[std::size_t(i + j * n)] = scale[r] * X(r, j);
    }
    cholmod_solve_in_place(m_rhs.data(), n, nrhs);
    Y.resize(n, nrhs);
    for(Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index r = row_of(i);
      for(Eigen::Index j = 0; j < nrhs; ++j) Y(r, j) = scale[r] * m_rhs[std::size_t(i + j * n)];
    }
  }

  /// A column-major rows x cols block at `data`, as CHOLMOD's dense type (no copy).
  static cholmod_dense dense_view(double* data, Eigen::Index rows, Eigen::Index cols)
  {
    cholmod_dense d{};
    d.nrow = std::size_t(rows);
    d.ncol = std::size_t(cols);
    d.nzmax = std::size_t(rows * cols);
    d.d = std::size_t(rows);
    d.x = data;
    d.xtype = CHOLMOD_REAL;
    d.dtype = CHOLMOD_DOUBLE;
    return d;
  }
  std::optional<Supernodal_ldlt> m_kept_ldlt;  // lapmesh's factorisation on the last analysis
  mutable std::vector<double> m_rhs;  // scaled_solve()'s right-hand sides, permuted and scaled
  mutable Eigen::MatrixXd m_work;     // CHOLMOD's work space
};

} // namespace internal
} // namespace lapmesh

#endif // LAPMESH_HAS_CHOLMOD
#endif
