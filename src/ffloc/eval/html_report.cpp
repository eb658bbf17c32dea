#include "ffloc/eval/html_report.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "ffloc/core/error.h"
#include "ffloc/eval/report.h"
#include "ffloc/eval/svg_chart.h"
#include "ffloc/io/image.h"

namespace ffloc {
namespace {

constexpr size_t kWorstQueries = 6;
constexpr int kThumbnailWidth = 160;
constexpr int kThumbnailQuality = 80;
constexpr int kCdfSamples = 300;
constexpr int kMaxDecades = 5;
// Finer than poses are judged at (the ground truth is rarely better), so an exact answer such as
// oracle-depth's 1e-13 m does not stretch the axes over decades nobody reads.
constexpr double kTranslationFloor = 0.001;  // metres; none where a scene is not metric
constexpr double kRotationFloorDeg = 0.01;

// Apart from each other on white, and from the status colours of the top view.
constexpr std::array<const char*, 8> kSeriesColours = {"#1f77b4", "#9467bd", "#17becf", "#8c564b",
                                                       "#e377c2", "#bcbd22", "#393b79", "#7f7f7f"};
constexpr const char* kMappingColour = "#b8b8b8";
constexpr const char* kTruthColour = "#222222";

const char* statusColour(PoseStatus status) {
  switch (status) {
    case PoseStatus::kLocalized: return "#2ca02c";
    case PoseStatus::kUncertain: return "#ff7f0e";
    case PoseStatus::kFailed: break;
  }
  return "#d62728";
}

// The frames of one (dataset, method), in evaluation order.
struct Series {
  std::string dataset, method;
  std::vector<const FrameResult*> frames;
  std::string colour;
  std::string label;

