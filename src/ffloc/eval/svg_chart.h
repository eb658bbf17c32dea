#pragma once

#include <string>
#include <vector>

namespace ffloc {

// Text made safe inside HTML or SVG, as element content and as a quoted attribute value.
std::string escapeHtml(const std::string& text);

// One axis of a chart: data values in [low, high] onto [0, 1], linearly or in log10, with the
// ticks a reader expects there (decades on a log axis, steps of 1, 2 or 5 on a linear one).
struct PlotAxis {
  double low = 0;
  double high = 1;
  bool logarithmic = false;

  // Values outside [low, high] are pinned to the nearer end, so nothing is drawn off the axis.
  double fraction(double value) const;
  std::vector<double> ticks() const;
};

// The shortest label that tells the ticks of an axis apart: "0.05", "20", "1e-05".
std::string tickLabel(double value);

// A log axis over the decades that hold the finite positive `values`, at most `max_decades` wide
// from the top and not below `floor` (0: none); three decades from the floor, or up to 1, when
// there are no such values.
PlotAxis logAxisOver(const std::vector<double>& values, double floor, int max_decades);

struct SvgPoint {
  double x = 0;
  double y = 0;
};

// An inline SVG chart: a framed plot area with ticks, grid and axis titles, content placed in data
// coordinates and clipped to the area, and a legend beneath that wraps to the chart's width.
class SvgChart {
 public:
  // `plot_height`: the framed plot area's, in pixels; the legend adds to the chart's height.
  SvgChart(int width, int plot_height, PlotAxis x, PlotAxis y, std::string x_title, std::string y_title);

  // Keeps a band at the top of the plot area for +infinite y values (failed frames), labelled
  // `label` on the y axis. Call before placing anything.
  void addInfinityBand(const std::string& label);

  // Makes a data unit span as many pixels on both axes, as a map needs: the plot area's height
  // follows the data's aspect within [min_plot_height, max_plot_height], and one axis's range
  // widens about its centre for the rest. Call before placing anything.
  void fitEqualScale(int min_plot_height, int max_plot_height);

  // The pixel position of a data point inside the plot area; y = +inf lands in the infinity band.
  SvgPoint at(double x, double y) const;

  // Elements in plot-area pixels (from at()), drawn in the order added.
  void addElement(const std::string& svg);
  // A vertical dashed guide at data x, labelled at its top.
  void addGuide(double x, const std::string& label);

  enum class Swatch { kLine, kDot, kCross };
  void addLegendEntry(const std::string& label, const std::string& colour, Swatch swatch);

  std::string svg() const;

 private:
  double frameWidth() const;
  double band() const;  // the infinity band's height, 0 without one
  // Where the data lies: the frame less the padding (and the infinity band).
  double plotWidth() const;
  double plotHeight() const;

  int width_;
  int plot_height_;
  PlotAxis x_, y_;
  std::string x_title_, y_title_;
  std::string infinity_label_;
  std::string content_;
  struct LegendEntry {
    std::string label, colour;
    Swatch swatch;
  };
  std::vector<LegendEntry> legend_;
};

// Pixel coordinates as SVG text, to a tenth of a pixel (finer is invisible and only adds bytes).
std::string svgNumber(double value);

// An SVG path's "d" through the points in order.
std::string pathThrough(const std::vector<SvgPoint>& points);
// An SVG path's "d" with a dot at each point (drawn with round caps): one element for thousands
// of cameras keeps the page small where a circle each would not.
std::string dotsAt(const std::vector<SvgPoint>& points);

}  // namespace ffloc
