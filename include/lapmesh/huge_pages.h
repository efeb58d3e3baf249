// lapmesh — the switch for transparent huge pages.
//
// Large meshes are processed in large arrays that the system maps afresh at every call; lapmesh
// asks for transparent huge pages for them (internal/memory.h), and the command line restarts
// itself with glibc's huge-page tunable for large inputs. `LAPMESH_HUGE_PAGES=0` in the
// environment turns both off.
#ifndef LAPMESH_HUGE_PAGES_H
#define LAPMESH_HUGE_PAGES_H

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

} // namespace lapmesh

#endif
