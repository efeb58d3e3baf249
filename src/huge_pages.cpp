#include "huge_pages.h"

#include <lapmesh/huge_pages.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include <unistd.h>

namespace lapmesh_cli {

namespace {

constexpr const char* tunable = "glibc.malloc.hugetlb";

std::string read_text(const char* path)
{
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

} // namespace

bool huge_pages_restart_wanted(const char* switch_value, const char* tunables, const std::string& thp_mode,
                               std::uintmax_t largest_input)
{
  if(lapmesh::huge_pages_switched_off(switch_value)) return false;
  if(tunables && std::strstr(tunables, tunable)) return false;  // set by the user, or this is the restarted run
  return thp_mode.find("[madvise]") != std::string::npos && largest_input >= huge_pages_min_input_bytes;
}

void restart_with_huge_pages_if_useful(int argc, char** argv)
{
  std::uintmax_t largest = 0;
  for(int i = 1; i < argc; ++i) {
    std::error_code ec;
    if(std::filesystem::is_regular_file(argv[i], ec)) {
      const std::uintmax_t size = std::filesystem::file_size(argv[i], ec);
      if(!ec && size > largest) largest = size;
    }
  }
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if(!huge_pages_restart_wanted(std::getenv(lapmesh::huge_pages_variable), tunables,
                                read_text("/sys/kernel/mm/transparent_hugepage/enabled"), largest))
    return;
  const std::string previous = tunables ? tunables : "";
  const std::string value = (previous.empty() ? "" : previous + ":") + tunable + "=1";
  if(setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
  execv("/proc/self/exe", argv);
  // Not restarted (no /proc, say): go on as started.
  if(tunables)
    setenv("GLIBC_TUNABLES", previous.c_str(), 1);
  else
    unsetenv("GLIBC_TUNABLES");
}

} // namespace lapmesh_cli
