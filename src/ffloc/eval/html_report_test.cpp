// The HTML report of a small real evaluation: a synthetic RGB-D scene localised by oracle-depth and
// by a degraded oracle that fails one query, with names that need escaping.
#include "ffloc/eval/html_report.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/testing/shared_data.h"
#include "ffloc/eval/evaluator.h"
#include "ffloc/eval/oracle_depth_source.h"
#include "ffloc/eval/report.h"
#include "ffloc/eval/svg_chart.h"
#include "ffloc/synthetic/synthetic.h"

namespace ffloc {
namespace {

const char* const kDatasetName = "room <&\"1\">";
const char* const kDegradedMethod = "noisy <&\"oracle\">";
const char* const kFailingFrame = "images/<q&\"first\">.png";

// oracle-depth with noisy 3D points, so poses are a little off, and no pairs for the first query,
// so it fails.
class DegradedOracle : public CoordinateSource {
 public:
  DegradedOracle() : oracle_(OracleDepthOptions{4, 1.0, 0.2, 0.05, 3}) {}
  std::string name() const override { return kDegradedMethod; }
  void prepare(const Scene& scene) override {
    oracle_.prepare(scene);
    first_query_ = scene.queryIndices().front();
  }
  Correspondences correspondences(const Scene& scene, size_t query_index) override {
    if (query_index == first_query_) return {};
    return oracle_.correspondences(scene, query_index);
  }

 private:
  OracleDepthSource oracle_;
  size_t first_query_ = 0;
};

struct Evaluation {
  Scene scene;
  std::vector<FrameResult> frames;
  std::vector<MethodSummary> summaries;
  std::string html;
};

const Evaluation& evaluation() {
  static const Evaluation result = [] {
    Evaluation e;
    SyntheticOptions options;
    options.seed = 23;
    options.width = 128;
    options.height = 96;
    options.mapping_frames = 9;
    options.query_frames = 8;
    e.scene = generateSyntheticScene(options, testing::makeTempDir("ffloc-html-report"));
    e.scene.name = kDatasetName;
    e.scene.frames[e.scene.queryIndices().front()].name = kFailingFrame;
    EvaluationOptions evaluation_options;
    evaluation_options.quiet = true;
    OracleDepthSource oracle;
    DegradedOracle degraded;
    for (CoordinateSource* source : std::initializer_list<CoordinateSource*>{&oracle, &degraded}) {
      const std::vector<FrameResult> frames = evaluate(e.scene, *source, evaluation_options);
      e.summaries.push_back(summarize(frames));
      e.frames.insert(e.frames.end(), frames.begin(), frames.end());
    }
    e.html = htmlReport(e.summaries, e.frames, {reportDataset(e.scene)});
    return e;
  }();
  return result;
}

size_t count(const std::string& text, const std::string& part) {
  size_t n = 0;
  for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + part.size())) ++n;
  return n;
}

// What follows each `prefix` up to the next quote: the rest of an attribute value.
std::vector<std::string> valuesAfter(const std::string& html, const std::string& prefix) {
  std::vector<std::string> values;
  for (size_t at = html.find(prefix); at != std::string::npos; at = html.find(prefix, at + 1)) {
    const size_t start = at + prefix.size();
    values.push_back(html.substr(start, html.find('"', start) - start));
  }
  return values;
}

std::vector<unsigned char> decodeBase64(const std::string& text) {
  static const std::string kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::vector<unsigned char> bytes;
  uint32_t block = 0;
  int bits = 0;
  for (char c : text) {
    if (c == '=') break;
    const size_t value = kAlphabet.find(c);
    if (value == std::string::npos) return {};
    block = (block << 6) | static_cast<uint32_t>(value);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      bytes.push_back(static_cast<unsigned char>((block >> bits) & 0xff));
    }
  }
  return bytes;
}

TEST(HtmlReport, IsOneSelfContainedPage) {
  const std::string& html = evaluation().html;
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(count(html, "</html>"), 1u);
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_EQ(html.find("url("), std::string::npos);
}

TEST(HtmlReport, TableHasTheMarkdownTablesNumbers) {
  const Evaluation& e = evaluation();
  ASSERT_EQ(e.summaries[1].failed, 1);
  const SummaryTable table = summaryTable(e.summaries);
  ASSERT_EQ(table.rows.size(), 2u);
  for (const std::string& column : table.header) EXPECT_NE(e.html.find("<th>" + column + "</th>"), std::string::npos);
  for (const std::vector<std::string>& row : table.rows)
    for (size_t c = 2; c < row.size(); ++c)
      EXPECT_NE(e.html.find("<td class=\"num\">" + row[c] + "</td>"), std::string::npos) << table.header[c];
  // Each number also is one the markdown table prints.
  const std::string markdown = markdownTable(e.summaries);
  for (const std::vector<std::string>& row : table.rows)
    for (size_t c = 2; c < row.size(); ++c) EXPECT_NE(markdown.find("| " + row[c] + " |"), std::string::npos);
}