  size_t failed() const {
    return static_cast<size_t>(
        std::count_if(frames.begin(), frames.end(), [](const FrameResult* f) { return !f->succeeded(); }));
  }
};

std::vector<Series> seriesOf(const std::vector<FrameResult>& frames) {
  std::vector<Series> series;
  for (const FrameResult& frame : frames) {
    auto found = std::find_if(series.begin(), series.end(),
                              [&](const Series& s) { return s.dataset == frame.dataset && s.method == frame.method; });
    if (found == series.end()) {
      series.push_back({frame.dataset, frame.method, {}, kSeriesColours[series.size() % kSeriesColours.size()], ""});
      found = series.end() - 1;
    }
    found->frames.push_back(&frame);
  }
  const bool one_dataset =
      std::all_of(series.begin(), series.end(), [&](const Series& s) { return s.dataset == series.front().dataset; });
  for (Series& s : series) {
    s.label = one_dataset ? s.method : s.dataset + " / " + s.method;
    if (s.failed() > 0)
      s.label += " (" + std::to_string(s.failed()) + " of " + std::to_string(s.frames.size()) + " failed)";
  }
  return series;
}

std::vector<const Series*> seriesOfDataset(const std::vector<Series>& series, const std::string& dataset) {
  std::vector<const Series*> chosen;
  for (const Series& s : series)
    if (s.dataset == dataset) chosen.push_back(&s);
  return chosen;
}

std::vector<std::string> datasetNames(const std::vector<Series>& series) {
  std::vector<std::string> names;
  for (const Series& s : series)
    if (std::find(names.begin(), names.end(), s.dataset) == names.end()) names.push_back(s.dataset);
  return names;
}

std::string formatted(const char* format, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

PlotAxis errorAxis(const std::vector<double>& errors, bool rotation, bool metric) {
  return logAxisOver(errors, rotation ? kRotationFloorDeg : metric ? kTranslationFloor : 0, kMaxDecades);
}

std::string strokeAttributes(const std::string& colour, double width) {
  return " fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"" + svgNumber(width) + "\"";
}

std::string dotsElement(const std::string& css_class, const std::vector<SvgPoint>& points, const std::string& colour,
                        double diameter) {
  if (points.empty()) return "";
  return "<path class=\"" + css_class + "\" d=\"" + dotsAt(points) + "\"" + strokeAttributes(colour, diameter) +
         " stroke-linecap=\"round\"/>";
}

std::string crossesElement(const std::vector<SvgPoint>& points, const std::string& colour) {
  if (points.empty()) return "";
  std::string d;
  for (const SvgPoint& p : points) d += "M" + svgNumber(p.x - 4) + " " + svgNumber(p.y - 4) + "l8 8m0 -8l-8 8";
  return "<path class=\"failed\" d=\"" + d + "\"" + strokeAttributes(colour, 1.6) + "/>";
}

std::string tableHtml(const std::vector<MethodSummary>& summaries, const std::vector<ReportDataset>& datasets) {
  std::vector<std::string> non_metric;
  for (const ReportDataset& dataset : datasets)
    if (!dataset.metric) non_metric.push_back(dataset.name);
  const SummaryTable table = summaryTable(summaries, non_metric);
  std::ostringstream out;
  out << "<table class=\"summary\"><thead><tr>";
  for (const std::string& column : table.header) out << "<th>" << escapeHtml(column) << "</th>";
  out << "</tr></thead><tbody>";
  for (const std::vector<std::string>& row : table.rows) {
    out << "<tr>";
    // As in the markdown table: dataset and method are text, the rest numbers.
    for (size_t c = 0; c < row.size(); ++c)
      out << (c < 2 ? "<td>" : "<td class=\"num\">") << escapeHtml(row[c]) << "</td>";
    out << "</tr>";
  }
  out << "</tbody></table>";
  return out.str();
}

// Failed frames are infinite errors: they never count as within, so the curve ends at the share
// of frames with a pose.
std::string cdfChart(const std::vector<Series>& series, bool rotation, bool metric, const std::string& x_title,
                     const std::vector<std::pair<double, std::string>>& guides) {
  auto error = [rotation](const FrameResult* f) { return rotation ? f->rotation_error_deg : f->translation_error; };
  std::vector<double> all;
  for (const Series& s : series)
    for (const FrameResult* f : s.frames) all.push_back(error(f));
  const PlotAxis x = errorAxis(all, rotation, metric);
  SvgChart chart(620, 300, x, {0, 100, false}, x_title, "queries within (%)");
  double last_guide = -1e9;
  for (const auto& [value, label] : guides) {
    const double px = chart.at(value, 0).x;
    if (value <= x.low || value >= x.high || px - last_guide < 14) continue;
    chart.addGuide(value, label);
    last_guide = px;
  }
  for (const Series& s : series) {
    std::vector<double> sorted;
    for (const FrameResult* f : s.frames) sorted.push_back(error(f));
    std::sort(sorted.begin(), sorted.end());
    std::vector<SvgPoint> curve;
    for (int i = 0; i <= kCdfSamples; ++i) {
      const double value = x.low * std::pow(x.high / x.low, static_cast<double>(i) / kCdfSamples);
      const auto within = std::upper_bound(sorted.begin(), sorted.end(), value) - sorted.begin();
      curve.push_back(chart.at(value, 100.0 * static_cast<double>(within) / static_cast<double>(sorted.size())));
    }
    chart.addElement("<path class=\"cdf\" d=\"" + pathThrough(curve) + "\"" + strokeAttributes(s.colour, 2) + "/>");
    chart.addLegendEntry(s.label, s.colour, SvgChart::Swatch::kLine);
  }
  return chart.svg();
}

std::string cdfSection(const std::vector<Series>& series, bool all_metric) {
  std::vector<std::pair<double, std::string>> translation_guides, rotation_guides;
  for (const AccuracyThreshold& threshold : accuracyThresholds()) {
    if (all_metric)
      translation_guides.push_back({threshold.translation, tickLabel(threshold.translation * 100) + " cm"});
    rotation_guides.push_back({threshold.rotation_deg, tickLabel(threshold.rotation_deg) + "°"});
  }
  for (auto* guides : {&translation_guides, &rotation_guides}) {
    std::sort(guides->begin(), guides->end());
    guides->erase(std::unique(guides->begin(), guides->end()), guides->end());
  }
  return "<div class=\"charts\">" +
         cdfChart(series, false, all_metric, all_metric ? "translation error (m)" : "translation error (scene units)",
                  translation_guides) +
         cdfChart(series, true, all_metric, "rotation error (deg)", rotation_guides) + "</div>";
}

std::string perQueryChart(const std::vector<const Series*>& series, bool rotation, bool metric,
                          const std::string& y_title) {
  auto error = [rotation](const FrameResult* f) { return rotation ? f->rotation_error_deg : f->translation_error; };
  std::vector<double> all;
  size_t queries = 0;
  for (const Series* s : series) {
    queries = std::max(queries, s->frames.size());
    for (const FrameResult* f : s->frames) all.push_back(error(f));
  }
  const PlotAxis y = errorAxis(all, rotation, metric);
  SvgChart chart(620, 240, {0, std::max<double>(1, static_cast<double>(queries) - 1), false}, y,
                 "query (in evaluation order)", y_title);
  chart.addInfinityBand("failed");
  for (const Series* s : series) {
    std::string line;
    std::vector<SvgPoint> dots, failures;
    bool pen_down = false;
    for (size_t q = 0; q < s->frames.size(); ++q) {
      const SvgPoint p = chart.at(static_cast<double>(q), error(s->frames[q]));
      if (!s->frames[q]->succeeded()) {
        failures.push_back(p);
        pen_down = false;
        continue;
      }
      line += (pen_down ? " " : "M") + svgNumber(p.x) + " " + svgNumber(p.y);
      pen_down = true;
      dots.push_back(p);
    }
    if (!line.empty())
      chart.addElement("<path class=\"errors\" d=\"" + line + "\"" + strokeAttributes(s->colour, 1.2) + "/>");
    chart.addElement(dotsElement("error-dots", dots, s->colour, 4));
    chart.addElement(crossesElement(failures, s->colour));
    chart.addLegendEntry(s->label, s->colour, SvgChart::Swatch::kLine);
  }
  return chart.svg();
}

// The two world axes along which the cameras spread most, in axis order.
std::array<int, 2> widestAxes(const std::vector<Eigen::Vector3d>& centres) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& c : centres) mean += c;
  mean /= std::max<double>(1, static_cast<double>(centres.size()));
  Eigen::Vector3d spread = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& c : centres) spread += (c - mean).cwiseAbs2();
  int narrowest = 0;
  for (int axis = 1; axis < 3; ++axis)
    if (spread[axis] < spread[narrowest]) narrowest = axis;
  if (narrowest == 0) return {1, 2};
  if (narrowest == 1) return {0, 2};
  return {0, 1};
}

