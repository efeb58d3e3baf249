// The binary answers of the viewer's API: one "frame" holds a JSON header and large arrays:
// uint32 little-endian header length, the JSON header, space padding to a multiple of 8, then
// the buffers (each padded to a multiple of 8) at the offsets the header gives.
#ifndef LAPMESH_VIEWER_FRAMES_H
#define LAPMESH_VIEWER_FRAMES_H

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>

namespace lapmesh_viewer {

class Frame
{
public:
  template <typename T>
  void add(const std::string& name, const char* type, const T* data, std::size_t count, int components = 1)
  {
    const std::size_t bytes = sizeof(T) * count;
    m_header["buffers"][name] = {{"type", type}, {"offset", m_data.size()}, {"count", count},
                                 {"components", components}};
    m_data.append(reinterpret_cast<const char*>(data), bytes);
    m_data.append((8 - m_data.size() % 8) % 8, '\0');
  }
  nlohmann::json& header() { return m_header; }
  std::string str() const
  {
    std::string h = m_header.dump();
    h.append((8 - (4 + h.size()) % 8) % 8, ' ');
    const std::uint32_t len = std::uint32_t(h.size());
    std::string out(4, '\0');
    for(int i = 0; i < 4; ++i) out[std::size_t(i)] = char((len >> (8 * i)) & 0xff);  // little-endian
    out += h;
    out += m_data;
    return out;
  }

private:
  nlohmann::json m_header = {{"buffers", nlohmann::json::object()}};
  std::string m_data;
};

} // namespace lapmesh_viewer

#endif
