#include "ffloc/core/cpu_features.h"

#include <cstdio>
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

void warnIfBfloat16IsEmulated(const std::string& advice) {
  if (cpuHasNativeBfloat16()) return;
  std::fprintf(stderr, "warning: this CPU has neither AMX nor AVX512-BF16, so bf16 is emulated and much slower than "
               "float32 here; %s\n", advice.c_str());
}

}  // namespace ffloc
