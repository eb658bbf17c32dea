#include "ffloc/eval/svg_chart.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace ffloc {
namespace {

constexpr double kMarginLeft = 72;
constexpr double kMarginRight = 16;
constexpr double kMarginTop = 10;
constexpr double kMarginBottom = 42;
// Between the frame and the data, so a curve at 100 % or a point pinned to an axis end is not
// hidden under the frame.
constexpr double kPadding = 6;
constexpr double kInfinityBand = 22;
constexpr double kLegendRow = 18;
// A rough width of one character at the chart's 12 px sans-serif, enough to wrap the legend.
constexpr double kCharWidth = 6.8;

std::string attribute(const std::string& name, const std::string& value) { return " " + name + "=\"" + value + "\""; }

std::string textAt(double x, double y, const std::string& text, const std::string& anchor,
                   const std::string& extra = "") {
  return "<text" + attribute("x", svgNumber(x)) + attribute("y", svgNumber(y)) + attribute("text-anchor", anchor) +
         extra + ">" + escapeHtml(text) + "</text>";
}

}  // namespace

std::string escapeHtml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

double PlotAxis::fraction(double value) const {
  if (std::isnan(value)) return 0;
  if (high <= low) return 0.5;
  double f;
  if (logarithmic)
    f = value <= 0 ? 0 : (std::log10(value) - std::log10(low)) / (std::log10(high) - std::log10(low));
  else
    f = (value - low) / (high - low);
  return std::clamp(f, 0.0, 1.0);
}

std::vector<double> PlotAxis::ticks() const {
  std::vector<double> ticks;
  if (logarithmic) {
    for (int k = static_cast<int>(std::ceil(std::log10(low) - 1e-9)); k <= std::floor(std::log10(high) + 1e-9); ++k)
      ticks.push_back(std::pow(10.0, k));
    return ticks;
  }
  const double span = high - low;
  if (!(span > 0)) return {low};
  const double rough = span / 6;
  const double magnitude = std::pow(10.0, std::floor(std::log10(rough)));
  double step = 10 * magnitude;
  for (double multiple : {1.0, 2.0, 5.0})
    if (multiple * magnitude >= rough) {
      step = multiple * magnitude;
      break;
    }
  // Multiples of the step, not a running sum, whose rounding could drop the last tick.
  for (double k = std::ceil(low / step - 1e-9); k * step <= high + 1e-9 * span; ++k)
    ticks.push_back(k == 0 ? 0.0 : k * step);
  return ticks;
}

std::string tickLabel(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  return buffer;
}

PlotAxis logAxisOver(const std::vector<double>& values, double floor, int max_decades) {
  double smallest = INFINITY, largest = 0;
  for (double v : values)
    if (std::isfinite(v) && v > 0) {
      smallest = std::min(smallest, v);
      largest = std::max(largest, v);
    }
  if (largest == 0) return floor > 0 ? PlotAxis{floor, 1000 * floor, true} : PlotAxis{0.001, 1, true};
  const double high_decade = std::ceil(std::log10(largest) - 1e-9);
  double low_decade = std::floor(std::log10(smallest) + 1e-9);
  low_decade = std::max(low_decade, high_decade - max_decades);
  if (floor > 0) low_decade = std::max(low_decade, std::floor(std::log10(floor) + 1e-9));
  if (low_decade >= high_decade) low_decade = high_decade - 1;
  return {std::pow(10.0, low_decade), std::pow(10.0, high_decade), true};
}

std::string svgNumber(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.1f", value);
  std::string text = buffer;
  if (text.size() > 2 && text.compare(text.size() - 2, 2, ".0") == 0) text.resize(text.size() - 2);
  return text == "-0" ? "0" : text;
}

std::string pathThrough(const std::vector<SvgPoint>& points) {
  std::string d;
  for (size_t i = 0; i < points.size(); ++i)
    d += (i == 0 ? "M" : " ") + svgNumber(points[i].x) + " " + svgNumber(points[i].y);
  return d;
}

std::string dotsAt(const std::vector<SvgPoint>& points) {
  std::string d;
  for (const SvgPoint& p : points) d += "M" + svgNumber(p.x) + " " + svgNumber(p.y) + "h0";
  return d;
}

SvgChart::SvgChart(int width, int plot_height, PlotAxis x, PlotAxis y, std::string x_title, std::string y_title)
    : width_(width),
      plot_height_(plot_height),
      x_(x),
      y_(y),
      x_title_(std::move(x_title)),
      y_title_(std::move(y_title)) {}

void SvgChart::addInfinityBand(const std::string& label) { infinity_label_ = label; }

double SvgChart::frameWidth() const { return width_ - kMarginLeft - kMarginRight; }
double SvgChart::band() const { return infinity_label_.empty() ? 0 : kInfinityBand; }
double SvgChart::plotWidth() const { return frameWidth() - 2 * kPadding; }
double SvgChart::plotHeight() const { return plot_height_ - 2 * kPadding - band(); }

