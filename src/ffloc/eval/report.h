#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ffloc/core/text_file_writer.h"
#include "ffloc/eval/metrics.h"

namespace ffloc {

// The summary JSON, schema fixed because other tools read it:
// {"results": [{"dataset", "method", "metric", "frames", "failed", "median_t", "median_r_deg",
//               "acc": {"5cm_5deg", "10cm_10deg", "20cm_20deg", "10cm_1deg", "25cm_5deg"},
//               "latency_ms": {"median", "p90"}, "verdict": {...}}, ...]}
// Accuracies are percentages; median_t is in the dataset's units. "metric" is false for the
// datasets named in `non_metric_datasets`, whose units are not metres: their thresholds' names
// (and the verdict's 25 cm) are then read in those units. A median that is infinite (more than
// half the frames failed) is written as null, since JSON has no infinity.
nlohmann::json summaryJson(const std::vector<MethodSummary>& summaries,
                           const std::vector<std::string>& non_metric_datasets = {});

// The summary table's cells, one row per (dataset, method), numbers formatted as every report
// shows them; datasets whose units are not metres are marked so the thresholds are read in their
// units.
struct SummaryTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};
SummaryTable summaryTable(const std::vector<MethodSummary>& summaries,
                          const std::vector<std::string>& non_metric_datasets = {});

// summaryTable as a markdown table like the paper's.
std::string markdownTable(const std::vector<MethodSummary>& summaries, const std::vector<std::string>& non_metric_datasets = {});

// One row per (method, frame): errors, status, inliers, timings and the estimated pose.
std::string perFrameCsv(const std::vector<FrameResult>& frames);

}  // namespace ffloc
