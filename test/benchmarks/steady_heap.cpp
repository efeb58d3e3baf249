// Linked into every benchmark program: they measure lapmesh in the process state that the
// command line and the Python module set at their start, glibc's heap kept between calls
// (operations/heap.h), so that the allocator's state during a case does not depend on which
// cases ran before it. A threshold set in the environment (GLIBC_TUNABLES,
// MALLOC_MMAP_THRESHOLD_, MALLOC_TRIM_THRESHOLD_) wins, as it does there.
#include "operations/heap.h"

namespace {
[[maybe_unused]] const bool heap_kept_between_calls = lapmesh_ops::keep_heap_between_calls();
}
