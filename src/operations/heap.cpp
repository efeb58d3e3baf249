#include "heap.h"

#include <lapmesh/huge_pages.h>

#include <cstdlib>
#include <cstring>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace lapmesh_ops {

bool set_steady_heap_thresholds()
{
#if defined(__GLIBC__)
  return mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1 && mallopt(M_TRIM_THRESHOLD, 64 << 20) == 1;
#else
  return false;
#endif
}

bool keep_heap_between_calls()
{
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if(tunables && (std::strstr(tunables, "mmap_threshold") || std::strstr(tunables, "trim_threshold"))) return false;
  if(std::getenv("MALLOC_MMAP_THRESHOLD_") || std::getenv("MALLOC_TRIM_THRESHOLD_")) return false;
  return set_steady_heap_thresholds();
}

std::size_t cached_working_memory() { return lapmesh::cached_working_memory(); }

std::size_t release_working_memory() { return lapmesh::release_working_memory(); }

} // namespace lapmesh_ops
