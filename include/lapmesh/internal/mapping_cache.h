// Internal: the mappings of lapmesh's large working arrays, kept for the next call.
//
// Why: a call on a large mesh maps its working arrays (the topology, the extracted triangles,
// the corner geometry) apart from glibc's heap, on whole huge pages (internal/memory.h). Unmapped
// at the end of the call, they come back from the kernel at the next call, zeroed page by page:
// on a mesh of a few 100k vertices that is slower than glibc's heap, which keeps its blocks
// warm, and in glibc's heap those arrays would instead take it past its trim threshold on larger
// meshes, so that every call faults its blocks in again one 4 KiB page at a time. Kept here, a
// freed mapping serves the next array that fits in it, warm, with no fault.
//
// The bounds: the cache holds at most working_memory_cache_limit() bytes (1 GiB, or an eighth of
// the physical memory where that is less; set_working_memory_cache_limit() changes it, 0 turns
// the cache off), at most max_entries mappings, and none beside a new mapping: a request that
// no cached mapping fits unmaps them all first, so that lapmesh's own arrays never need more
// memory than they would without the cache. A computation about to allocate much memory of
// another kind (a sparse factorisation) empties it as well (release_working_memory()).
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

/// Freed mappings of whole pages, each of a known size, reused by size (best fit). Process-wide
/// and thread-safe. Every function is noexcept: a mapping that cannot be kept is unmapped.
class Mapping_cache
{
public:
  static constexpr std::size_t max_entries = 64;
  static constexpr std::size_t default_limit = std::size_t(1) << 30;

  /// The process's cache. Never destroyed: arrays in static storage may be freed after it would be.
  static Mapping_cache& instance() noexcept
  {
    alignas(Mapping_cache) static unsigned char storage[sizeof(Mapping_cache)];
    static Mapping_cache* cache = ::new(static_cast<void*>(storage)) Mapping_cache();
    return *cache;
  }

  /// A cached mapping of exactly `bytes` (the smallest that holds them, its tail unmapped), or
  /// nullptr; on nullptr nothing is cached any more, so that the caller's new mapping does not
  /// lie beside cached ones.
  void* take(std::size_t bytes) noexcept
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    std::size_t best = m_count;
    for(std::size_t i = 0; i < m_count; ++i)
      if(m_entries[i].bytes >= bytes && (best == m_count || m_entries[i].bytes < m_entries[best].bytes)) best = i;
    if(best == m_count) {
      unmap_all();
      return nullptr;
    }
    const Entry e = m_entries[best];
    erase(best);
    if(e.bytes > bytes) unmap(static_cast<char*>(e.address) + bytes, e.bytes - bytes);
    return e.address;
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

  Mapping_cache() noexcept : m_limit(std::min(default_limit, physical_memory() / 8)) {}

  static std::size_t physical_memory() noexcept
  {
#if defined(__linux__)
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    if(pages > 0 && page > 0) return std::size_t(pages) * std::size_t(page);
#endif
    return default_limit * 8;
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

  mutable std::mutex m_mutex;
  Entry m_entries[max_entries] = {};
  std::size_t m_count = 0, m_total = 0, m_limit;
};

} // namespace internal
} // namespace lapmesh

#endif
