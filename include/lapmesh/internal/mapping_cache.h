// Internal: the mappings of lapmesh's working arrays, kept for the next call.
//
// Why: a call on a large mesh maps its working arrays (the topology, the extracted triangles,
// the corner geometry) apart from glibc's heap, on whole huge pages (internal/memory.h). Unmapped
// at the end of the call, they come back from the kernel at the next call, zeroed page by page:
// on a mesh of a few 100k vertices that is slower than glibc's heap, which keeps its blocks
// warm, and in glibc's heap those arrays would instead take it past its trim threshold on larger
// meshes, so that every call faults its blocks in again one 4 KiB page at a time. Kept here, a
// freed mapping serves the next array that fits in it, warm, with no fault.
//
// How a request is served: from the smallest cached mapping that holds it, whose tail stays
// cached; where none does, a new mapping takes over the pages of the cached ones (mremap moves
// them, written as they are, without copying) and faults in fresh pages only for the rest. The
// arrays of a call come in another order than they were freed (a call's small arrays first, its
// large ones after), so with whole mappings only, the small arrays would take the large mappings
// apart and the large arrays find nothing left that fits.
//
// Arrays under 4 MiB (from 256 KiB on) have a cache of their own, in small pages, where a mapping
// serves only an array of exactly its size: otherwise glibc's heap holds them, and where other
// code's frees have taken the heap past its trim threshold, they are faulted in afresh at every
// call. Carved by a smaller array, as the large mappings are, such a mapping would no longer hold
// the array it came from at the next call, which would then map fresh pages; among arrays of one
// mesh the same sizes come back at every call.
//
// The bounds: the two caches hold at most working_memory_cache_limit() bytes together (1 GiB, or
// an eighth of the physical memory where that is less, a sixteenth of it for the small arrays;
// set_working_memory_cache_limit() changes it, 0 turns the caches off), each in at most
// max_entries mappings, and no fresh page is faulted in while a cached large one is left:
// lapmesh's own arrays never need more memory than they would without the caches. A computation
// about to allocate much memory of another kind (a sparse factorisation) hands the large mappings
// back (release_cached_large_arrays()); the small ones stay, as freed blocks in glibc's heap would,
// until a sparse factor's values are first written, before which both go (hand_back_idle_memory()).
// A call that takes nothing from the caches and allocates only its result (the uniform stiffness)
// hands both back before it (release_working_memory()): the heap's freed blocks could serve that
// result, the cached mappings cannot.
#ifndef LAPMESH_INTERNAL_MAPPING_CACHE_H
#define LAPMESH_INTERNAL_MAPPING_CACHE_H

#include <algorithm>
#include <cstddef>
#include <mutex>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace lapmesh {
namespace internal {

/// The size of a transparent huge page on x86-64 and arm64 with 4 KiB base pages.
constexpr std::size_t huge_page_bytes = std::size_t(1) << 21;

/// Freed mappings of whole pages, each of a known size, reused by size (best fit, or exact
/// sizes only). Process-wide and thread-safe. Every function is noexcept: a mapping that cannot
/// be kept is unmapped.
class Mapping_cache
{
public:
  static constexpr std::size_t max_entries = 64;
  static constexpr std::size_t default_limit = std::size_t(1) << 30;
  /// The small arrays' cache gets one part in this many of a limit of both caches.
  static constexpr std::size_t small_arrays_share = 16;

  /// The process's cache of the mappings of large arrays, in huge pages (best fit, carved).
  static Mapping_cache& large_arrays() noexcept { return process_cache<false>(); }
  /// The process's cache of the mappings of small arrays, in small pages (exact sizes).
  static Mapping_cache& small_arrays() noexcept { return process_cache<true>(); }

  /// The two caches together, as the public functions of huge_pages.h see them.
  static std::size_t total_cached_bytes() noexcept
  {
    return large_arrays().cached_bytes() + small_arrays().cached_bytes();
  }
  static std::size_t release_both() noexcept { return large_arrays().release() + small_arrays().release(); }
  static std::size_t total_limit() noexcept { return large_arrays().limit() + small_arrays().limit(); }
  /// Splits `bytes` between the caches: the small arrays' share, the rest for the large ones.
  static void set_total_limit(std::size_t bytes) noexcept
  {
    small_arrays().set_limit(share_of(bytes, true));
    large_arrays().set_limit(share_of(bytes, false));
  }

  /// A cached mapping of `bytes` bytes (whole pages): the head of the smallest one that holds
  /// them, its tail kept in the cache, or with exact sizes one of exactly that size; nullptr where
  /// none is.
  void* take(std::size_t bytes) noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    std::size_t best = m_count;
    for(std::size_t i = 0; i < m_count; ++i) {
      const std::size_t size = m_entries[i].bytes;
      if(m_exact_sizes ? size == bytes : size >= bytes && (best == m_count || size < m_entries[best].bytes)) best = i;
    }
    return best == m_count ? nullptr : take_head(best, bytes);
  }

