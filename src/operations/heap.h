// The process-wide memory settings of the front ends: glibc's heap kept between calls, and the
// working arrays that lapmesh keeps for its next call (lapmesh/huge_pages.h).
//
// Until a block of 32 MiB has been freed, glibc hands the top of its heap back to the kernel at
// the end of every call that freed more than a few times its largest block, and the next call
// faults it in again, one page at a time. A program that calls lapmesh on many small meshes
// never leaves that state, and each call then costs several times as much. The command line
// (the viewer included) and the Python module therefore put glibc in the state it reaches by
// itself after that first large block.
#ifndef LAPMESH_OPERATIONS_HEAP_H
#define LAPMESH_OPERATIONS_HEAP_H

#include <cstddef>

namespace lapmesh_ops {

/// Blocks up to 32 MiB from the heap, and up to 64 MiB of free heap kept (glibc's mmap and trim
/// thresholds, the largest values its adaptive rule reaches). Returns whether glibc took them
/// (false outside glibc).
bool set_steady_heap_thresholds();

/// set_steady_heap_thresholds(), unless the environment sets a threshold itself
/// (GLIBC_TUNABLES's mmap_threshold or trim_threshold, MALLOC_MMAP_THRESHOLD_,
/// MALLOC_TRIM_THRESHOLD_). Returns whether it set them.
bool keep_heap_between_calls();

/// Bytes of freed working arrays that lapmesh keeps for its next call (lapmesh/huge_pages.h).
std::size_t cached_working_memory();
/// Hands them back to the system; returns how many bytes that was.
std::size_t release_working_memory();

} // namespace lapmesh_ops

#endif
