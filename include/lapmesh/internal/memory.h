// Internal: how the large arrays of a call meet the memory system.
//
// Why huge pages: a large mesh is processed in arrays of tens to hundreds of MiB, written once
// and freed at the end of the call. glibc maps every block over its mmap threshold (at most
// 32 MiB) afresh from the kernel at each call, and hands the top of its heap back when a call
// frees more than its trim threshold, so the blocks of each call fault in again, one 4 KiB page
// at a time; on virtual machines each fault is expensive. Where the kernel gives transparent
// huge pages on request (`/sys/kernel/mm/transparent_hugepage/enabled` set to `madvise`; with
// `always` it does so anyway, with `never` not at all), a fresh block advised before its first
// write faults in 2 MiB pages instead. lapmesh's working arrays (Working_array: the topology, the
// extracted triangles, the corner geometry) of at least 4 MiB get mappings of their own, on 2 MiB
// boundaries and advised whole (allocate_large()): together they would take the heap past its
// trim threshold. Freed, such a mapping is kept for the next call's arrays (mapping_cache.h),
// which find its pages warm, as glibc's heap would have kept them below its trim threshold. The
// working arrays from 256 KiB to 4 MiB are mappings of their own as well, in small pages, kept for
// the next array of their size: in glibc's heap, other code's frees (the caller's) may take it past
// its trim threshold between two calls, and the next call's blocks would be faulted in afresh.
// Where a fault is a trip to the hypervisor, a burst of 4 KiB faults also slows the next pass over
// other memory (the caller's mesh), likely because its mappings fall out of the hypervisor's
// caches. The blocks of Eigen's arrays come from glibc: only those of at least 32 MiB, which glibc
// maps apart, are advised, on the whole 2 MiB pages inside them, so memory outside a block is
// never affected; advising smaller ones, inside glibc's heap, measured slower on the project's
// 2-core test machine (doc/benchmarks-history.md). `LAPMESH_HUGE_PAGES=0` in the environment
// turns both off, and the working arrays' mappings with them (read once per process).
//
// Why populating: where no huge page is to be had (transparent huge pages off, or physical
// memory too fragmented for 2 MiB pages), an Eigen result of at least 32 MiB that is written whole
// right after it is sized has its pages made present by one madvise(MADV_POPULATE_WRITE) call
// (Linux 5.14 on; an older kernel refuses it and nothing changes): the kernel still zeroes every
// page, but without a trip through the fault handler for each one (prepare_for_writing()). Where
// several threads write it, they make its pages present together, one call per huge page.
//
// Why prefetches: the passes over corners read the triangles and positions at the indices of
// the neighbours, which on a large mesh miss the caches; the addresses are known a few
// vertices or faces ahead, so the loads can be started early.
#ifndef LAPMESH_INTERNAL_MEMORY_H
#define LAPMESH_INTERNAL_MEMORY_H

#include <lapmesh/huge_pages.h>
#include <lapmesh/internal/mapping_cache.h>
#include <lapmesh/internal/parallel.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace lapmesh {
namespace internal {

/// glibc's largest mmap threshold: smaller blocks of glibc's are not advised.
constexpr std::size_t huge_page_advice_min_bytes = std::size_t(32) << 20;

/// `x` rounded down to a whole number of huge pages.
constexpr std::uintptr_t round_down_to_huge_pages(std::uintptr_t x) noexcept
{
  return x & ~std::uintptr_t(huge_page_bytes - 1);
}

/// `x` rounded up to a whole number of huge pages.
constexpr std::uintptr_t round_up_to_huge_pages(std::uintptr_t x) noexcept
{
  return round_down_to_huge_pages(x + huge_page_bytes - 1);
}

/// Advises transparent huge pages for the whole 2 MiB pages inside [p, p + bytes), a block
/// that has not been written yet. A hint only: nothing changes where the kernel or the
/// platform does not support it.
inline void advise_huge_pages(const void* p, std::size_t bytes) noexcept
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if(bytes < huge_page_advice_min_bytes || !huge_pages_enabled()) return;
  const std::uintptr_t begin = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t first = round_up_to_huge_pages(begin), last = round_down_to_huge_pages(begin + bytes);
  if(last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

/// Blocks of at least this size that lapmesh allocates for itself (its working arrays) are
/// mapped apart on 2 MiB boundaries, in huge pages, and cached when freed: glibc would put those
/// under its mmap threshold in its heap, which it trims at the end of the call, so that the next
/// call faults them in again one 4 KiB page at a time; and it maps the others a few KiB off a
/// 2 MiB boundary, leaving their first and last 2 MiB in small pages.
constexpr std::size_t huge_page_mapping_min_bytes = std::size_t(4) << 20;

/// Working arrays of at least this size, and under huge_page_mapping_min_bytes, are mapped apart
/// in small pages: smaller ones take few faults in glibc's heap, and would crowd the cache.
constexpr std::size_t small_mapping_min_bytes = std::size_t(256) << 10;

/// Where allocate_large() puts a block (a function of the size alone, so that deallocate_large()
/// takes the same branch).
enum class Block_place
{
  heap,               ///< operator new
  small_page_mapping, ///< a mapping of its own in small pages, cached by its exact size
  huge_page_mapping   ///< a mapping of its own in huge pages, cached by best fit
};

inline Block_place block_place(std::size_t bytes) noexcept
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if(!huge_pages_enabled() || bytes < small_mapping_min_bytes) return Block_place::heap;
  return bytes < huge_page_mapping_min_bytes ? Block_place::small_page_mapping : Block_place::huge_page_mapping;
#else
  (void)bytes;
  return Block_place::heap;
#endif
}

/// The system's page size (read once per process).
inline std::size_t system_page_bytes() noexcept
{
#if defined(__linux__)
  static const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE) > 0 ? sysconf(_SC_PAGESIZE) : 4096);
  return page;