// Mapping cameras, ground truth and estimates of one method on the two axes of widest spread (from
// above in a scene whose up is the third), at equal scale; estimates far off are pinned to the
// border, their lines from the truth still show where they went.
std::string topView(const Series& series, const ReportDataset& dataset) {
  std::vector<Eigen::Vector3d> framed = dataset.mapping_centres;
  for (const FrameResult* f : series.frames) framed.push_back(f->truth.centre());
  const std::array<int, 2> axes = widestAxes(framed);
  Eigen::Vector2d low(INFINITY, INFINITY), high(-INFINITY, -INFINITY);
  for (const Eigen::Vector3d& c : framed) {
    const Eigen::Vector2d p(c[axes[0]], c[axes[1]]);
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  // A margin around the cameras, and some extent when they all stand in one place.
  const Eigen::Vector2d margin = Eigen::Vector2d::Constant(std::max((high - low).maxCoeff(), 1e-6) * 0.05);
  low -= margin;
  high += margin;
  const std::string units = dataset.metric ? " (m)" : "";
  static constexpr std::array<const char*, 3> kAxisNames = {"x", "y", "z"};
  SvgChart chart(560, 0, {low.x(), high.x(), false}, {low.y(), high.y(), false}, kAxisNames[axes[0]] + units,
                 kAxisNames[axes[1]] + units);
  chart.fitEqualScale(260, 520);
  auto at = [&](const Eigen::Vector3d& c) { return chart.at(c[axes[0]], c[axes[1]]); };

  std::vector<SvgPoint> mapping;
  for (const Eigen::Vector3d& c : dataset.mapping_centres) mapping.push_back(at(c));
  chart.addElement(dotsElement("mapping", mapping, kMappingColour, 4));
  std::vector<SvgPoint> truths, failures;
  for (PoseStatus status : {PoseStatus::kLocalized, PoseStatus::kUncertain, PoseStatus::kFailed}) {
    std::string offsets;
    std::vector<SvgPoint> estimates;
    for (const FrameResult* f : series.frames) {
      if (!f->succeeded() || f->verdict != status) continue;
      const SvgPoint truth = at(f->truth.centre()), estimate = at(f->estimate.centre());
      offsets += "M" + svgNumber(truth.x) + " " + svgNumber(truth.y) + "L" + svgNumber(estimate.x) + " " +
                 svgNumber(estimate.y);
      estimates.push_back(estimate);
    }
    if (!offsets.empty())
      chart.addElement("<path class=\"offset\" d=\"" + offsets + "\"" + strokeAttributes(statusColour(status), 1) +
                       "/>");
    chart.addElement(dotsElement(std::string("estimate ") + toString(status), estimates, statusColour(status), 6));
  }
  for (const FrameResult* f : series.frames) (f->succeeded() ? truths : failures).push_back(at(f->truth.centre()));
  chart.addElement(dotsElement("truth", truths, kTruthColour, 2.5));
  chart.addElement(crossesElement(failures, statusColour(PoseStatus::kFailed)));

  chart.addLegendEntry("mapping", kMappingColour, SvgChart::Swatch::kDot);
  chart.addLegendEntry("truth", kTruthColour, SvgChart::Swatch::kDot);
  chart.addLegendEntry("localized", statusColour(PoseStatus::kLocalized), SvgChart::Swatch::kDot);
  chart.addLegendEntry("uncertain", statusColour(PoseStatus::kUncertain), SvgChart::Swatch::kDot);
  chart.addLegendEntry("failed", statusColour(PoseStatus::kFailed), SvgChart::Swatch::kCross);
  return "<figure class=\"view\"><figcaption>" + escapeHtml(series.method) + "</figcaption>" + chart.svg() +
         "</figure>";
}

std::string base64(const std::vector<unsigned char>& bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const size_t n = std::min<size_t>(3, bytes.size() - i);
    uint32_t block = static_cast<uint32_t>(bytes[i]) << 16;
    if (n > 1) block |= static_cast<uint32_t>(bytes[i + 1]) << 8;
    if (n > 2) block |= bytes[i + 2];
    for (size_t k = 0; k < 4; ++k) out += k <= n ? kAlphabet[(block >> (18 - 6 * k)) & 63] : '=';
  }
  return out;
}

