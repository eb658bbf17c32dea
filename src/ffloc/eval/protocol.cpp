#include "ffloc/eval/protocol.h"

#include <cctype>
#include <filesystem>
#include <map>

#include "ffloc/core/error.h"

namespace ffloc {

const std::vector<BenchmarkProtocol>& benchmarkProtocols() {
  // Indoor: top-10 retrieval and N = 1,500 (paper §4.2, Indoor6); outdoor: top-20 and N = 3,000
  // (§4.1 Wayspots, §4.4 Cambridge). Mapping times are the "Mapping" columns for FastForward.
  static const std::vector<BenchmarkProtocol> kProtocols = {
      {"wayspots", "Tables 1 and 2 (tab:wayspots, tab:wayspots_acc) and appendix tab:wayspots_medians", true, 20, 3000,
       {"10cm_10deg"}, true, 1, "3s"},
      {"indoor6", "Table 3 left (tab:indoor6_rio10)", false, 10, 1500, {"10cm_10deg", "20cm_20deg"}, true, 1, "8s"},
      {"rio10", "Table 3 right (tab:indoor6_rio10; the validation sequences)", false, 10, 1500,
       {"10cm_10deg", "20cm_20deg"}, true, 1, "10s"},
      {"cambridge", "Table 4 (tab:cambridge_table)", true, 20, 3000, {}, true, 1,
       "~30s (the retrieval index, §4.4 text; the table leaves FastForward's cell empty)"},
      {"7scenes", "appendix tab:7scenes_datasets", false, 10, 1500,
       {"5cm_5deg", "10cm_10deg"}, true, 15, "7s"},
  };
  return kProtocols;
}

const BenchmarkProtocol& benchmarkProtocol(const std::string& name) {
  std::string known;
  for (const BenchmarkProtocol& protocol : benchmarkProtocols()) {
    if (protocol.name == name) return protocol;
    known += (known.empty() ? "" : ", ") + protocol.name;
  }
  throw InputError("protocol: unknown protocol '" + name + "' (known: " + known + ")");
}

namespace {

// The capture number of 7-Scenes' "frame-NNNNNN..." names; -1 for other names.
long captureNumber(const std::string& name) {
  const std::string file = std::filesystem::path(name).filename().string();
  if (file.rfind("frame-", 0) != 0) return -1;
  const size_t begin = 6;
  size_t end = begin;
  while (end < file.size() && std::isdigit(static_cast<unsigned char>(file[end]))) ++end;
  return end > begin ? std::stol(file.substr(begin, end - begin)) : -1;
}

}  // namespace

void thinMappingFrames(Scene& scene, int stride) {
  if (stride < 1) throw InputError("mapping stride must be at least 1, got " + std::to_string(stride));
  // A scan already thinned on disk (every 4th frame, say) keeps one frame per `stride` captures,
  // not one per `stride` files, when the names carry the capture number.
  std::map<std::string, long> next_capture;  // per sequence folder
  int seen = 0;
  for (Frame& frame : scene.frames) {
    if (frame.split != Split::kMapping) continue;
    const long capture = captureNumber(frame.name);
    bool keep;
    if (capture < 0) {
      keep = seen++ % stride == 0;
    } else {
      const std::string sequence = std::filesystem::path(frame.name).parent_path().string();
      const auto next = next_capture.find(sequence);
      keep = next == next_capture.end() || capture >= next->second;
      if (keep) next_capture[sequence] = capture + stride;
    }
    if (!keep) frame.split = Split::kUnassigned;
  }
}

std::string describeProtocol(const BenchmarkProtocol& p, size_t top_k, int64_t features) {
  std::string columns = p.medians ? "median errors" : "";
  for (const std::string& key : p.accuracy_keys) columns += (columns.empty() ? "" : ", ") + key;
  // An override (--top-k 5) was printed as the paper's value the run did not use.
  const auto setting = [](const std::string& name, int64_t used, int64_t paper) {
    return name + " " + std::to_string(used) + (used == paper ? "" : " (the paper's " + std::to_string(paper) + ")");
  };
  std::string text = "protocol " + p.name + " (" + (p.outdoor ? "outdoor" : "indoor") + "): " +
                     setting("top-K", static_cast<int64_t>(top_k), static_cast<int64_t>(p.top_k)) + ", " +
                     setting("N", features, p.features);
  if (p.mapping_stride > 1) text += ", every " + std::to_string(p.mapping_stride) + "th mapping frame";
  text += "; the paper reports " + columns + " in " + p.paper_tables + "; FastForward's mapping time there: " +
          p.mapping_time + "\n";
  return text;
}

}  // namespace ffloc
