// Internal: lapmesh's own parsers of OFF, OBJ, PLY (ASCII, binary little and big endian) and
// STL (ASCII and binary), from bytes in memory to a polygon soup.
//
// Hostile input is the design case. No count read from a file is trusted: before anything
// is reserved, a declared number of vertices, faces, elements or list entries is checked
// against what the remaining bytes can hold (every value takes at least one byte and a
// separator in text, its size in binary), so a short file claiming 10^9 vertices fails at
// once. Tokens are bounded (max_token_chars), every quoted piece of the file goes through
// excerpt(), and content after a complete OFF, PLY or STL (other than whitespace or, in OFF,
// comments) is refused rather than ignored.
#ifndef LAPMESH_INTERNAL_IO_PARSERS_H
#define LAPMESH_INTERNAL_IO_PARSERS_H

#include <lapmesh/internal/io_input.h>
#include <lapmesh/types.h>

#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

namespace lapmesh {
namespace io {


namespace internal {

/// A number or keyword longer than this is refused (the longest double printed with %f is
/// about 330 characters).
constexpr std::size_t max_token_chars = 1024;

enum class Int_parse { ok, not_integer, out_of_range };

/// Parses all of `t` as a signed integer.
inline Int_parse parse_integer(std::string_view t, long long& x)
{
  if(t.empty()) return Int_parse::not_integer;
  const char* b = t.data();
  if(*b == '+' && t.size() > 1 && t[1] != '-') ++b;  // from_chars rejects a leading '+'
  const auto r = std::from_chars(b, t.data() + t.size(), x);
  if(r.ptr != t.data() + t.size()) return Int_parse::not_integer;
  if(r.ec == std::errc::result_out_of_range) return Int_parse::out_of_range;
  return r.ec == std::errc() ? Int_parse::ok : Int_parse::not_integer;
}

/// Parses all of `t` as a double (also "+1", "inf", "nan" as strtod spells them).
inline bool parse_double(std::string_view t, double& x)
{
  if(t.empty() || t.size() > max_token_chars) return false;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), x);
  if(r.ptr == t.data() + t.size() && (r.ec == std::errc() || r.ec == std::errc::result_out_of_range)) {
    if(r.ec == std::errc::result_out_of_range) {  // overflow or underflow: the value strtod gives
      const std::string s(t);
      x = std::strtod(s.c_str(), nullptr);
    }
    return true;
  }
  const std::string s(t);
  char* e = nullptr;
  x = std::strtod(s.c_str(), &e);
  return e && *e == '\0' && e != s.c_str() && !std::isspace(static_cast<unsigned char>(s[0]));
}

/// A part of an error message given as text, or as a function that makes it: the loops over
/// millions of vertices and faces name each one only when it has an error.
inline std::string message_text(const std::string& text) { return text; }
inline std::string message_text(const char* text) { return text; }
template <typename MakeText>
std::string message_text(const MakeText& make_text)
{
  return make_text();
}

/// Tokenizer over text in memory with line numbers. Tokens are separated by blanks; '\n'
/// ends a line; with `comments`, '#' starts a comment that runs to the end of the line.
/// Nothing scans ahead: a refused token costs at most max_token_chars bytes of reading.
class Text_reader
{
public:
  Text_reader(std::string_view data, bool comments, std::size_t first_line = 1)
    : m_p(data.data()), m_end(data.data() + data.size()), m_line(first_line), m_comments(comments)
  {}

