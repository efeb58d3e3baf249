#include "heap.h"

#include <cstdlib>
#include <cstring>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace lapmesh_ops {

bool keep_heap_between_calls()
{
#if defined(__GLIBC__)
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if(tunables && (std::strstr(tunables, "mmap_threshold") || std::strstr(tunables, "trim_threshold"))) return false;
  return mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1 && mallopt(M_TRIM_THRESHOLD, 64 << 20) == 1;
#else
  return false;
#endif
}

} // namespace lapmesh_ops