void SvgChart::fitEqualScale(int min_plot_height, int max_plot_height) {
  const double data_height = plotWidth() * (y_.high - y_.low) / (x_.high - x_.low);
  plot_height_ =
      std::clamp(static_cast<int>(std::lround(data_height + 2 * kPadding + band())), min_plot_height, max_plot_height);
  const double per_pixel = std::max((x_.high - x_.low) / plotWidth(), (y_.high - y_.low) / plotHeight());
  for (auto [axis, pixels] : {std::pair{&x_, plotWidth()}, std::pair{&y_, plotHeight()}}) {
    const double centre = (axis->low + axis->high) / 2;
    axis->low = centre - per_pixel * pixels / 2;
    axis->high = centre + per_pixel * pixels / 2;
  }
}

SvgPoint SvgChart::at(double x, double y) const {
  const double px = kPadding + x_.fraction(x) * plotWidth();
  if (band() > 0 && y == INFINITY) return {px, band() / 2};
  return {px, band() + kPadding + (1 - y_.fraction(y)) * plotHeight()};
}

void SvgChart::addElement(const std::string& svg) { content_ += svg; }

void SvgChart::addGuide(double x, const std::string& label) {
  const double px = at(x, y_.low).x;
  content_ +=
      "<path class=\"guide\"" +
      attribute("d", "M" + svgNumber(px) + " " + svgNumber(band()) + "V" + svgNumber(plot_height_)) + "/>" +
      textAt(0, 0, label, "end",
             " class=\"guide-label\"" + attribute("transform", "translate(" + svgNumber(px - 3) + " " +
                                                                   svgNumber(band() + kPadding) + ") rotate(-90)"));
}

void SvgChart::addLegendEntry(const std::string& label, const std::string& colour, Swatch swatch) {
  legend_.push_back({label, colour, swatch});
}

std::string SvgChart::svg() const {
  std::ostringstream legend;
  double x = kMarginLeft, row = 0;
  for (const LegendEntry& entry : legend_) {
    const double entry_width = 30 + kCharWidth * static_cast<double>(entry.label.size()) + 18;
    if (x > kMarginLeft && x + entry_width > width_) {
      x = kMarginLeft;
      ++row;
    }
    const double y = kMarginTop + plot_height_ + kMarginBottom + row * kLegendRow + kLegendRow / 2;
    switch (entry.swatch) {
      case Swatch::kLine:
        legend << "<path" << attribute("d", "M" + svgNumber(x) + " " + svgNumber(y) + "h24")
               << attribute("stroke", entry.colour) << " stroke-width=\"2\"/>";
        break;
      case Swatch::kDot:
        legend << "<circle" << attribute("cx", svgNumber(x + 12)) << attribute("cy", svgNumber(y)) << " r=\"4\""
               << attribute("fill", entry.colour) << "/>";
        break;
      case Swatch::kCross:
        legend << "<path" << attribute("d", "M" + svgNumber(x + 8) + " " + svgNumber(y - 4) + "l8 8m0 -8l-8 8")
               << attribute("stroke", entry.colour) << " stroke-width=\"2\"/>";
        break;
    }
    legend << textAt(x + 30, y + 4, entry.label, "start");
    x += entry_width;
  }
  const double legend_height = legend_.empty() ? 0 : (row + 1) * kLegendRow + 4;
  const double height = kMarginTop + plot_height_ + kMarginBottom + legend_height;

  std::ostringstream out;
  out << "<svg class=\"chart\"" << attribute("width", std::to_string(width_)) << attribute("height", svgNumber(height))
      << attribute("viewBox", "0 0 " + std::to_string(width_) + " " + svgNumber(height)) << ">";
  out << "<g" << attribute("transform", "translate(" + svgNumber(kMarginLeft) + " " + svgNumber(kMarginTop) + ")")
      << ">";
  for (double tick : x_.ticks()) {
    const double px = at(tick, y_.low).x;
    out << "<path class=\"grid\"" << attribute("d", "M" + svgNumber(px) + " 0V" + std::to_string(plot_height_)) << "/>"
        << textAt(px, plot_height_ + 15, tickLabel(tick), "middle");
  }
  for (double tick : y_.ticks()) {
    const double py = at(x_.low, tick).y;
    // Smaller values are drawn at the foot of the axis (an exact pose's 1e-13 m among centimetres).
    const bool foot = y_.logarithmic && tick <= y_.low;
    out << "<path class=\"grid\"" << attribute("d", "M0 " + svgNumber(py) + "H" + svgNumber(frameWidth())) << "/>"
        << textAt(-6, py + 4, (foot ? "≤" : "") + tickLabel(tick), "end");
  }
  if (!infinity_label_.empty()) {
    out << "<path class=\"band\"" << attribute("d", "M0 " + svgNumber(band()) + "H" + svgNumber(frameWidth())) << "/>"
        << textAt(-6, band() / 2 + 4, infinity_label_, "end");
  }
  const std::string frame_size =
      attribute("width", svgNumber(frameWidth())) + attribute("height", std::to_string(plot_height_));
  out << "<rect class=\"frame\"" << frame_size << "/>";
  // A nested svg clips what it holds to its box; a clipPath would need an id unique on the page.
  out << "<svg" << frame_size << ">" << content_ << "</svg>";
  out << textAt(frameWidth() / 2, plot_height_ + 34, x_title_, "middle");
  out << textAt(0, 0, y_title_, "middle",
                attribute("transform", "translate(-56 " + svgNumber(plot_height_ / 2.0) + ") rotate(-90)"));
  out << "</g>" << legend.str() << "</svg>";
  return out.str();
}

}  // namespace ffloc
