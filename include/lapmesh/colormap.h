// lapmesh — colour maps for per-vertex scalars, with automatic and explicit ranges.
//
// Maps: jet (the seed report's), viridis (perceptually uniform), coolwarm (diverging, for
// signed values), gray. Their names are the Colormap table of types.h (colormap_names() lists
// them with the maps): the CLI's choices, its error messages and doc/cli.md follow it. The viridis and coolwarm tables are sampled at
// nine points and interpolated linearly in sRGB, which is within one 8-bit step of the
// published maps for viridis and close for coolwarm.
#ifndef LAPMESH_COLORMAP_H
#define LAPMESH_COLORMAP_H

#include <lapmesh/types.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace lapmesh {

/// An 8-bit RGB colour.
struct Rgb
{
  std::uint8_t r = 0; ///< red
  std::uint8_t g = 0; ///< green
  std::uint8_t b = 0; ///< blue
};

/// A colour map and its name.
struct Colormap_name
{
  const char* name; ///< as the CLI and the viewer spell it
  Colormap map;     ///< the map
};

/// The colour maps by name, in the order the documentation lists them.
inline const std::array<Colormap_name, 4>& colormap_names()
{
  static const std::array<Colormap_name, 4> names = [] {
    std::array<Colormap_name, 4> out{};
    for(std::size_t i = 0; i < out.size(); ++i) out[i] = {name_table<Colormap>()[i].name, name_table<Colormap>()[i].value};
    return out;
  }();
  return names;
}

/// The names of colormap_names() joined by `separator` (for option help and error messages).
inline std::string colormap_name_list(const std::string& separator = ", ")
{
  return name_list<Colormap>(separator);
}

/// @brief returns the colour map named `s` (a name of colormap_names()), or nothing. The
/// spellings "diverging" and "grey" of earlier versions are still read (as coolwarm and gray)
/// but are no longer offered or listed.
inline std::optional<Colormap> parse_colormap(const std::string& s)
{
  if(const auto map = parse<Colormap>(s)) return map;
  if(s == "diverging") return Colormap::coolwarm;
  if(s == "grey") return Colormap::gray;
  return std::nullopt;
}

namespace internal {
using Rgb_table = std::array<std::array<double, 3>, 9>;
inline const Rgb_table& viridis_table()
{
  static const Rgb_table t = {{{68, 1, 84}, {72, 40, 120}, {62, 73, 137}, {49, 104, 142}, {38, 130, 142},
                               {31, 158, 137}, {53, 183, 121}, {110, 206, 88}, {253, 231, 37}}};
  return t;
}
inline const Rgb_table& coolwarm_table()
{
  static const Rgb_table t = {{{59, 76, 192}, {98, 130, 234}, {141, 176, 254}, {184, 208, 249}, {221, 221, 221},
                               {245, 196, 173}, {244, 154, 123}, {222, 96, 77}, {180, 4, 38}}};
  return t;
}
inline Rgb interpolate(const Rgb_table& t, double x)
{
  const double s = x * 8.0;
  const int i = std::min(7, int(s));
  const double w = s - i;
  auto channel = [&](int k) { return std::uint8_t(std::lround((1 - w) * t[i][k] + w * t[i + 1][k])); };
  return {channel(0), channel(1), channel(2)};
}
} // namespace internal

/// The colour of x in [0, 1] (clamped; NaN maps to the low end).
inline Rgb map_color(Colormap map, double x)
{
  x = std::isnan(x) ? 0.0 : std::clamp(x, 0.0, 1.0);
  auto to8 = [](double v) { return std::uint8_t(std::lround(255.0 * std::clamp(v, 0.0, 1.0))); };
  switch(map) {
    case Colormap::jet:
      return {to8(1.5 - std::abs(4 * x - 3)), to8(1.5 - std::abs(4 * x - 2)), to8(1.5 - std::abs(4 * x - 1))};
    case Colormap::viridis: return internal::interpolate(internal::viridis_table(), x);
    case Colormap::coolwarm: return internal::interpolate(internal::coolwarm_table(), x);
    default: return {to8(x), to8(x), to8(x)};
  }
}

