#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ffloc/data/scene.h"

namespace ffloc {

// The settings the paper (FastForward) evaluates each benchmark with, and what its tables report,
// so `ffloc eval --protocol NAME` reproduces a table's setting. docs/protocols.md maps every
// table to a command line.
struct BenchmarkProtocol {
  std::string name;          // "7scenes", "wayspots", "indoor6", "rio10", "cambridge"
  std::string paper_tables;  // where the numbers are, e.g. "Table 3 (tab:indoor6_rio10, left)"
  bool outdoor = false;
  size_t top_k = 10;        // retrieved mapping images per query: indoor 10, outdoor 20
  int64_t features = 1500;  // N, map features sampled per query: indoor 1500, outdoor 3000
  // Summary-JSON keys (AccuracyThreshold::key) of the accuracies the tables give.
  std::vector<std::string> accuracy_keys;
  bool medians = true;  // the tables give median translation and rotation errors
  // Keep every n-th mapping frame as a retrieval candidate (7-Scenes: "a frame rate of fifteen").
  int mapping_stride = 1;
  // FastForward's mapping time as the table prints it (the retrieval index), or how the text
  // gives it where the table leaves the cell empty.
  std::string mapping_time;
};

// Every protocol, in the order of the paper's sections.
const std::vector<BenchmarkProtocol>& benchmarkProtocols();

// The protocol called `name`; InputError "protocol: unknown protocol ..." listing the known ones.
const BenchmarkProtocol& benchmarkProtocol(const std::string& name);

// Keeps one mapping frame in `stride` and makes the others unassigned, as the paper thins
// 7-Scenes' 30 Hz mapping scans. Frames named "frame-NNNNNN..." are thinned by that capture
// number within their folder (a kept frame, then the first at least `stride` captures later),
// so a scan stored already thinned keeps the same rate in time; other names by their order.
void thinMappingFrames(Scene& scene, int stride);

// One paragraph for the report: the protocol's settings as run (`top_k` and `features`, the
// paper's beside them where the user chose others), the columns the paper reports and its
// mapping time.
std::string describeProtocol(const BenchmarkProtocol& protocol, size_t top_k, int64_t features);

}  // namespace ffloc