  /// Moves to the next line with content (skipping the rest of the current one, blank and
  /// comment lines); false at the end of the data.
  bool next_line()
  {
    if(m_started && !skip_rest_of_line()) return false;
    m_started = true;
    for(;;) {
      skip_blanks();
      if(m_p == m_end) return false;
      if(*m_p == '\n') {
        ++m_p;
        ++m_line;
      } else if(m_comments && *m_p == '#') {
        if(!skip_rest_of_line()) return false;
      } else {
        return true;
      }
    }
  }
  /// True when the current line has no more tokens.
  bool at_line_end()
  {
    skip_blanks();
    return m_p == m_end || *m_p == '\n' || (m_comments && *m_p == '#');
  }
  /// The next token of the current line, empty at its end.
  std::string_view token()
  {
    if(at_line_end()) return {};
    const char* b = m_p;
    const char* limit = m_p + std::min<std::size_t>(std::size_t(m_end - m_p), max_token_chars + 1);
    while(m_p < limit && !is_blank(*m_p) && *m_p != '\n' && !(m_comments && *m_p == '#')) ++m_p;
    if(std::size_t(m_p - b) > max_token_chars)
      fail("a token longer than " + std::to_string(max_token_chars) + " characters: " +
           excerpt(std::string_view(b, max_excerpt_chars + 1)));
    return std::string_view(b, std::size_t(m_p - b));
  }
  /// The next token, crossing line ends (the token stream of ASCII PLY); empty at the end.
  std::string_view any_token()
  {
    for(;;) {
      skip_blanks();
      if(m_p == m_end) return {};
      if(*m_p != '\n') return token();
      ++m_p;
      ++m_line;
    }
  }
  /// Skips to the start of the next line; false if there is none.
  bool skip_rest_of_line()
  {
    const void* nl = std::memchr(m_p, '\n', std::size_t(m_end - m_p));
    if(!nl) {
      m_p = m_end;
      return false;
    }
    m_p = static_cast<const char*>(nl) + 1;
    ++m_line;
    return true;
  }
  /// Reads the three coordinates of a vertex; `where` names it in the message.
  template <typename Label>
  void coordinates(std::array<double, 3>& p, const Label& where)
  {
    for(double& x : p) {
      const std::string_view t = token();
      if(t.empty()) fail(message_text(where) + ": expected three coordinates");
      if(!parse_double(t, x)) fail(message_text(where) + ": bad coordinate " + excerpt(t));
    }
  }
  /// Reads an integer token; fails with a message built from `what` otherwise.
  template <typename Label>
  long long integer(const Label& what)
  {
    const std::string_view t = token();
    if(t.empty()) fail("expected " + message_text(what) + ", found the end of the line");
    long long x = 0;
    const Int_parse r = parse_integer(t, x);
    if(r == Int_parse::out_of_range) fail(message_text(what) + " " + excerpt(t) + " is out of range");
    if(r != Int_parse::ok) fail("expected " + message_text(what) + ", found " + excerpt(t));
    return x;
  }
  /// Excerpt of the data at the reading position (does not scan ahead).
  std::string here()
  {
    skip_blanks();
    return excerpt(std::string_view(m_p, std::min<std::size_t>(std::size_t(m_end - m_p), max_excerpt_chars + 1)));
  }
  std::size_t remaining() const { return std::size_t(m_end - m_p); }
  const char* position() const { return m_p; }
  std::size_t line() const { return m_line; }
  [[noreturn]] void fail(const std::string& what) const { throw Io_error("line " + std::to_string(m_line) + ": " + what); }

private:
  static bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
  void skip_blanks()
  {
    while(m_p < m_end && is_blank(*m_p)) ++m_p;
  }
  const char* m_p;
  const char* m_end;
  std::size_t m_line;
  bool m_comments;
  bool m_started = false;
};

/// Fails unless `count` items of at least `min_bytes` each fit in `available` bytes.
template <typename Label>
void check_fits(unsigned long long count, std::size_t min_bytes, std::size_t available, const Label& what)
{
  if(min_bytes > 0 && (unsigned __int128)count * min_bytes > (unsigned __int128)available)
    throw Io_error("the file declares " + std::to_string(count) + " " + message_text(what) +
                   ", more than its remaining " + std::to_string(available) +
                   " bytes can hold (truncated or corrupt header)");
}

/// Optional numeric fields after the values lapmesh reads (colours, normals, texture
/// coordinates): at most `max_fields` numbers, then the end of the line.
template <typename Label>
void skip_numeric_fields(Text_reader& r, int max_fields, const Label& where)
{
  for(int k = 0; !r.at_line_end(); ++k) {
    const std::string_view t = r.token();
    double ignored;
    if(k >= max_fields || !parse_double(t, ignored)) r.fail(message_text(where) + ": unexpected " + excerpt(t));
  }
}

// ---------------------------------------------------------------------------------------- OFF

inline Polygon_soup parse_off(std::string_view data)
{
  Text_reader r(data, true);
  if(!r.next_line()) throw Io_error("empty file: no OFF header");
  const std::string_view header = r.token();
  // [ST][C][N][4][n]OFF; lapmesh reads 3D positions and skips the optional per-vertex fields.
  if(header.size() < 3 || header.size() > 8 || header.substr(header.size() - 3) != "OFF")
    r.fail("missing OFF header (found " + excerpt(header) + ")");
  if(header.find('4') != std::string_view::npos || header.find('n') != std::string_view::npos)
    r.fail("only 3D OFF files are supported (header " + excerpt(header) + ")");
  if(r.at_line_end()) {
    if(!r.next_line()) r.fail("truncated file: missing the vertex, face and edge counts");
  }
  {
    Text_reader probe = r;
    if(probe.token() == "BINARY") r.fail("binary OFF is not supported; convert it to ASCII OFF or PLY");
  }
  const long long nv = r.integer("the number of vertices");
  const long long nf = r.integer("the number of faces");
  if(nv < 0 || nf < 0) r.fail("bad counts line: negative number of vertices or faces");
  if(!r.at_line_end()) r.integer("the number of edges");
  if(!r.at_line_end()) r.fail("unexpected " + r.here() + " after the vertex, face and edge counts");
  // A vertex line holds at least 3 values, a face line 2 (the count and one index), each of
  // at least one character and a separator.
  check_fits((unsigned long long)nv, 6, r.remaining() + 1, "vertices");
  check_fits((unsigned long long)nf, 4, r.remaining() + 1 - std::size_t(6 * nv), "faces after its vertices");

  Polygon_soup soup;
  soup.points.resize(std::size_t(nv));
  for(long long i = 0; i < nv; ++i) {
    if(!r.next_line())
      throw Io_error("truncated file: expected " + std::to_string(nv) + " vertices, found " + std::to_string(i));
    const auto vertex = [i] { return "vertex " + std::to_string(i); };
    r.coordinates(soup.points[std::size_t(i)], vertex);
    skip_numeric_fields(r, 9, vertex);  // normal, colour, texture
  }
  soup.polygons.resize(std::size_t(nf));
  for(long long f = 0; f < nf; ++f) {
    if(!r.next_line())
      throw Io_error("truncated file: expected " + std::to_string(nf) + " faces, found " + std::to_string(f));
    const auto face = [f] { return "face " + std::to_string(f); };
    const long long k = r.integer([&] { return face() + ": the number of vertices"; });
    if(k < 1) r.fail(face() + ": bad vertex count " + std::to_string(k));
    check_fits((unsigned long long)k, 2, r.remaining() + 1, [&] { return "vertices in " + face(); });
    auto& poly = soup.polygons[std::size_t(f)];
    poly.resize(std::size_t(k));
    for(long long a = 0; a < k; ++a) {
      const std::string_view t = r.token();
      if(t.empty()) r.fail(face() + ": expected " + std::to_string(k) + " vertex indices, found " + std::to_string(a));
      long long idx = -1;
      const Int_parse res = parse_integer(t, idx);
      if(res == Int_parse::not_integer) r.fail(face() + ": bad vertex index " + excerpt(t));
      if(res == Int_parse::out_of_range || idx < 0 || idx >= nv)
        r.fail(face() + ": vertex index " + (res == Int_parse::ok ? std::to_string(idx) : excerpt(t)) +
               " out of range [0, " + std::to_string(nv) + ")");
      poly[std::size_t(a)] = std::size_t(idx);
    }
    skip_numeric_fields(r, 4, face);  // a face colour
  }
  if(r.next_line()) r.fail("unexpected content after the last face: " + r.here());
  return soup;
}

// ---------------------------------------------------------------------------------------- OBJ

inline bool is_obj_keyword(std::string_view t)
{
  if(t.empty() || t.size() > 32) return false;
  for(char c : t)
    if(!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) return false;
  return true;
}

inline Polygon_soup parse_obj(std::string_view data)
{
  Text_reader r(data, true);
  Polygon_soup soup;
  while(r.next_line()) {
    const std::string_view kw = r.token();
    if(kw == "v") {
      std::array<double, 3> p;
      const auto vertex = [&soup] { return "vertex " + std::to_string(soup.points.size()); };
      r.coordinates(p, vertex);
      skip_numeric_fields(r, 5, vertex);  // w, or a colour
      soup.points.push_back(p);
    } else if(kw == "f") {
      std::vector<std::size_t> poly;
      poly.reserve(4);  // a triangle or a quad without growing
      for(std::string_view t = r.token(); !t.empty(); t = r.token()) {
        const std::string_view head = t.substr(0, t.find('/'));  // "v/vt/vn": keep v
        const auto face = [&soup] { return "face " + std::to_string(soup.polygons.size()); };
        long long idx = 0;
        const Int_parse res = parse_integer(head, idx);
        const long long n = static_cast<long long>(soup.points.size());
        if(res == Int_parse::not_integer || (res == Int_parse::ok && idx == 0))
          r.fail(face() + ": bad vertex reference " + excerpt(t));
        const long long zero_based = res != Int_parse::ok ? -1 : idx > 0 ? idx - 1 : n + idx;  // negative: relative
        if(zero_based < 0 || zero_based >= n)
          r.fail(face() + ": vertex " + excerpt(head) + " refers to a vertex not defined before it");
        poly.push_back(std::size_t(zero_based));
      }
      soup.polygons.push_back(std::move(poly));
    } else if(!is_obj_keyword(kw)) {
      r.fail("not an OBJ statement: " + excerpt(kw));
    }
    // vt, vn, g, o, s, usemtl, mtllib, l, ...: not geometry lapmesh uses.
  }
  return soup;
}

// ---------------------------------------------------------------------------------------- PLY

enum class Ply_type { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

inline bool ply_type_from(std::string_view name, Ply_type& t)
{
  static const std::pair<const char*, Ply_type> names[] = {
    {"char", Ply_type::int8},     {"int8", Ply_type::int8},       {"uchar", Ply_type::uint8},
    {"uint8", Ply_type::uint8},   {"short", Ply_type::int16},     {"int16", Ply_type::int16},
    {"ushort", Ply_type::uint16}, {"uint16", Ply_type::uint16},   {"int", Ply_type::int32},
    {"int32", Ply_type::int32},   {"uint", Ply_type::uint32},     {"uint32", Ply_type::uint32},
    {"float", Ply_type::float32}, {"float32", Ply_type::float32}, {"double", Ply_type::float64},
    {"float64", Ply_type::float64}};
  for(const auto& [n, type] : names)
    if(name == n) {
      t = type;
      return true;
    }
  return false;
}
inline std::size_t ply_size(Ply_type t)
{
  switch(t) {
  case Ply_type::int8: case Ply_type::uint8: return 1;
  case Ply_type::int16: case Ply_type::uint16: return 2;
  case Ply_type::int32: case Ply_type::uint32: case Ply_type::float32: return 4;
  default: return 8;
  }
}
inline bool ply_is_integer(Ply_type t) { return t != Ply_type::float32 && t != Ply_type::float64; }

struct Ply_property
{
  std::string name;
  Ply_type type = Ply_type::float32;  ///< the value type (the entries' type for a list)
  bool is_list = false;
  Ply_type count_type = Ply_type::uint8;
};

struct Ply_element
{
  std::string name;
  unsigned long long count = 0;
  std::vector<Ply_property> properties;
};

/// Reads the values of a PLY body, ASCII or binary, as doubles or integers of their type.
class Ply_body
{
public:
  enum class Format { ascii, binary_le, binary_be };
  Ply_body(std::string_view body, Format f, std::size_t first_line)
    : m_text(body, false, first_line), m_p(body.data()), m_end(body.data() + body.size()), m_format(f)
  {}