/// The interval of values mapped onto the colour map (values outside are clamped).
struct Value_range
{
  double min = 0; ///< value at the start of the colour map
  double max = 1; ///< value at its end
};

namespace internal {
/// [min, max] of the finite values after discarding clip_percent percent at each end;
/// std::nullopt when no value is finite.
inline std::optional<Value_range> clipped_extremes(const std::vector<double>& values, double clip_percent)
{
  if(!(clip_percent >= 0 && clip_percent < 50)) throw std::invalid_argument("clip percentage must be in [0, 50)");
  std::vector<double> v;
  v.reserve(values.size());
  for(double x : values)
    if(std::isfinite(x)) v.push_back(x);
  if(v.empty()) return std::nullopt;
  const std::size_t k = std::size_t(std::floor(clip_percent / 100.0 * double(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  const double lo = v[k];
  std::nth_element(v.begin(), v.end() - 1 - k, v.end());
  return Value_range{lo, v[v.size() - 1 - k]};
}
} // namespace internal

/// The automatic range of `values`: [min, max] after discarding `clip_percent` percent of the
/// values at each end (0 keeps all); when the clipped range has both signs it is made
/// symmetric about 0, so that 0 sits in the middle of a diverging map.
/// Non-finite values are ignored. A constant signal gets a unit-wide range around it.
inline Value_range auto_range(const std::vector<double>& values, double clip_percent = 0.0)
{
  const std::optional<Value_range> e = internal::clipped_extremes(values, clip_percent);
  if(!e) return {0.0, 1.0};
  double lo = e->min, hi = e->max;
  if(lo < 0 && hi > 0) {
    const double a = std::max(-lo, hi);
    lo = -a;
    hi = a;
  }
  if(!(hi > lo)) {
    lo -= 0.5;
    hi += 0.5;
  }
  return {lo, hi};
}

/// The range [-a, a] symmetric about 0, with a the largest |value| after discarding
/// `clip_percent` percent of the values at each end (as auto_range()): puts 0 in the middle
/// of a diverging map also when the values have one sign. Non-finite values are ignored;
/// a = 0.5 when no value is finite or all are 0.
inline Value_range symmetric_range(const std::vector<double>& values, double clip_percent = 0.0)
{
  const std::optional<Value_range> e = internal::clipped_extremes(values, clip_percent);
  double a = e ? std::max(std::abs(e->min), std::abs(e->max)) : 0.0;
  if(!(a > 0)) a = 0.5;
  return {-a, a};
}

/// Parses "MIN:MAX" (MIN < MAX, finite); std::nullopt if malformed.
inline std::optional<Value_range> parse_range(const std::string& s)
{
  const auto colon = s.find(':');
  if(colon == std::string::npos) return std::nullopt;
  try {
    std::size_t used1 = 0, used2 = 0;
    const std::string a = s.substr(0, colon), b = s.substr(colon + 1);
    const double lo = std::stod(a, &used1), hi = std::stod(b, &used2);
    if(used1 != a.size() || used2 != b.size() || !std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi))
      return std::nullopt;
    return Value_range{lo, hi};
  } catch(const std::exception&) {
    return std::nullopt;
  }
}

/// Colours of `values` through `map` over `range` (values outside are clamped).
inline std::vector<Rgb> colorize(const std::vector<double>& values, Colormap map, Value_range range)
{
  std::vector<Rgb> out(values.size());
  const double scale = 1.0 / (range.max - range.min);
  for(std::size_t i = 0; i < values.size(); ++i) out[i] = map_color(map, (values[i] - range.min) * scale);
  return out;
}

} // namespace lapmesh

#endif
