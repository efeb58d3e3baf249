// Internal: atomic file writes shared by the mesh writers (io.h) and the spectral basis files.
//
// The data goes to a hidden temporary file ".NAME.lapmesh-tmp.PID" in the destination
// directory, locked with flock for the whole write, and is renamed over the target only when
// complete: a failure never leaves a partial file, and the temporaries of killed writers are
// recognised (dead PID, free lock) and removed by the next write to that directory.
#ifndef LAPMESH_INTERNAL_ATOMIC_FILE_H
#define LAPMESH_INTERNAL_ATOMIC_FILE_H

#include <lapmesh/errors.h>

#include <cerrno>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

namespace lapmesh {
namespace internal {

/// The temporary file of a write to `target` by process `pid`: hidden, in the same
/// directory (so that the rename is atomic), named so that cleanup can recognise it.
inline std::filesystem::path temporary_path(const std::filesystem::path& target, long pid)
{
  const std::filesystem::path dir = target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  return dir / ("." + target.filename().string() + ".lapmesh-tmp." + std::to_string(pid));
}

/// Removes the temporary files that writers killed before their rename (kill -9, power
/// loss) left in `dir`: names ".NAME.lapmesh-tmp.PID" of regular files whose process PID is
/// no longer alive and whose lock (held by a live writer for the whole write, released by
/// the kernel when it dies) is free. A live writer's file is never touched: its PID is
/// alive, and where PIDs do not tell (another PID namespace) its lock is held. Returns the
/// number of files removed; never throws.
inline std::size_t remove_stale_temporaries(const std::filesystem::path& dir)
{
  namespace fs = std::filesystem;
  static const std::string marker = ".lapmesh-tmp.";
  std::size_t removed = 0;
  std::error_code ec;
  for(fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const std::size_t m = name.rfind(marker);
    if(name.size() < 2 || name[0] != '.' || m == std::string::npos || m < 2) continue;
    const std::string digits = name.substr(m + marker.size());
    if(digits.empty() || digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const long pid = std::stol(digits);
    if(pid <= 0 || pid == long(::getpid())) continue;
    if(::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to judge)
    const int fd = ::open(it->path().c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    if(fd < 0) continue;
    struct stat st;
    const bool regular = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
    if(regular && ::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      std::error_code rm;
      if(fs::remove(it->path(), rm)) ++removed;
    }
    ::close(fd);
  }
  return removed;
}

/// Writes through a temporary file in the destination directory and renames it over
/// `path` when `write` has succeeded; removes the temporary file on any failure. Stale
/// temporary files of dead lapmesh processes in that directory are removed first.
inline void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& write)
{
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if(!fs::is_directory(dir, ec)) throw Io_error("cannot write: directory '" + dir.string() + "' does not exist");
  if(fs::is_directory(target, ec)) throw Io_error("cannot write: it is a directory");
  remove_stale_temporaries(dir);
  const fs::path tmp = temporary_path(target, long(::getpid()));
  // The lock tells a cleaner in another process that this file is being written.
  const int lock_fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0666);
  if(lock_fd < 0) throw Io_error("cannot write: permission denied or read-only location");
  ::flock(lock_fd, LOCK_EX);
  try {
    {
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      if(!out) throw Io_error("cannot write: permission denied or read-only location");
      write(out);
      out.flush();
      if(!out) throw Io_error("write error (disk full?)");
    }
    fs::rename(tmp, target, ec);
    if(ec) throw Io_error("cannot replace the file: " + ec.message());
  } catch(...) {
    fs::remove(tmp, ec);
    ::close(lock_fd);
    throw;
  }
  ::close(lock_fd);
}

} // namespace internal
} // namespace lapmesh

#endif
