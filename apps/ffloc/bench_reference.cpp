#include "bench_reference.h"

#include <cstdlib>
#include <fstream>
#include <regex>

#include "ffloc/core/error.h"
#include "ffloc/io/input_file.h"

namespace ffloc::cli {

ReferenceTiming readReferenceTiming(const std::filesystem::path& path) {
  requireRegularFile(path, "reference timing file");  // a FIFO blocked the bench forever
  std::ifstream file(path);
  if (!file) throwInputError(path.string(), 0, "cannot open the reference timing file");
  const std::regex process(R"(^\s*(fp32|bf16) process \d+:\s*$)");
  const std::regex encoder(R"(^\s*\(i\)\s+encoder\b.*\bmedian ([0-9.]+) s\b)");
  const std::regex pair(R"(^\s*\(ii\)\s+decoder\b.*\bmedian ([0-9.]+) s\b)");
  const std::regex pooled(
      R"(^\s*(fp32|bf16) all calls pooled: encoder median ([0-9.]+) s\b.*decoder\+heads median ([0-9.]+) s\b)");
  ReferenceTiming reference;
  reference.path = path;
  std::string line, dtype;
  int line_number = 0, rows = 0;
  while (std::getline(file, line)) {
    ++line_number;
    std::smatch match;
    try {
      if (std::regex_search(line, match, process)) {
        dtype = match[1];
      } else if (!dtype.empty() && std::regex_search(line, match, encoder)) {
        reference.encoder[dtype].process_medians.push_back(std::stod(match[1]));
        ++rows;
      } else if (!dtype.empty() && std::regex_search(line, match, pair)) {
        reference.pair[dtype].process_medians.push_back(std::stod(match[1]));
        ++rows;
      } else if (std::regex_search(line, match, pooled)) {
        reference.encoder[match[1]].pooled_median = std::stod(match[2]);
        reference.pair[match[1]].pooled_median = std::stod(match[3]);
        ++rows;
      }
    } catch (const std::logic_error&) {
      throwInputError(path.string(), line_number, "malformed number in '" + line + "'");
    }
  }
  if (rows == 0) {
    throwInputError(path.string(), 0,
                    "no timing lines found (expected '(i) encoder ... median X s' under '<dtype> process N:' "
                    "or '<dtype> all calls pooled: ...')");
  }
  return reference;
}

std::optional<ReferenceTiming> findReferenceTiming(const std::string& explicit_path) {
  if (!explicit_path.empty()) return readReferenceTiming(explicit_path);
  const char* shared = std::getenv("FFLOC_SHARED_DIR");
  if (!shared) return std::nullopt;
  const std::filesystem::path path =
      std::filesystem::path(shared) / "fixtures" / "dust3r" / "python_reference_timing.txt";
  if (!std::filesystem::exists(path)) return std::nullopt;
  return readReferenceTiming(path);
}

}  // namespace ffloc::cli