// "" when the image cannot be read: the report is written after the evaluation, which one
// unreadable image should not undo.
std::string thumbnailDataUri(const std::filesystem::path& path) {
  cv::Mat image;
  try {
    image = readImageRgb(path);
  } catch (const InputError&) {
    return "";
  }
  cv::Mat small, bgr;
  const int height =
      std::max(1, static_cast<int>(std::lround(image.rows * static_cast<double>(kThumbnailWidth) / image.cols)));
  cv::resize(image, small, {kThumbnailWidth, height}, 0, 0, cv::INTER_AREA);
  cv::cvtColor(small, bgr, cv::COLOR_RGB2BGR);
  std::vector<unsigned char> jpeg;
  if (!cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, kThumbnailQuality})) return "";
  return "data:image/jpeg;base64," + base64(jpeg);
}

// Long frame names wrap after a folder before anywhere else.
std::string breakableAtSlashes(const std::string& html) {
  std::string out;
  for (char c : html) out += c == '/' ? std::string("/<wbr>") : std::string(1, c);
  return out;
}

std::string worstQueries(const Series& series, const ReportDataset& dataset) {
  // Positions in evaluation order, which the captions give to find a query on the error plots.
  std::vector<size_t> ranked(series.frames.size());
  for (size_t q = 0; q < ranked.size(); ++q) ranked[q] = q;
  std::stable_sort(ranked.begin(), ranked.end(), [&](size_t a, size_t b) {
    const FrameResult& fa = *series.frames[a];
    const FrameResult& fb = *series.frames[b];
    if (fa.translation_error != fb.translation_error) return fa.translation_error > fb.translation_error;
    return fa.rotation_error_deg > fb.rotation_error_deg;
  });
  ranked.resize(std::min(ranked.size(), kWorstQueries));
  const std::string units = dataset.metric ? " m" : "";
  std::ostringstream out;
  out << "<h4>" << escapeHtml(series.method) << "</h4><div class=\"thumbs\">";
  for (size_t q : ranked) {
    const FrameResult* f = series.frames[q];
    const auto image = dataset.query_images.find(f->frame);
    const std::string uri = image == dataset.query_images.end() ? "" : thumbnailDataUri(image->second);
    out << "<figure class=\"thumb\">";
    if (uri.empty())
      out << "<div class=\"missing\">image not readable</div>";
    else
      out << "<img alt=\"" << escapeHtml(f->frame) << "\" src=\"" << uri << "\">";
    out << "<figcaption>query " << q << " · <span class=\"status\" style=\"color:" << statusColour(f->verdict) << "\">"
        << toString(f->verdict) << "</span><br><span class=\"name\">" << breakableAtSlashes(escapeHtml(f->frame))
        << "</span><br>";
    if (f->succeeded())
      out << "t " << formatted("%.3g", f->translation_error) << units << ", r "
          << formatted("%.3g", f->rotation_error_deg) << "°";
    else
      out << "no pose (" << toString(f->status) << ")";
    out << "</figcaption></figure>";
  }
  out << "</div>";
  return out.str();
}

