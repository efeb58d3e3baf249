#include "restart.h"

#include "huge_pages.h"

#include <lapmesh/blas.h>
#include <lapmesh/huge_pages.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <unistd.h>

namespace lapmesh_cli {

namespace {

std::string read_text(const char* path)
{
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::optional<std::string> huge_pages_tunables(int argc, char** argv)
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
    return std::nullopt;
  const std::string previous = tunables ? tunables : "";
  return (previous.empty() ? "" : previous + ":") + huge_pages_tunable + "=1";
}

} // namespace

bool subcommand_uses_the_blas(int argc, char** argv)
{
  static constexpr const char* factorising[] = {"spectrum", "reconstruct", "smooth", "denoise-study", "view"};
  if(argc < 2) return false;
  for(const char* name : factorising)
    if(std::strcmp(argv[1], name) == 0) return true;
  return false;
}

void restart_if_useful(int argc, char** argv)
{
  std::vector<std::pair<const char*, std::string>> settings;
  if(const auto tunables = huge_pages_tunables(argc, argv)) settings.emplace_back("GLIBC_TUNABLES", *tunables);
  if(!std::getenv("OPENBLAS_CORETYPE") && subcommand_uses_the_blas(argc, argv))
    if(const auto core = lapmesh::openblas_coretype_that_fits()) settings.emplace_back("OPENBLAS_CORETYPE", *core);
  if(settings.empty()) return;

  std::vector<std::pair<const char*, std::optional<std::string>>> before;
  bool set = true;
  for(const auto& [name, value] : settings) {
    const char* old = std::getenv(name);
    before.emplace_back(name, old ? std::optional<std::string>(old) : std::nullopt);
    set = set && setenv(name, value.c_str(), 1) == 0;
  }
  if(set) execv("/proc/self/exe", argv);
  // Not restarted (no /proc, say): go on as started.
  for(const auto& [name, old] : before) {
    if(old)
      setenv(name, old->c_str(), 1);
    else
      unsetenv(name);
  }
}

} // namespace lapmesh_cli