  /// Moves the cached mappings, oldest first, over the start of [address, address + bytes), a
  /// new mapping of whole huge pages not written yet, until it is full or the cache empty (the
  /// last one moved may leave its tail cached). A part the kernel does not move (a mapping it has
  /// split into areas of other attributes) is unmapped instead: its place in the new mapping is
  /// faulted in fresh. For the large arrays' cache only: exact sizes are never carved.
  void move_into(void* address, std::size_t bytes) noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    for(std::size_t moved = 0; m_count > 0 && moved < bytes;) {
      const std::size_t part = std::min(m_entries[0].bytes, bytes - moved);
      move_pages(static_cast<char*>(take_head(0, part)), static_cast<char*>(address) + moved, part);
      moved += part;
    }
  }

  /// Keeps the mapping [address, address + bytes) for a later take(); false (nothing kept) when
  /// it does not fit under the limit. The oldest mappings make room for it.
  bool keep(void* address, std::size_t bytes) noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    if(bytes > m_limit) return false;
    while(m_count > 0 && (m_count == max_entries || m_total + bytes > m_limit)) evict_oldest();
    m_entries[m_count++] = Entry{address, bytes};
    m_total += bytes;
    return true;
  }

  /// Unmaps every cached mapping; returns the bytes handed back.
  std::size_t release() noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    const std::size_t bytes = m_total;
    unmap_all();
    return bytes;
  }

  std::size_t cached_bytes() const noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    return m_total;
  }
  std::size_t limit() const noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    return m_limit;
  }
  /// A lower limit hands back the oldest mappings over it at once.
  void set_limit(std::size_t bytes) noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    m_limit = bytes;
    while(m_count > 0 && m_total > m_limit) evict_oldest();
  }

private:
  struct Entry
  {
    void* address;
    std::size_t bytes;
  };

  explicit Mapping_cache(bool exact_sizes) noexcept
    : m_exact_sizes(exact_sizes), m_limit(share_of(std::min(default_limit, physical_memory() / 8), exact_sizes))
  {}

  /// Never destroyed: arrays in static storage may be freed after it would be.
  template <bool ExactSizes>
  static Mapping_cache& process_cache() noexcept
  {
    alignas(Mapping_cache) static unsigned char storage[sizeof(Mapping_cache)];
    static Mapping_cache* cache = ::new(static_cast<void*>(storage)) Mapping_cache(ExactSizes);
    return *cache;
  }
  /// The part of a limit of both caches that the small arrays' cache (exact sizes) or the large
  /// arrays' one gets.
  static std::size_t share_of(std::size_t total, bool exact_sizes) noexcept
  {
    return exact_sizes ? total / small_arrays_share : total - total / small_arrays_share;
  }

  static std::size_t physical_memory() noexcept
  {
#if defined(__linux__)
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    if(pages > 0 && page > 0) return std::size_t(pages) * std::size_t(page);
#endif
    return default_limit * 8;
  }
  /// The first `bytes` of entry i, taken out of the cache; the rest of it stays cached.
  void* take_head(std::size_t i, std::size_t bytes) noexcept
  {
    Entry& e = m_entries[i];
    void* head = e.address;
    if(e.bytes == bytes) {
      erase(i);
    } else {
      e.address = static_cast<char*>(e.address) + bytes;
      e.bytes -= bytes;
      m_total -= bytes;
    }
    return head;
  }
  /// Moves the pages of [from, from + bytes) to [to, to + bytes), replacing what lies there.
  /// mremap moves one area of the kernel's at a time: a range that spans several is halved, on
  /// huge page boundaries, until each part lies in one.
  static void move_pages(char* from, char* to, std::size_t bytes) noexcept
  {
#if defined(__linux__) && defined(MREMAP_FIXED)
    if(mremap(from, bytes, bytes, MREMAP_MAYMOVE | MREMAP_FIXED, to) != MAP_FAILED) return;
    if(bytes > huge_page_bytes) {
      const std::size_t half = (bytes / 2 + huge_page_bytes - 1) / huge_page_bytes * huge_page_bytes;
      move_pages(from, to, half);
      move_pages(from + half, to + half, bytes - half);
      return;
    }
#else
    (void)to;
#endif
    unmap(from, bytes);
  }
  static void unmap(void* address, std::size_t bytes) noexcept
  {
#if defined(__linux__)
    munmap(address, bytes);
#else
    (void)address;
    (void)bytes;
#endif
  }
  void unmap_all() noexcept
  {
    for(std::size_t i = 0; i < m_count; ++i) unmap(m_entries[i].address, m_entries[i].bytes);
    m_count = 0;
    m_total = 0;
  }
  void evict_oldest() noexcept
  {
    unmap(m_entries[0].address, m_entries[0].bytes);
    erase(0);
  }
  /// Removes entry i, keeping the others oldest first.
  void erase(std::size_t i) noexcept
  {
    m_total -= m_entries[i].bytes;
    std::copy(m_entries + i + 1, m_entries + m_count, m_entries + i);
    --m_count;
  }

  const bool m_exact_sizes;
  mutable std::mutex m_mutex;
  Entry m_entries[max_entries] = {};
  std::size_t m_count = 0, m_total = 0, m_limit;
};

} // namespace internal
} // namespace lapmesh

#endif
