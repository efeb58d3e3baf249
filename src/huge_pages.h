// When the command line restarts with transparent huge pages (restart.h does it).
//
// A large mesh is processed in large buffers that glibc maps afresh from the kernel; faulting them
// in 4 KiB pages takes a large share of a run on virtual machines. glibc (2.35 and later) backs
// its heap and its mappings with transparent huge pages under the tunable glibc.malloc.hugetlb=1,
// which it reads at start-up only. So when the kernel gives huge pages on request (its "madvise"
// mode; "always" needs nothing, "never" cannot help) and an argument names a large file, the
// process restarts itself once with the tunable added. LAPMESH_HUGE_PAGES=0 turns this off.
#ifndef LAPMESH_SRC_HUGE_PAGES_H
#define LAPMESH_SRC_HUGE_PAGES_H

#include <cstdint>
#include <string>

namespace lapmesh_cli {

/// The input size from which the restart pays for itself (it costs one start of the program).
constexpr std::uintmax_t huge_pages_min_input_bytes = 8u << 20;

/// Whether to restart: `switch_value` is LAPMESH_HUGE_PAGES (nullptr when unset), `tunables`
/// GLIBC_TUNABLES (nullptr when unset), `thp_mode` the content of
/// /sys/kernel/mm/transparent_hugepage/enabled, `largest_input` the size of the largest file
/// named by an argument.
bool huge_pages_restart_wanted(const char* switch_value, const char* tunables, const std::string& thp_mode,
                               std::uintmax_t largest_input);

/// The tunable that huge_pages_restart_wanted() adds to GLIBC_TUNABLES.
constexpr const char* huge_pages_tunable = "glibc.malloc.hugetlb";

} // namespace lapmesh_cli

#endif
