// Internal: the text the mesh writers produce, formatted into large blocks.
//
// A mesh of a million vertices is written as tens of millions of short numbers. Formatted one
// by one through std::ostream (a sentry and a virtual call per item) and printf (a multiple-
// precision conversion per double), the writing took longer than the computation it reports.
// Here doubles go through std::to_chars with printf's "%.17g" format (the same characters,
// several times faster) and integers through std::to_chars, into a block that reaches the
// stream in one call when it is full.
#ifndef LAPMESH_INTERNAL_IO_TEXT_OUTPUT_H
#define LAPMESH_INTERNAL_IO_TEXT_OUTPUT_H

#include <charconv>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <ostream>
#include <string>
#include <vector>

namespace lapmesh {
namespace io {
namespace internal {

/// Room that format_double() needs: "%.17g" of a double is at most 24 characters.
constexpr std::size_t formatted_double_room = 32;

/// Writes x at `out` exactly as printf's "%.17g" does (17 significant digits, which read back
/// bitwise) and returns the end; `out` has formatted_double_room characters.
inline char* format_double(char* out, double x)
{
#if defined(__cpp_lib_to_chars) && __cpp_lib_to_chars >= 201611L
  return std::to_chars(out, out + formatted_double_room, x, std::chars_format::general, 17).ptr;
#else
  return out + std::snprintf(out, formatted_double_room, "%.17g", x);
#endif
}

/// Text for an output stream, gathered in blocks: put() appends, and a full block (or flush())
/// goes to the stream in one write. Call flush() at the end: the destructor does not, since a
/// write failure there could not be reported.
class Text_output
{
public:
  explicit Text_output(std::ostream& os, std::size_t block_bytes = std::size_t(1) << 20)
    : m_os(os), m_block(block_bytes + 64)
  {
    m_limit = m_block.data() + block_bytes;
    m_at = m_block.data();
  }
  Text_output(const Text_output&) = delete;
  Text_output& operator=(const Text_output&) = delete;

  void put(double x)
  {
    m_at = format_double(m_at, x);
    after_put();
  }
  void put(std::size_t i)
  {
    m_at = std::to_chars(m_at, m_at + 24, i).ptr;
    after_put();
  }
  void put(int i)
  {
    m_at = std::to_chars(m_at, m_at + 24, i).ptr;
    after_put();
  }
  void put(char c)
  {
    *m_at++ = c;
    after_put();
  }
  /// A literal or short text (longer ones go straight through).
  void put(const char* text) { put(text, std::strlen(text)); }
  void put(const std::string& text) { put(text.data(), text.size()); }
  void put(const char* text, std::size_t size)
  {
    if(size > 64) {
      flush();
      m_os.write(text, std::streamsize(size));
      return;
    }
    std::memcpy(m_at, text, size);
    m_at += size;
    after_put();
  }

  void flush()
  {
    if(m_at != m_block.data()) m_os.write(m_block.data(), m_at - m_block.data());
    m_at = m_block.data();
  }

private:
  // Every put() writes at most 64 characters past m_limit: the block has that much spare room.
  void after_put()
  {
    if(m_at >= m_limit) flush();
  }

  std::ostream& m_os;
  std::vector<char> m_block;
  char* m_limit;
  char* m_at;
};

} // namespace internal
} // namespace io
} // namespace lapmesh

#endif
