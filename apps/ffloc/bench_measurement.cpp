#include "bench_measurement.h"

#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>

#include "ffloc/core/allocator.h"
#include "ffloc/core/clock.h"

namespace ffloc::cli {
namespace {

// A "Vm...:   <n> kB" line of /proc/self/status, in MiB.
std::optional<double> procStatusMiB(const std::string& key) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind(key + ":", 0) == 0) return std::stod(line.substr(key.size() + 1)) / 1024.0;
  }
  return std::nullopt;
}

// Resets the peak RSS (VmHWM) to the current RSS (Linux >= 4.0), so that each model reports its
// own peak; false where the kernel refuses.
bool resetPeakRss() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  clear.flush();
  return static_cast<bool>(clear);
}

// The process-wide peak where /proc is missing: ru_maxrss (KiB on Linux).
double processPeakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

}  // namespace

Timing timeCalls(int warmup, int repeats, const std::function<void()>& call) {
  for (int i = 0; i < warmup; ++i) call();
  Timing timing;
  for (int i = 0; i < repeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    call();
    timing.seconds.push_back(secondsSince(start));
  }
  return timing;
}

// Starts the peak-RSS window for a freshly built model.
MemoryReport startMemoryWindow() {
  // glibc keeps freed heap memory resident: the previous model's weights, where this model's did
  // not land, stayed as 100-180 MiB of the next model's peak. Returned first, the window starts
  // from what this model holds, as in a process that builds only it.
  returnFreeMemory();
  MemoryReport memory;
  memory.after_build_mib = procStatusMiB("VmRSS").value_or(0.0);
  memory.peak_is_per_model = resetPeakRss() && procStatusMiB("VmHWM").has_value();
  return memory;
}

void closeMemoryWindow(MemoryReport& memory) {
  memory.peak_mib = memory.peak_is_per_model ? *procStatusMiB("VmHWM") : processPeakRssMiB();
}

std::string loadAverage() {
  double load[3] = {0.0, 0.0, 0.0};
  if (getloadavg(load, 3) != 3) return "unknown";
  char text[64];
  std::snprintf(text, sizeof(text), "%.2f %.2f %.2f", load[0], load[1], load[2]);
  return text;
}

}  // namespace ffloc::cli