constexpr const char* kStyle = R"(
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:24px;color:#222;max-width:1320px}
h1{font-size:22px}h2{font-size:18px;margin-top:32px;border-bottom:1px solid #ddd}
h3{font-size:15px;margin:14px 0 6px}h4{font-size:13px;margin:10px 0 4px}
p.note{color:#555;font-size:13px;max-width:900px}nav{font-size:13px}
table.summary{border-collapse:collapse;font-size:12px}
table.summary th,table.summary td{border:1px solid #ccc;padding:3px 6px}
table.summary th{background:#f3f3f3}table.summary td{white-space:nowrap}
td.num{text-align:right;font-variant-numeric:tabular-nums}
.charts{display:flex;flex-wrap:wrap;gap:12px 24px}
svg.chart{font-size:12px;font-family:inherit}
svg .grid{stroke:#ebebeb}svg .frame{fill:none;stroke:#999}
svg .band{stroke:#ccc;stroke-dasharray:4 3}svg .guide{stroke:#aaa;stroke-dasharray:3 3}
svg .guide-label{fill:#888;font-size:10px}
figure{margin:0}figure.view figcaption{font-size:13px;font-weight:600;margin-left:72px}
.thumbs{display:flex;flex-wrap:wrap;gap:12px}
figure.thumb{width:160px;font-size:11px;line-height:1.35}
figure.thumb img{display:block;width:160px;border:1px solid #ccc}
figure.thumb .missing{width:158px;height:100px;border:1px dashed #bbb;color:#888;
  display:flex;align-items:center;justify-content:center}
figure.thumb .name{overflow-wrap:anywhere}figure.thumb .status{font-weight:600}
)";

}  // namespace

ReportDataset reportDataset(const Scene& scene) {
  ReportDataset dataset;
  dataset.name = scene.name;
  dataset.metric = scene.metric;
  for (size_t index : scene.mappingIndices())
    dataset.mapping_centres.push_back(scene.frames[index].camera_to_world.centre());
  for (size_t index : scene.queryIndices())
    dataset.query_images[scene.frames[index].name] = scene.frames[index].image_path;
  return dataset;
}

std::string htmlReport(const std::vector<MethodSummary>& summaries, const std::vector<FrameResult>& frames,
                       const std::vector<ReportDataset>& datasets, const std::string& table_note) {
  const std::vector<Series> series = seriesOf(frames);
  static const ReportDataset kUnknownDataset;
  auto datasetNamed = [&](const std::string& name) -> const ReportDataset& {
    const auto found =
        std::find_if(datasets.begin(), datasets.end(), [&](const ReportDataset& d) { return d.name == name; });
    return found == datasets.end() ? kUnknownDataset : *found;
  };
  const bool all_metric =
      std::all_of(series.begin(), series.end(), [&](const Series& s) { return datasetNamed(s.dataset).metric; });

  std::ostringstream out;
  out << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>ffloc evaluation</title><style>"
      << kStyle << "</style></head><body>\n<h1>ffloc evaluation</h1>\n";
  out << "<p class=\"note\">" << frames.size() << " query localizations over " << datasetNames(series).size()
      << " dataset(s). Failed frames count as infinite error: they are misses in every accuracy, a cumulative curve "
         "that ends below 100 % is short by its failures, and they are marked on the error plots.</p>\n";
  out << "<nav><a href=\"#summary\">summary</a> · <a href=\"#cumulative\">cumulative error</a> · "
         "<a href=\"#per-query\">errors per query</a> · <a href=\"#top-view\">top view</a> · "
         "<a href=\"#worst\">worst queries</a></nav>\n";
  out << "<h2 id=\"summary\">Summary</h2>\n" << tableHtml(summaries, datasets) << "\n";
  if (!table_note.empty()) out << "<p class=\"note\">" << escapeHtml(table_note) << "</p>\n";
  out << "<h2 id=\"cumulative\">Cumulative error</h2>\n" << cdfSection(series, all_metric) << "\n";
  out << "<h2 id=\"per-query\">Errors per query</h2>\n";
  for (const std::string& name : datasetNames(series)) {
    const std::vector<const Series*> of_dataset = seriesOfDataset(series, name);
    const bool metric = datasetNamed(name).metric;
    out << "<h3>" << escapeHtml(name) << "</h3><div class=\"charts\">"
        << perQueryChart(of_dataset, false, metric, metric ? "translation error (m)" : "translation error")
        << perQueryChart(of_dataset, true, metric, "rotation error (deg)") << "</div>\n";
  }
  out << "<h2 id=\"top-view\">Top view</h2>\n<p class=\"note\">Camera centres on the two world axes along which "
         "they spread most; lines join each query's true centre to its estimate, coloured by the verdict.</p>\n";
  for (const std::string& name : datasetNames(series)) {
    out << "<h3>" << escapeHtml(name) << "</h3><div class=\"charts\">";
    for (const Series* s : seriesOfDataset(series, name)) out << topView(*s, datasetNamed(name));
    out << "</div>\n";
  }
  out << "<h2 id=\"worst\">Worst queries</h2>\n<p class=\"note\">The " << kWorstQueries
      << " queries with the largest translation error per method; failed ones first.</p>\n";
  for (const std::string& name : datasetNames(series)) {
    out << "<h3>" << escapeHtml(name) << "</h3>\n";
    for (const Series* s : seriesOfDataset(series, name)) out << worstQueries(*s, datasetNamed(name)) << "\n";
  }
  out << "</body></html>\n";
  return out.str();
}

}  // namespace ffloc
