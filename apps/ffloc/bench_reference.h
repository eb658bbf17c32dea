#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace ffloc::cli {

// The Python reference timing (fixtures/dust3r/python_reference_timing.txt), per dtype: the
// medians of each process and the median of all calls pooled, for the encoder and for the
// decoder + both DPT heads of a pair.
struct ReferenceRow {
  std::vector<double> process_medians;
  std::optional<double> pooled_median;
};
struct ReferenceTiming {
  std::filesystem::path path;
  std::map<std::string, ReferenceRow> encoder, pair;
};

// The setup the reference was measured with; other setups get no ratio.
constexpr const char* kReferenceConfig = "large";
constexpr int64_t kReferenceWidth = 512, kReferenceHeight = 384;

// InputError naming the file when it cannot be read or parsed.
ReferenceTiming readReferenceTiming(const std::filesystem::path& path);
// The explicit path, else the fixture under FFLOC_SHARED_DIR when it exists.
std::optional<ReferenceTiming> findReferenceTiming(const std::string& explicit_path);

}  // namespace ffloc::cli
