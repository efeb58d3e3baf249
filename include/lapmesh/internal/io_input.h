// Internal: how lapmesh gets the bytes of an input file, and how it quotes them in messages.
//
// Only regular files are read: the type is checked on the open descriptor (fstat), so a FIFO,
// a device (/dev/zero, also through a symlink) or a directory is refused before any byte is
// read and without blocking (the open is non-blocking). The file is mapped, not copied: a
// parser that refuses a 2 GB garbage file at its header touches a few pages only.
//
// Every message that quotes file content goes through excerpt(): at most a few dozen
// characters, non-printable bytes (NUL included) written as \xNN.
#ifndef LAPMESH_INTERNAL_IO_INPUT_H
#define LAPMESH_INTERNAL_IO_INPUT_H

#include <lapmesh/errors.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace lapmesh {

namespace io {
namespace internal {

/// The longest excerpt of file content quoted in a message.
constexpr std::size_t max_excerpt_chars = 40;

/// `text` quoted for a one-line message: at most max_excerpt_chars bytes of it, printable
/// ASCII kept, everything else as \xNN, and "..." when it was cut.
inline std::string excerpt(std::string_view text)
{
  static const char hex[] = "0123456789abcdef";
  std::string out = "'";
  const std::size_t n = std::min(text.size(), max_excerpt_chars);
  for(std::size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if(c >= 0x20 && c < 0x7f && c != '\\' && c != '\'') {
      out += char(c);
    } else {
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  out += text.size() > n ? "'..." : "'";
  return out;
}

/// A read-only view of a whole regular file (mapped; an empty file has an empty view).
class Mapped_file
{
public:
  explicit Mapped_file(const std::string& path)
  {
    // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer.
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if(fd < 0) {
      const int e = errno;
      if(e == ENOENT) throw Io_error("no such file");
      if(e == EACCES) throw Io_error("cannot open the file for reading: permission denied");
      throw Io_error(std::string("cannot open the file for reading: ") + std::strerror(e));
    }
    struct stat st;
    if(::fstat(fd, &st) != 0) {
      ::close(fd);
      throw Io_error("cannot read the file's type");
    }
    if(!S_ISREG(st.st_mode)) {
      ::close(fd);
      if(S_ISDIR(st.st_mode)) throw Io_error("is a directory, not a mesh file");
      const char* kind = S_ISFIFO(st.st_mode)  ? "a FIFO (named pipe)"
                         : S_ISCHR(st.st_mode) ? "a character device"
                         : S_ISBLK(st.st_mode) ? "a block device"
                         : S_ISSOCK(st.st_mode) ? "a socket"
                                                : "not a regular file";
      throw Io_error(std::string("is ") + kind + ", not a regular mesh file");
    }
    m_size = std::size_t(st.st_size);
    if(m_size > 0) {
      void* p = ::mmap(nullptr, m_size, PROT_READ, MAP_PRIVATE, fd, 0);
      if(p == MAP_FAILED) {
        ::close(fd);
        throw Io_error("cannot map the file into memory (" + std::to_string(m_size) + " bytes)");
      }
      m_data = static_cast<const char*>(p);
    }
    ::close(fd);
  }
  ~Mapped_file()
  {
    if(m_data) ::munmap(const_cast<char*>(m_data), m_size);
  }
  Mapped_file(const Mapped_file&) = delete;
  Mapped_file& operator=(const Mapped_file&) = delete;

  std::string_view view() const { return std::string_view(m_data ? m_data : "", m_size); }

private:
  const char* m_data = nullptr;
  std::size_t m_size = 0;
};

} // namespace internal
} // namespace io
} // namespace lapmesh

#endif