  std::size_t remaining() const { return m_format == Format::ascii ? m_text.remaining() : std::size_t(m_end - m_p); }
  bool ascii() const { return m_format == Format::ascii; }

  /// A value of integer type (exact); fails for a value outside the type in ASCII.
  template <typename Label>
  long long integer(Ply_type t, const Label& where)
  {
    if(ascii()) {
      const std::string_view tok = m_text.any_token();
      if(tok.empty()) truncated(where);
      long long x = 0;
      if(parse_integer(tok, x) != Int_parse::ok || !fits(t, x)) fail(message_text(where) + ": bad integer " + excerpt(tok));
      return x;
    }
    const unsigned char* b = take(ply_size(t), where);
    switch(t) {
    case Ply_type::int8: return static_cast<std::int8_t>(b[0]);
    case Ply_type::uint8: return b[0];
    case Ply_type::int16: return static_cast<std::int16_t>(std::uint16_t(unsigned_value(b, 2)));
    case Ply_type::uint16: return (long long)unsigned_value(b, 2);
    case Ply_type::int32: return static_cast<std::int32_t>(std::uint32_t(unsigned_value(b, 4)));
    default: return (long long)unsigned_value(b, 4);  // uint32
    }
  }
  /// A value of any type as a double.
  template <typename Label>
  double real(Ply_type t, const Label& where)
  {
    if(ply_is_integer(t)) return double(integer(t, where));
    if(ascii()) {
      const std::string_view tok = m_text.any_token();
      if(tok.empty()) truncated(where);
      double x = 0;
      if(!parse_double(tok, x)) fail(message_text(where) + ": bad number " + excerpt(tok));
      return x;
    }
    const unsigned char* b = take(ply_size(t), where);
    if(t == Ply_type::float32) {
      const std::uint32_t bits = std::uint32_t(unsigned_value(b, 4));
      float f;
      std::memcpy(&f, &bits, 4);
      return double(f);
    }
    const std::uint64_t bits = unsigned_value(b, 8);
    double d;
    std::memcpy(&d, &bits, 8);
    return d;
  }
  /// Fails unless only whitespace follows.
  void expect_end()
  {
    if(ascii()) {
      const std::string_view tok = m_text.any_token();
      if(!tok.empty()) fail("unexpected content after the last element: " + excerpt(tok));
      return;
    }
    for(const char* q = m_p; q < m_end; ++q)
      if(!(*q == ' ' || *q == '\n' || *q == '\r' || *q == '\t'))
        throw Io_error("unexpected " + std::to_string(m_end - m_p) + " bytes after the last element: " +
                       excerpt(std::string_view(m_p, std::min<std::size_t>(std::size_t(m_end - m_p), max_excerpt_chars + 1))));
  }
  [[noreturn]] void fail(const std::string& what) const
  {
    if(ascii()) m_text.fail(what);
    throw Io_error(what);
  }

private:
  static bool fits(Ply_type t, long long x)
  {
    switch(t) {
    case Ply_type::int8: return x >= -128 && x <= 127;
    case Ply_type::uint8: return x >= 0 && x <= 255;
    case Ply_type::int16: return x >= -32768 && x <= 32767;
    case Ply_type::uint16: return x >= 0 && x <= 65535;
    case Ply_type::int32: return x >= -2147483648LL && x <= 2147483647LL;
    default: return x >= 0 && x <= 4294967295LL;
    }
  }
  template <typename Label>
  [[noreturn]] void truncated(const Label& where) const
  {
    fail("truncated file: " + message_text(where) + " is missing");
  }
  template <typename Label>
  const unsigned char* take(std::size_t n, const Label& where)
  {
    if(std::size_t(m_end - m_p) < n) truncated(where);
    const unsigned char* b = reinterpret_cast<const unsigned char*>(m_p);
    m_p += n;
    return b;
  }
  std::uint64_t unsigned_value(const unsigned char* b, std::size_t n) const
  {
    std::uint64_t v = 0;
    for(std::size_t i = 0; i < n; ++i) {
      const std::size_t byte = m_format == Format::binary_le ? n - 1 - i : i;
      v = (v << 8) | b[byte];
    }
    return v;
  }
  Text_reader m_text;
  const char* m_p;
  const char* m_end;
  Format m_format;
};

inline Polygon_soup parse_ply(std::string_view data)
{
  // The magic line is checked before any scanning: garbage fails at its first bytes.
  if(data.substr(0, 4) != "ply\n" && data.substr(0, 5) != "ply\r\n")
    throw Io_error("line 1: missing PLY header (found " + excerpt(data.substr(0, 8)) + ")");
  Text_reader h(data, false);
  h.next_line();
  Ply_body::Format format = Ply_body::Format::ascii;
  bool have_format = false;
  std::vector<Ply_element> elements;
  for(;;) {
    if(!h.next_line()) throw Io_error("truncated PLY header: no 'end_header' line");
    const std::string_view kw = h.token();
    if(kw == "end_header") {
      if(!h.at_line_end()) h.fail("unexpected " + h.here() + " after 'end_header'");
      break;
    }
    if(kw == "comment" || kw == "obj_info") continue;
    if(kw == "format") {
      const std::string_view f = h.token();
      if(f == "ascii") format = Ply_body::Format::ascii;
      else if(f == "binary_little_endian") format = Ply_body::Format::binary_le;
      else if(f == "binary_big_endian") format = Ply_body::Format::binary_be;
      else h.fail("unknown PLY format " + excerpt(f) + " (expected ascii, binary_little_endian or binary_big_endian)");
      if(h.token() != "1.0") h.fail("unsupported PLY version (expected 1.0)");
      have_format = true;
    } else if(kw == "element") {
      Ply_element e;
      e.name = std::string(h.token());
      if(e.name.empty()) h.fail("element without a name");
      const std::string_view c = h.token();
      long long count = 0;
      const Int_parse res = parse_integer(c, count);
      if(res == Int_parse::not_integer) h.fail("element " + excerpt(e.name) + ": bad count " + excerpt(c));
      if(res == Int_parse::out_of_range || count < 0)
        h.fail("element " + excerpt(e.name) + ": count " + excerpt(c) + " out of range");
      e.count = (unsigned long long)count;
      for(const auto& other : elements)
        if(other.name == e.name) h.fail("element " + excerpt(e.name) + " declared twice");
      elements.push_back(std::move(e));
    } else if(kw == "property") {
      if(elements.empty()) h.fail("'property' before any 'element' line");
      Ply_property p;
      std::string_view type = h.token();
      if(type == "list") {
        p.is_list = true;
        const std::string_view ct = h.token();
        if(!ply_type_from(ct, p.count_type) || !ply_is_integer(p.count_type))
          h.fail("bad list count type " + excerpt(ct) + " (expected an integer type)");
        type = h.token();
      }
      if(!ply_type_from(type, p.type)) h.fail("unknown property type " + excerpt(type));
      p.name = std::string(h.token());
      if(p.name.empty()) h.fail("property without a name");
      if(!h.at_line_end()) h.fail("unexpected " + h.here() + " after the property name");
      elements.back().properties.push_back(std::move(p));
    } else {
      h.fail("unknown PLY header line " + excerpt(kw));
    }
  }
  if(!have_format) throw Io_error("PLY header without a 'format' line");
  // The body starts after the '\n' of the end_header line.
  h.skip_rest_of_line();
  const std::string_view body = data.substr(std::size_t(h.position() - data.data()));
  Ply_body in(body, format, h.line());

  // Every count against the bytes it needs, before reserving anything.
  std::size_t needed_so_far = 0;
  long long num_vertices = -1, num_faces = -1;
  for(const auto& e : elements) {
    std::size_t min_bytes = 0;  // per instance: one byte and a separator per value in ASCII
    for(const auto& p : e.properties) min_bytes += in.ascii() ? 2 : ply_size(p.is_list ? p.count_type : p.type);
    const std::size_t available = in.remaining() + 1 - std::min(in.remaining() + 1, needed_so_far);
    check_fits(e.count, min_bytes, available, excerpt(e.name) + " elements");
    needed_so_far += std::size_t(e.count * min_bytes);
    if(e.name == "vertex") num_vertices = (long long)e.count;
    if(e.name == "face") num_faces = (long long)e.count;
  }
  if(num_vertices < 0) throw Io_error("PLY header without a 'vertex' element");
  if(num_vertices > 0x7fffffffLL || num_faces > 0x7fffffffLL)
    throw Io_error("more than 2^31 - 1 vertices or faces: beyond lapmesh's index range");

  Polygon_soup soup;
  for(const auto& e : elements) {
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    int xyz[3] = {-1, -1, -1};
    int indices = -1;
    for(int k = 0; k < int(e.properties.size()); ++k) {
      const Ply_property& p = e.properties[std::size_t(k)];
      if(is_vertex && !p.is_list)
        for(int c = 0; c < 3; ++c)
          if(p.name == std::string(1, char('x' + c))) xyz[c] = k;
      if(is_face && p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
        if(!ply_is_integer(p.type)) throw Io_error("face property " + p.name + " must have an integer type");
        indices = k;
      }
    }
    if(is_vertex && (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0))
      throw Io_error("the 'vertex' element lacks one of the properties x, y, z");
    if(is_face && indices < 0 && e.count > 0)
      throw Io_error("the 'face' element has no list property 'vertex_indices'");
    if(e.properties.empty()) continue;  // nothing to read, whatever the count
    if(is_vertex) soup.points.resize(std::size_t(e.count));
    if(is_face) soup.polygons.resize(std::size_t(e.count));
    for(unsigned long long i = 0; i < e.count; ++i) {
      for(int k = 0; k < int(e.properties.size()); ++k) {
        const Ply_property& p = e.properties[std::size_t(k)];
        const auto where = [&] { return e.name + " " + std::to_string(i) + ": property " + p.name; };
        if(!p.is_list) {
          const double x = in.real(p.type, where);
          if(is_vertex)
            for(int c = 0; c < 3; ++c)
              if(xyz[c] == k) soup.points[std::size_t(i)][std::size_t(c)] = x;
          continue;
        }
        const long long len = in.integer(p.count_type, [&] { return where() + ": list length"; });
        if(len < 0) in.fail(where() + ": negative list length " + std::to_string(len));
        check_fits((unsigned long long)len, in.ascii() ? 2 : ply_size(p.type), in.remaining() + 1,
                   [&] { return "list entries in " + e.name + " " + std::to_string(i); });
        if(is_face && k == indices) {
          auto& poly = soup.polygons[std::size_t(i)];
          poly.resize(std::size_t(len));
          for(long long a = 0; a < len; ++a) {
            const long long idx = in.integer(p.type, where);
            if(idx < 0 || idx >= num_vertices)
              in.fail("face " + std::to_string(i) + ": vertex index " + std::to_string(idx) + " out of range [0, " +
                      std::to_string(num_vertices) + ")");
            poly[std::size_t(a)] = std::size_t(idx);
          }
        } else {
          for(long long a = 0; a < len; ++a) in.real(p.type, where);
        }
      }
    }
  }
  in.expect_end();
  return soup;
}

// ---------------------------------------------------------------------------------------- STL

/// STL has no shared vertices: equal positions are merged, numbered in order of first
/// appearance (0 and -0 are one position). A position with a NaN equals none, so it is not
/// looked up: a file of NaNs takes one step per vertex, not one per vertex before it.
/// Open addressing over the point indices, at most half full. The hash mixes every bit: the
/// positions of a binary STL are floats, whose low 29 bits are zero as doubles.
class Stl_vertex_merger
{
public:
  /// `expected`: the number of distinct positions likely to come, to size the table once.
  explicit Stl_vertex_merger(Polygon_soup& soup, std::size_t expected = 0) : m_soup(soup)
  {
    std::size_t capacity = 64;  // grows as needed; `expected` sizes it up to 2^25 slots
    while(capacity < 2 * expected && capacity < (std::size_t(1) << 25)) capacity *= 2;
    m_slots.assign(capacity, empty_slot);
  }
  std::size_t index_of(const std::array<double, 3>& p)
  {
    if(has_nan(p)) return append(p);
    if(2 * (m_soup.points.size() + 1) > m_slots.size()) grow();
    const std::size_t mask = m_slots.size() - 1;
    for(std::size_t s = hash(p) & mask;; s = (s + 1) & mask) {
      ++m_probes;
      const std::uint32_t i = m_slots[s];
      if(i == empty_slot) {
        m_slots[s] = std::uint32_t(m_soup.points.size());
        return append(p);
      }
      if(m_soup.points[i] == p) return i;  // compares as doubles: -0 == 0
    }
  }
  /// The slots looked at so far, over all lookups.
  std::size_t probes() const { return m_probes; }

private:
  static constexpr std::uint32_t empty_slot = 0xffffffffu;
  static bool has_nan(const std::array<double, 3>& p) { return std::isnan(p[0]) || std::isnan(p[1]) || std::isnan(p[2]); }
  static std::uint64_t mix(std::uint64_t x)
  {
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
  }
  static std::uint64_t hash(const std::array<double, 3>& p)
  {
    std::uint64_t h = 0;
    for(double c : p) {
      const double normalized = c == 0 ? 0.0 : c;  // -0 hashes as 0
      std::uint64_t bits;
      std::memcpy(&bits, &normalized, 8);
      h = mix(h + bits);
    }
    return h;
  }
  std::size_t append(const std::array<double, 3>& p)
  {
    if(m_soup.points.size() >= 0x7fffffffu)
      throw Io_error("more than 2^31 - 1 distinct vertices: beyond lapmesh's index range");
    m_soup.points.push_back(p);
    return m_soup.points.size() - 1;
  }
  void grow()
  {
    m_slots.assign(2 * m_slots.size(), empty_slot);
    const std::size_t mask = m_slots.size() - 1;
    for(std::size_t i = 0; i < m_soup.points.size(); ++i) {
      const auto& p = m_soup.points[i];
      if(has_nan(p)) continue;
      std::size_t s = hash(p) & mask;
      while(m_slots[s] != empty_slot) s = (s + 1) & mask;
      m_slots[s] = std::uint32_t(i);
    }
  }
  Polygon_soup& m_soup;
  std::vector<std::uint32_t> m_slots;
  std::size_t m_probes = 0;
};

inline Polygon_soup parse_stl_binary(std::string_view data, std::size_t triangles)
{
  Polygon_soup soup;
  soup.polygons.reserve(triangles);
  Stl_vertex_merger merge(soup, triangles / 2 + 2);  // a closed surface's vertex count
  const unsigned char* b = reinterpret_cast<const unsigned char*>(data.data()) + 84;
  for(std::size_t f = 0; f < triangles; ++f, b += 50) {
    std::vector<std::size_t> poly(3);
    for(int v = 0; v < 3; ++v) {
      std::array<double, 3> p;
      for(int c = 0; c < 3; ++c) {
        const unsigned char* q = b + 12 + 12 * v + 4 * c;  // after the normal
        const std::uint32_t bits = std::uint32_t(q[0]) | std::uint32_t(q[1]) << 8 | std::uint32_t(q[2]) << 16 |
                                   std::uint32_t(q[3]) << 24;
        float x;
        std::memcpy(&x, &bits, 4);
        p[std::size_t(c)] = double(x);
      }
      poly[std::size_t(v)] = merge.index_of(p);
    }
    soup.polygons.push_back(std::move(poly));
  }
  return soup;
}

inline Polygon_soup parse_stl_ascii(std::string_view data)
{
  Text_reader r(data, false);
  Polygon_soup soup;
  Stl_vertex_merger merge(soup);
  auto expect = [&r](std::string_view word, const auto& where) {
    const std::string_view t = r.any_token();
    if(t != word)
      r.fail(message_text(where) + ": expected '" + std::string(word) + "', found " +
             (t.empty() ? "the end of the file" : excerpt(t)));
  };
  std::string_view t = r.any_token();
  if(t != "solid") r.fail("missing 'solid' keyword (found " + excerpt(t) + ")");
  r.skip_rest_of_line();  // the solid's name
  for(;;) {
    t = r.any_token();
    if(t == "endsolid") {
      r.skip_rest_of_line();
      t = r.any_token();
      if(t.empty()) break;
      if(t != "solid") r.fail("unexpected content after 'endsolid': " + excerpt(t));
      r.skip_rest_of_line();
      continue;
    }
    const std::size_t facet = soup.polygons.size();
    const auto where = [facet] { return "facet " + std::to_string(facet); };
    if(t != "facet")
      r.fail(where() + ": expected 'facet' or 'endsolid', found " + (t.empty() ? "the end of the file" : excerpt(t)));
    expect("normal", where);
    for(int c = 0; c < 3; ++c) {
      double ignored;
      const std::string_view n = r.any_token();
      if(!parse_double(n, ignored)) r.fail(where() + ": bad normal component " + excerpt(n));
    }
    expect("outer", where);
    expect("loop", where);
    std::vector<std::size_t> poly(3);
    for(int v = 0; v < 3; ++v) {
      expect("vertex", where);
      std::array<double, 3> p;
      for(int c = 0; c < 3; ++c) {
        const std::string_view x = r.any_token();
        if(!parse_double(x, p[std::size_t(c)])) r.fail(where() + ": bad coordinate " + excerpt(x));
      }
      poly[std::size_t(v)] = merge.index_of(p);
    }
    expect("endloop", [&] { return where() + " (a facet has three vertices)"; });
    expect("endfacet", where);
    soup.polygons.push_back(std::move(poly));
  }
  return soup;
}

inline Polygon_soup parse_stl(std::string_view data)
{
  // Binary when the size matches the declared triangle count exactly (a binary header may
  // also start with "solid"); ASCII when it starts with "solid".
  if(data.size() >= 84) {
    const unsigned char* c = reinterpret_cast<const unsigned char*>(data.data()) + 80;
    const std::uint64_t n = std::uint64_t(c[0]) | std::uint64_t(c[1]) << 8 | std::uint64_t(c[2]) << 16 | std::uint64_t(c[3]) << 24;
    if(84 + 50 * n == data.size()) return parse_stl_binary(data, std::size_t(n));
    std::size_t s = 0;
    while(s < data.size() && s < 256 && std::isspace(static_cast<unsigned char>(data[s]))) ++s;
    if(data.substr(s, 5) != "solid")
      throw Io_error("binary STL: the header declares " + std::to_string(n) + " triangles, which take " +
                     std::to_string(84 + 50 * n) + " bytes, but the file has " + std::to_string(data.size()) +
                     " (and it does not start with 'solid' as ASCII STL does)");
  }
  return parse_stl_ascii(data);
}

/// Parses `data` as the format `ext` ("off", "obj", "ply" or "stl").
inline Polygon_soup parse_mesh(std::string_view data, const std::string& ext)
{
  if(ext == "off") return parse_off(data);
  if(ext == "obj") return parse_obj(data);
  if(ext == "ply") return parse_ply(data);
  if(ext == "stl") return parse_stl(data);
  throw Io_error("unsupported mesh format '." + ext + "' (expected .off, .obj, .ply or .stl)");
}

} // namespace internal
} // namespace io
} // namespace lapmesh

#endif
