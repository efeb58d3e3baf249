#include "svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace lapmesh_cli {
namespace {

constexpr double panel_width = 420, axes_left = 70, axes_right = 15, axes_top = 34, axes_height = 250;
constexpr double legend_line = 16;

std::string escape(const std::string& s)
{
  std::string o;
  for(char c : s) {
    if(c == '&') o += "&amp;";
    else if(c == '<') o += "&lt;";
    else if(c == '>') o += "&gt;";
    else if(c == '"') o += "&quot;";
    else o += c;
  }
  return o;
}

std::string num(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string tick_label(double v)
{
  char buf[32];
  if(v == 0) return "0";
  const double a = std::abs(v);
  if(a >= 1e-3 && a < 1e4) std::snprintf(buf, sizeof buf, "%g", v);
  else std::snprintf(buf, sizeof buf, "%.0e", v);
  return buf;
}

struct Axis
{
  bool log = false;
  double lo = 0, hi = 1;
  double map(double v) const { return log ? std::log10(v) : v; }
  bool usable(double v) const { return std::isfinite(v) && (!log || v > 0); }
};

Axis make_axis(bool log, const std::vector<const std::vector<double>*>& data)
{
  Axis a;
  a.log = log;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for(const auto* d : data)
    for(double v : *d)
      if(a.usable(v)) {
        lo = std::min(lo, a.map(v));
        hi = std::max(hi, a.map(v));
      }
  if(!std::isfinite(lo)) lo = 0, hi = 1;
  if(log) {
    lo = std::floor(lo);
    hi = std::ceil(hi);
    if(hi <= lo) hi = lo + 1;
  } else {
    if(hi <= lo) hi = lo + 1;
    const double pad = 0.03 * (hi - lo);
    lo -= pad;
    hi += pad;
  }
  a.lo = lo;
  a.hi = hi;
  return a;
}

std::vector<double> ticks(const Axis& a)
{
  std::vector<double> t;
  if(a.log) {
    const int step = std::max(1, int(std::ceil((a.hi - a.lo) / 6)));
    for(int e = int(a.lo); e <= int(a.hi); e += step) t.push_back(std::pow(10.0, e));
    return t;
  }
  const double range = a.hi - a.lo;
  const double raw = range / 6;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for(double m : {1.0, 2.0, 5.0, 10.0})
    if(m * mag >= raw) {
      step = m * mag;
      break;
    }
  for(double v = std::ceil(a.lo / step) * step; v <= a.hi + 1e-9 * range; v += step) t.push_back(std::abs(v) < 1e-12 * range ? 0 : v);
  return t;
}

} // namespace

void write_svg_plot(std::ostream& out, const std::string& title, const std::vector<Plot_panel>& panels, int columns)
{
  columns = std::max(1, std::min(columns, int(panels.size())));
  std::size_t max_series = 0;
  for(const auto& p : panels) max_series = std::max(max_series, p.series.size());
  const double panel_height = axes_top + axes_height + 45 + legend_line * double(max_series) + 10;
  const int rows = int((panels.size() + std::size_t(columns) - 1) / std::size_t(columns));
  const double width = panel_width * columns, height = 30 + panel_height * rows;
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << num(width) << "\" height=\"" << num(height)
      << "\" viewBox=\"0 0 " << num(width) << ' ' << num(height) << "\" font-family=\"sans-serif\" font-size=\"11\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      << "<text x=\"" << num(width / 2) << "\" y=\"20\" text-anchor=\"middle\" font-size=\"14\">" << escape(title)
      << "</text>\n";
  for(std::size_t k = 0; k < panels.size(); ++k) {
    const Plot_panel& p = panels[k];
    const double ox = panel_width * double(k % std::size_t(columns)), oy = 30 + panel_height * double(k / std::size_t(columns));
    const double x0 = ox + axes_left, x1 = ox + panel_width - axes_right, y0 = oy + axes_top, y1 = y0 + axes_height;
    std::vector<const std::vector<double>*> xs, ys;
    for(const auto& s : p.series) {
      xs.push_back(&s.x);
      ys.push_back(&s.y);
    }
    const Axis ax = make_axis(p.log_x, xs), ay = make_axis(p.log_y, ys);
    auto px = [&](double v) { return x0 + (ax.map(v) - ax.lo) / (ax.hi - ax.lo) * (x1 - x0); };
    auto py = [&](double v) { return y1 - (ay.map(v) - ay.lo) / (ay.hi - ay.lo) * (y1 - y0); };
    out << "<g>\n<text x=\"" << num((x0 + x1) / 2) << "\" y=\"" << num(oy + 20)
        << "\" text-anchor=\"middle\" font-size=\"12\" font-weight=\"bold\">" << escape(p.title) << "</text>\n";
    out << "<rect x=\"" << num(x0) << "\" y=\"" << num(y0) << "\" width=\"" << num(x1 - x0) << "\" height=\""
        << num(y1 - y0) << "\" fill=\"none\" stroke=\"black\"/>\n";
    for(double t : ticks(ax)) {
      const double x = px(t);
      if(x < x0 - 0.5 || x > x1 + 0.5) continue;
      out << "<line x1=\"" << num(x) << "\" y1=\"" << num(y0) << "\" x2=\"" << num(x) << "\" y2=\"" << num(y1)
          << "\" stroke=\"#ddd\"/>\n<text x=\"" << num(x) << "\" y=\"" << num(y1 + 14) << "\" text-anchor=\"middle\">"
          << tick_label(t) << "</text>\n";
    }
    for(double t : ticks(ay)) {
      const double y = py(t);
      if(y < y0 - 0.5 || y > y1 + 0.5) continue;
      out << "<line x1=\"" << num(x0) << "\" y1=\"" << num(y) << "\" x2=\"" << num(x1) << "\" y2=\"" << num(y)
          << "\" stroke=\"#ddd\"/>\n<text x=\"" << num(x0 - 4) << "\" y=\"" << num(y + 4) << "\" text-anchor=\"end\">"
          << tick_label(t) << "</text>\n";
    }
    out << "<text x=\"" << num((x0 + x1) / 2) << "\" y=\"" << num(y1 + 30) << "\" text-anchor=\"middle\">"
        << escape(p.x_label + (p.log_x ? " (log scale)" : "")) << "</text>\n";
    out << "<text transform=\"translate(" << num(ox + 14) << ' ' << num((y0 + y1) / 2)
        << ") rotate(-90)\" text-anchor=\"middle\">" << escape(p.y_label + (p.log_y ? " (log scale)" : ""))
        << "</text>\n";
    out << "<clipPath id=\"clip" << k << "\"><rect x=\"" << num(x0) << "\" y=\"" << num(y0) << "\" width=\""
        << num(x1 - x0) << "\" height=\"" << num(y1 - y0) << "\"/></clipPath>\n<g clip-path=\"url(#clip" << k << ")\">\n";
    // What each series actually draws, so that its legend entry shows the same.
    std::vector<bool> draws_line(p.series.size(), false), draws_markers(p.series.size(), false);
    for(std::size_t k_series = 0; k_series < p.series.size(); ++k_series) {
      const auto& s = p.series[k_series];
      const std::string dash = s.dashed ? " stroke-dasharray=\"6 3\"" : "";
      out << "<g class=\"series\" data-series=\"" << k_series << "\">\n";
      std::string points;
      std::size_t run_length = 0;
      auto flush = [&] {
        if(run_length >= 2) {  // a single point is a marker, not a line
          out << "<polyline fill=\"none\" stroke=\"" << s.color << "\" stroke-width=\"1.8\"" << dash << " points=\""
              << points << "\"/>\n";
          draws_line[k_series] = true;
        }
        points.clear();
        run_length = 0;
      };
      for(std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        if(!ax.usable(s.x[i]) || !ay.usable(s.y[i])) {
          flush();
          continue;
        }
        points += num(px(s.x[i])) + "," + num(py(s.y[i])) + " ";
        ++run_length;
      }
      flush();
      for(std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i)
        if(ax.usable(s.x[i]) && ay.usable(s.y[i])) {
          out << "<circle cx=\"" << num(px(s.x[i])) << "\" cy=\"" << num(py(s.y[i])) << "\" r=\"2\" fill=\"" << s.color
              << "\"/>\n";
          draws_markers[k_series] = true;
        }
      out << "</g>\n";
    }
    out << "</g>\n";
    for(std::size_t i = 0; i < p.series.size(); ++i) {
      const auto& s = p.series[i];
      const double ly = y1 + 46 + legend_line * double(i);
      out << "<g class=\"legend-entry\" data-series=\"" << i << "\">\n";
      if(draws_line[i])
        out << "<line x1=\"" << num(x0) << "\" y1=\"" << num(ly - 4) << "\" x2=\"" << num(x0 + 24) << "\" y2=\""
            << num(ly - 4) << "\" stroke=\"" << s.color << "\" stroke-width=\"2\""
            << (s.dashed ? " stroke-dasharray=\"6 3\"" : "") << "/>\n";
      if(draws_markers[i])
        out << "<circle cx=\"" << num(x0 + 12) << "\" cy=\"" << num(ly - 4) << "\" r=\"2\" fill=\"" << s.color << "\"/>\n";
      const bool empty = !draws_line[i] && !draws_markers[i];
      out << "<text x=\"" << num(x0 + 30) << "\" y=\"" << num(ly) << "\"" << (empty ? " fill=\"#777\"" : "") << ">"
          << escape(empty ? s.label + " (" + s.empty_note + ")" : s.label) << "</text>\n</g>\n";
    }
    out << "</g>\n";
  }
  out << "</svg>\n";
}

} // namespace lapmesh_cli