#else
  return 4096;
#endif
}

/// The bytes that a block of `bytes` placed at `place` (not the heap) maps: whole small or huge
/// pages. Less than `bytes` only where rounding up overflows.
inline std::size_t mapped_bytes(Block_place place, std::size_t bytes) noexcept
{
  const std::size_t page = place == Block_place::huge_page_mapping ? huge_page_bytes : system_page_bytes();
  return (bytes + page - 1) / page * page;
}

/// The cache of a mapping's place.
inline Mapping_cache& cache_of(Block_place place) noexcept
{
  return place == Block_place::small_page_mapping ? Mapping_cache::small_arrays() : Mapping_cache::large_arrays();
}

#if defined(__linux__) && defined(MADV_HUGEPAGE)
/// A new private mapping of `bytes` bytes (whole pages), read and written. Throws std::bad_alloc.
inline void* map_fresh_pages(std::size_t bytes)
{
  void* mapped = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if(mapped == MAP_FAILED) throw std::bad_alloc();
  return mapped;
}
#endif

/// `bytes` of memory, not initialised: a block of whole 2 MiB pages advised huge (a cached one that
/// holds it, else a new mapping that takes over the cached pages first, mapping_cache.h), a block of
/// whole small pages (a cached one of its size, else a new mapping), or one from operator new, as
/// block_place() says. Throws std::bad_alloc.
inline void* allocate_large(std::size_t bytes)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  const Block_place place = block_place(bytes);
  if(place != Block_place::heap) {
    const std::size_t size = mapped_bytes(place, bytes);
    if(size < bytes) throw std::bad_alloc();
    Mapping_cache& cache = cache_of(place);
    if(void* cached = cache.take(size)) return cached;
    if(place == Block_place::small_page_mapping) return map_fresh_pages(size);
    // Map one huge page more and unmap what lies outside the first aligned block.
    void* mapped = map_fresh_pages(size + huge_page_bytes);
    const std::uintptr_t begin = reinterpret_cast<std::uintptr_t>(mapped);
    const std::uintptr_t first = round_up_to_huge_pages(begin);
    if(first > begin) munmap(mapped, first - begin);
    munmap(reinterpret_cast<void*>(first + size), begin + huge_page_bytes - first);
    madvise(reinterpret_cast<void*>(first), size, MADV_HUGEPAGE);
    cache.move_into(reinterpret_cast<void*>(first), size);
    return reinterpret_cast<void*>(first);
  }
#endif
  return ::operator new(bytes);
}

/// While true, deallocate_large() hands mappings back to the system (release_to_system()).
inline bool& bypassing_mapping_cache() noexcept
{
  thread_local bool bypassing = false;
  return bypassing;
}

