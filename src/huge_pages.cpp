#include "huge_pages.h"

#include <lapmesh/huge_pages.h>

#include <cstring>

namespace lapmesh_cli {

bool huge_pages_restart_wanted(const char* switch_value, const char* tunables, const std::string& thp_mode,
                               std::uintmax_t largest_input)
{
  if(lapmesh::huge_pages_switched_off(switch_value)) return false;
  if(tunables && std::strstr(tunables, huge_pages_tunable)) return false;  // set by the user, or this is the restarted run
  return thp_mode.find("[madvise]") != std::string::npos && largest_input >= huge_pages_min_input_bytes;
}

} // namespace lapmesh_cli
