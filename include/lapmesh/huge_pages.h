// lapmesh — the switch for transparent huge pages, and the cache of working memory.
//
// Large meshes are processed in large arrays that the system maps afresh at every call; lapmesh
// asks for transparent huge pages for them (internal/memory.h), and the command line restarts
// itself with glibc's huge-page tunable for large inputs. `LAPMESH_HUGE_PAGES=0` in the
// environment turns both off.
//
// lapmesh's own working arrays of 256 KiB or more (on meshes of some thousands of vertices and
// up) are mappings of their own, in huge pages from 4 MiB on. When a call frees them, lapmesh
// keeps them, up to a limit, for the next call, which then finds its arrays warm instead of
// faulted in and zeroed by the kernel page by page (internal/mapping_cache.h). A sparse
// factorisation (implicit smoothing, the eigenpairs) hands them back before it first writes its
// factor, the largest block of such a call, rather than hold them beside it; the uniform stiffness,
// which needs no working array, hands them all back before it allocates its matrix. A program that is
// done with large meshes, or keeps memory tight, hands them back with release_working_memory() or
// lowers the limit. `LAPMESH_HUGE_PAGES=0` also keeps the working arrays in the C++ heap.
#ifndef LAPMESH_HUGE_PAGES_H
#define LAPMESH_HUGE_PAGES_H

#include <lapmesh/internal/mapping_cache.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>

namespace lapmesh {

/// The environment variable that turns huge pages off.
constexpr const char* huge_pages_variable = "LAPMESH_HUGE_PAGES";

/// True for the value of huge_pages_variable that turns huge pages off ("0"); `value` is
/// nullptr when the variable is unset.
inline bool huge_pages_switched_off(const char* value) { return value && std::strcmp(value, "0") == 0; }

/// False when the environment turns huge pages off (read once per process).
inline bool huge_pages_enabled()
{
  static const bool enabled = !huge_pages_switched_off(std::getenv(huge_pages_variable));
  return enabled;
}

/// Bytes of freed working memory that lapmesh keeps mapped for its next calls.
inline std::size_t cached_working_memory() { return internal::Mapping_cache::total_cached_bytes(); }

/// Hands the cached working memory back to the system; returns how many bytes that was.
inline std::size_t release_working_memory() { return internal::Mapping_cache::release_both(); }

/// The most bytes of freed working memory that lapmesh keeps: 1 GiB, or an eighth of the
/// physical memory where that is less, unless set. Arrays under 4 MiB take at most a sixteenth.
inline std::size_t working_memory_cache_limit() { return internal::Mapping_cache::total_limit(); }

/// Sets that limit; 0 keeps nothing. What the cache holds over the new limit is handed back.
inline void set_working_memory_cache_limit(std::size_t bytes) { internal::Mapping_cache::set_total_limit(bytes); }

} // namespace lapmesh

#endif