/// Frees a block of allocate_large(bytes); a mapping goes to its cache where it fits. A small
/// array's mapping is kept even while bypassing_mapping_cache(): handed back, it would be mapped
/// and faulted in afresh at the next call, for little memory.
inline void deallocate_large(void* p, std::size_t bytes) noexcept
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  const Block_place place = block_place(bytes);
  if(place != Block_place::heap) {
    const std::size_t size = mapped_bytes(place, bytes);
    const bool bypass = place == Block_place::huge_page_mapping && bypassing_mapping_cache();
    if(bypass || !cache_of(place).keep(p, size)) munmap(p, size);
    return;
  }
#endif
  ::operator delete(p);
}

/// std::allocator whose resize() leaves integers unset instead of zeroing them, and whose blocks
/// of at least small_mapping_min_bytes are mappings of their own (allocate_large()).
/// lapmesh's own large arrays are written in full right after they are sized, in parallel under
/// CGAL::Parallel_tag: zeroing them first would be a serial pass that also takes the page faults
/// of every fresh page on one thread.
template <typename T>
struct Working_array_allocator : std::allocator<T>
{
  template <typename U>
  struct rebind
  {
    using other = Working_array_allocator<U>;
  };
  Working_array_allocator() = default;
  template <typename U>
  Working_array_allocator(const Working_array_allocator<U>&) noexcept
  {}
  T* allocate(std::size_t count)
  {
    if(count > std::size_t(-1) / sizeof(T)) throw std::bad_alloc();
    return static_cast<T*>(allocate_large(count * sizeof(T)));
  }
  void deallocate(T* p, std::size_t count) noexcept { deallocate_large(p, count * sizeof(T)); }
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value)
  {
    ::new(static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args)
  {
    ::new(static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A working array of a call (the topology's arrays, the extracted triangles and vertices, the
/// corner geometry): a std::vector that resize() does not zero, in a cached mapping of its own
/// from 256 KiB on (in huge pages from 4 MiB), in glibc's heap below.
template <typename T>
using Working_array = std::vector<T, Working_array_allocator<T>>;

/// Hands the cached mappings of large arrays back to the system, before a computation that
/// allocates much memory of another kind (a sparse factorisation), which they would otherwise
/// lie beside at its peak. Those of small arrays stay cached, as glibc's heap keeps its freed
/// blocks: an implicit step that refactorises at every iteration would otherwise fault the small
/// arrays of each iteration's assembly in afresh.
inline void release_cached_large_arrays() noexcept { Mapping_cache::large_arrays().release(); }

/// Empties `array` and hands its memory back to the system, not to the cache of mappings: for
/// memory that allocations outside working arrays (a result's Eigen matrix) are about to need,
/// and which the cache could not give them. A mapping under 4 MiB is cached all the same (see
/// deallocate_large()).
template <typename T>
void release_to_system(Working_array<T>& array) noexcept
{
  bool& bypassing = bypassing_mapping_cache();
  const bool was = bypassing;
  bypassing = true;
  Working_array<T>().swap(array);
  bypassing = was;
}

/// advise_huge_pages() for the values of a dense Eigen array, sized and not yet written.
template <typename Derived>
void advise_huge_pages(const Eigen::PlainObjectBase<Derived>& array) noexcept
{
  advise_huge_pages(array.data(), sizeof(typename Derived::Scalar) * std::size_t(array.size()));
}

/// advise_huge_pages() for the values and inner indices of a sparse matrix sized by
/// resizeNonZeros() and not yet written. Their size is the storage's: nonZeros() reads the outer
/// indices, which are not written yet either.
template <typename Scalar, int Options, typename StorageIndex>
void advise_huge_pages(const Eigen::SparseMatrix<Scalar, Options, StorageIndex>& matrix) noexcept
{
  const std::size_t nnz = std::size_t(matrix.data().size());
  advise_huge_pages(matrix.valuePtr(), sizeof(Scalar) * nnz);
  advise_huge_pages(matrix.innerIndexPtr(), sizeof(StorageIndex) * nnz);
}

/// Makes the pages of [p, p + bytes), a fresh block of at least 32 MiB about to be written whole,
/// present at once (see above). Not for a block that may stay partly unwritten: its pages would
/// count in the process's memory all the same. `parallel`: one call per huge page of the block,
/// spread over the threads, so that they zero the pages together.
inline void populate_for_writing(const void* p, std::size_t bytes, bool parallel = false) noexcept
{
#if defined(__linux__)
#ifdef MADV_POPULATE_WRITE
  constexpr int populate_write = MADV_POPULATE_WRITE;
#else
  constexpr int populate_write = 23;  // the value of Linux's uapi, which older C libraries do not name
#endif
  if(bytes < huge_page_advice_min_bytes) return;
  const std::uintptr_t page = system_page_bytes();
  const std::uintptr_t begin = reinterpret_cast<std::uintptr_t>(p) / page * page;
  // Pieces counted from the huge page that holds the first byte: no two threads fault in the same
  // huge page.
  const std::uintptr_t origin = round_down_to_huge_pages(begin);
  const std::size_t span = std::size_t(reinterpret_cast<std::uintptr_t>(p) + bytes - origin);
  for_each_part(span, parallel ? huge_page_bytes : span, parallel, [&](std::size_t, std::size_t from, std::size_t to) {
    const std::uintptr_t first = std::max(begin, origin + from);
    madvise(reinterpret_cast<void*>(first), origin + to - first, populate_write);
  });
#else
  (void)p;
  (void)bytes;
  (void)parallel;
#endif
}

/// A dense Eigen array, sized and about to be written whole: advise_huge_pages(), then
/// populate_for_writing(), by several threads where several write it (`parallel`): threads that
/// fault the pages in as they write took longer than populating calls before them
/// (doc/benchmarks.md).
template <typename Derived>
void prepare_for_writing(const Eigen::PlainObjectBase<Derived>& array, bool parallel = false) noexcept
{
  advise_huge_pages(array);
  populate_for_writing(array.data(), sizeof(typename Derived::Scalar) * std::size_t(array.size()), parallel);
}

/// The values and inner indices of a sparse matrix sized by resizeNonZeros(), about to be written
/// whole: as for a dense array.
template <typename Scalar, int Options, typename StorageIndex>
void prepare_for_writing(const Eigen::SparseMatrix<Scalar, Options, StorageIndex>& matrix, bool parallel = false) noexcept
{
  advise_huge_pages(matrix);
  const std::size_t nnz = std::size_t(matrix.data().size());
  populate_for_writing(matrix.valuePtr(), sizeof(Scalar) * nnz, parallel);
  populate_for_writing(matrix.innerIndexPtr(), sizeof(StorageIndex) * nnz, parallel);
}

/// Frees the storage of a sparse matrix, which becomes empty. Assigning an empty matrix would
/// not: Eigen 3.4 copies into the existing storage and keeps its capacity.
template <typename Scalar, int Options, typename StorageIndex>
void release(Eigen::SparseMatrix<Scalar, Options, StorageIndex>& matrix) noexcept
{
  Eigen::SparseMatrix<Scalar, Options, StorageIndex>().swap(matrix);
}

/// Hands the free memory inside glibc's heap back to the system when at least `min_bytes` of it
/// lie unused. A symbolic analysis (METIS's graphs, AMD's work space) frees many blocks under
/// the mmap threshold between blocks it keeps: glibc can neither trim them, being below live
/// blocks, nor reuse them for the factor that follows, which is mapped apart, so they would stay
/// resident through every factorisation. No effect outside glibc.
inline void release_free_heap(std::size_t min_bytes) noexcept
{
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  if(mallinfo2().fordblks >= min_bytes) malloc_trim(0);
#else
  (void)min_bytes;
#endif
}

/// Hands back to the system the memory that the process holds for lapmesh but that no array
/// uses: the cached mappings of both sizes and the free pages of glibc's heap. Before a sparse
/// factor's values are first written: they are the largest block of a call (of a one-step
/// implicit smoothing, most of its peak), and the arrays that the call's assembly and analysis
/// freed before would otherwise stay resident beside them. The price: the next call touches
/// those pages afresh (allocated before this, the values keep a block that glibc kept warm).
inline void hand_back_idle_memory() noexcept
{
  Mapping_cache::release_both();
  release_free_heap(std::size_t(1) << 20);
}

/// Starts loading the cache line at p (a hint; no effect where the compiler has none).
inline void prefetch(const void* p) noexcept
{
#if defined(__GNUC__)
  __builtin_prefetch(p);
#else
  (void)p;
#endif
}

/// How many nonzeros ahead a product of a sparse matrix with per-vertex values prefetches the
/// values it gathers through the inner indices: on a large mesh the neighbours' values lie far
/// apart in memory, and with a handful of nonzeros per row the loads must start many rows early
/// to hide their latency.
constexpr int sparse_gather_prefetch_distance = 128;

} // namespace internal
} // namespace lapmesh

#endif
