#pragma once

#include <algorithm>
#include <functional>
#include <string>
#include <vector>

#include "ffloc/core/statistics.h"

namespace ffloc::cli {

// Wall-clock seconds of repeated calls.
struct Timing {
  std::vector<double> seconds;

  double median() const { return ffloc::median(seconds); }
  double min() const { return *std::min_element(seconds.begin(), seconds.end()); }
  double max() const { return *std::max_element(seconds.begin(), seconds.end()); }
};

Timing timeCalls(int warmup, int repeats, const std::function<void()>& call);

// Resident memory around one model: after building it, and its peak while timing (per model
// where the kernel lets the peak be reset, else the process-wide peak).
struct MemoryReport {
  double after_build_mib = 0.0;
  double peak_mib = 0.0;
  bool peak_is_per_model = false;
};

MemoryReport startMemoryWindow();
void closeMemoryWindow(MemoryReport& memory);

// The 1, 5 and 15 minute load averages, "unknown" where the system does not say.
std::string loadAverage();

}  // namespace ffloc::cli
