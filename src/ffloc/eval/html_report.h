#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/eval/metrics.h"

namespace ffloc {

// What the HTML report needs of one evaluated dataset beyond its FrameResults: the mapping cameras
// for the top view and the query images for the thumbnails. Small, so a long multi-dataset
// evaluation need not keep every Scene until the end.
struct ReportDataset {
  std::string name;  // Scene::name, as FrameResult::dataset names it
  bool metric = true;
  std::vector<Eigen::Vector3d> mapping_centres;
  std::map<std::string, std::filesystem::path> query_images;  // by Frame::name
};

ReportDataset reportDataset(const Scene& scene);

// One self-contained HTML page (docs/report.md): the summary table, cumulative error curves, the
// errors over each query sequence, a top view of the cameras per dataset and method, and
// thumbnails of the worst queries as embedded JPEGs. It references nothing outside itself.
// `summaries` gives the table rows (pooled rows included); `frames` everything else, each matched
// to its dataset by name. A query image that cannot be read gets a note instead of a thumbnail.
// `table_note`, when not empty, is printed under the summary table (how the run was made: the
// benchmark protocol's line).
std::string htmlReport(const std::vector<MethodSummary>& summaries, const std::vector<FrameResult>& frames,
                       const std::vector<ReportDataset>& datasets, const std::string& table_note = "");

}  // namespace ffloc