TEST(HtmlReport, OneCumulativeCurvePerMethodInEachOfTheTwoCharts) {
  EXPECT_EQ(count(evaluation().html, "<path class=\"cdf\""), 2u * 2u);
}

// The degraded method fails its first query: its curve ends at 7 of 8, an eighth of the plot's
// height (the 300 px frame less 6 px of padding at either end) below oracle-depth's 100 %.
TEST(HtmlReport, FailuresKeepTheCurveBelowTheTop) {
  const std::vector<std::string> curves = valuesAfter(evaluation().html, "<path class=\"cdf\" d=\"");
  ASSERT_EQ(curves.size(), 4u);
  auto last_y = [](const std::string& d) { return std::stod(d.substr(d.rfind(' ') + 1)); };
  EXPECT_NEAR(last_y(curves[1]) - last_y(curves[0]), (300 - 2 * 6) / 8.0, 0.1);
}

TEST(HtmlReport, TopViewHasOneMarkerPerMappingCamera) {
  const Evaluation& e = evaluation();
  const std::vector<std::string> views = valuesAfter(e.html, "<path class=\"mapping\" d=\"");
  EXPECT_EQ(views.size(), 2u);  // one per method
  for (const std::string& markers : views) EXPECT_EQ(count(markers, "h0"), e.scene.mappingIndices().size());
}

TEST(HtmlReport, WorstQueriesAreDecodableJpegThumbnails) {
  const std::string& html = evaluation().html;
  const std::vector<std::string> thumbnails = valuesAfter(html, "src=\"data:image/jpeg;base64,");
  for (const std::string& encoded : thumbnails) {
    const std::vector<unsigned char> jpeg = decodeBase64(encoded);
    const cv::Mat image = cv::imdecode(jpeg, cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty());
    EXPECT_EQ(image.cols, 160);
    EXPECT_EQ(image.rows, 120);  // 128x96 scaled to 160 wide
  }
  EXPECT_EQ(thumbnails.size(), 2u * 6u);
  EXPECT_NE(html.find("no pose ("), std::string::npos) << "the failed query is among the worst";
}

TEST(HtmlReport, NamesAreEscaped) {
  const std::string& html = evaluation().html;
  for (const char* raw : {"<&\"", "room <&", "oracle\">", "<q&"}) EXPECT_EQ(html.find(raw), std::string::npos) << raw;
  EXPECT_NE(html.find(escapeHtml(kDatasetName)), std::string::npos);
  EXPECT_NE(html.find(escapeHtml(kDegradedMethod)), std::string::npos);
  EXPECT_NE(html.find("alt=\"" + escapeHtml(kFailingFrame) + "\""), std::string::npos);
  EXPECT_EQ(escapeHtml("a<b&c\"d'e>"), "a&lt;b&amp;c&quot;d&#39;e&gt;");
}

TEST(HtmlReport, UnreadableImageGetsANoteNotAnError) {
  const Evaluation& e = evaluation();
  ReportDataset dataset = reportDataset(e.scene);
  for (auto& [name, path] : dataset.query_images) path = "/nonexistent/" + name;
  const std::string html = htmlReport(e.summaries, e.frames, {dataset});
  EXPECT_EQ(html.find("data:image/jpeg"), std::string::npos);
  EXPECT_EQ(count(html, "image not readable"), 2u * 6u);
}

TEST(SvgChart, AxesAndTicks) {
  const PlotAxis log_axis = logAxisOver({0.0, 0.004, 0.3, INFINITY}, 0, 5);
  EXPECT_DOUBLE_EQ(log_axis.low, 0.001);
  EXPECT_DOUBLE_EQ(log_axis.high, 1);
  EXPECT_EQ(log_axis.ticks().size(), 4u);
  EXPECT_DOUBLE_EQ(log_axis.fraction(0.0), 0);  // below the axis: pinned to its start
  EXPECT_DOUBLE_EQ(log_axis.fraction(0.01), 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(logAxisOver({1e-9, 2.0}, 0, 5).low, 1e-4);      // at most 5 decades
  EXPECT_DOUBLE_EQ(logAxisOver({1e-9, 2.0}, 0.002, 5).low, 1e-3);  // nor below the floor's decade
  EXPECT_DOUBLE_EQ(logAxisOver({}, 0.01, 5).high, 10);
  EXPECT_EQ(PlotAxis({-0.3, 1.1, false}).ticks(), (std::vector<double>{0, 0.5, 1}));  // steps of 1, 2 or 5
  const std::vector<double> ticks = PlotAxis{0, 0.9, false}.ticks();
  ASSERT_EQ(ticks.size(), 5u);
  for (size_t k = 0; k < ticks.size(); ++k) EXPECT_NEAR(ticks[k], 0.2 * static_cast<double>(k), 1e-12);
  EXPECT_EQ(tickLabel(0.05), "0.05");
  EXPECT_EQ(svgNumber(12.04), "12");
  EXPECT_EQ(svgNumber(-0.01), "0");
  EXPECT_EQ(dotsAt({{1, 2}, {3.26, 4}}), "M1 2h0M3.3 4h0");
}

}  // namespace
}  // namespace ffloc
