#include "ffloc/core/cpu_features.h"

#include <cstdio>
#include <fstream>
#include <sstream>

namespace ffloc {

bool cpuHasFlag(const std::string& flag) {
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("flags", 0) == 0) return cpuinfoFlagsLineLists(line, flag);
  }
  return false;
}

bool cpuinfoFlagsLineLists(const std::string& flags_line, const std::string& flag) {
  const size_t colon = flags_line.find(':');
  if (colon == std::string::npos) return false;
  std::istringstream words(flags_line.substr(colon + 1));
  std::string word;
  while (words >> word) {
    if (word == flag) return true;
  }
  return false;
}

bool cpuHasNativeBfloat16() {
  static const bool native = cpuHasFlag("amx_bf16") || cpuHasFlag("avx512_bf16");
  return native;
}

void warnIfBfloat16IsEmulated(const std::string& advice) {
  if (cpuHasNativeBfloat16()) return;
  std::fprintf(stderr, "warning: this CPU has neither AMX nor AVX512-BF16, so bf16 is emulated and much slower than "
               "float32 here; %s\n", advice.c_str());
}

}  // namespace ffloc
