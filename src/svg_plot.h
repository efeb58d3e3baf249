// A small SVG line-plot writer for the command-line tool (presentation code, not library):
// a grid of panels, each with labelled axes (linear or log10), tick labels, series drawn as
// polylines with markers, and a legend. Non-finite and (on log axes) non-positive points break
// a series' polyline instead of being drawn.
#ifndef LAPMESH_SRC_SVG_PLOT_H
#define LAPMESH_SRC_SVG_PLOT_H

#include <ostream>
#include <string>
#include <vector>

namespace lapmesh_cli {

struct Plot_series
{
  std::string label;
  std::vector<double> x, y;
  std::string color = "#1f77b4";
  bool dashed = false;
  /// Appended to the legend label when no point can be drawn (the legend then shows no
  /// line for it, since the axes hold none).
  std::string empty_note = "no finite values";
};

struct Plot_panel
{
  std::string title, x_label, y_label;
  bool log_x = false, log_y = false;
  std::vector<Plot_series> series;
};

/// Writes the panels in a grid of `columns` columns with an overall title. Each panel gets
/// its own legend (below the axes). Series k of a panel is drawn in <g class="series"
/// data-series="k"> and its legend entry is <g class="legend-entry" data-series="k">; the
/// entry's sample shows a line only when the series draws one (two consecutive drawable
/// points) and a marker only when it draws markers.
void write_svg_plot(std::ostream& out, const std::string& title, const std::vector<Plot_panel>& panels, int columns);

} // namespace lapmesh_cli

#endif
