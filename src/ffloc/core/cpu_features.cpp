#include "ffloc/core/cpu_features.h"

#include <fstream>

namespace ffloc {

bool cpuHasFlag(const std::string& flag) {
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("flags", 0) == 0) return (" " + line + " ").find(" " + flag + " ") != std::string::npos;
  }
  return false;
}

bool cpuHasNativeBfloat16() {
  static const bool native = cpuHasFlag("amx_bf16") || cpuHasFlag("avx512_bf16");
  return native;
}

}  // namespace ffloc
