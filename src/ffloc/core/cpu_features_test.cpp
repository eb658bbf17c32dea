#include "ffloc/core/cpu_features.h"

#include <gtest/gtest.h>

#include <fstream>

namespace ffloc {
namespace {

TEST(CpuFeatures, FindsWholeFlagsOnly) {
  if (!std::ifstream("/proc/cpuinfo")) GTEST_SKIP() << "/proc/cpuinfo is not readable here";
  // Every x86-64 CPU has sse2 and fpu; a prefix of a flag is not a flag. ("ss", the prefix this
  // test used first, is itself a flag on Intel CPUs with self-snoop; no x86 CPU lists "fp".)
#if defined(__x86_64__)
  EXPECT_TRUE(cpuHasFlag("sse2"));
  EXPECT_TRUE(cpuHasFlag("fpu"));
  EXPECT_FALSE(cpuHasFlag("fp"));
#endif
  EXPECT_FALSE(cpuHasFlag("no_such_cpu_flag"));
  EXPECT_FALSE(cpuHasFlag(""));
  EXPECT_FALSE(cpuHasFlag("flags"));
  EXPECT_EQ(cpuHasNativeBfloat16(), cpuHasFlag("amx_bf16") || cpuHasFlag("avx512_bf16"));
}

TEST(CpuFeatures, ReadsAFlagsLineWithRunsOfBlanks) {
  // As an AMD EPYC (Zen 5) VM's kernel writes it: a tab before the colon, eight spaces in a gap.
  const std::string line = "flags\t\t: fpu sse2 pti        vmmcall avx512_bf16";
  EXPECT_TRUE(cpuinfoFlagsLineLists(line, "pti"));
  EXPECT_TRUE(cpuinfoFlagsLineLists(line, "vmmcall"));
  EXPECT_TRUE(cpuinfoFlagsLineLists(line, "avx512_bf16"));
  EXPECT_FALSE(cpuinfoFlagsLineLists(line, ""));
  EXPECT_FALSE(cpuinfoFlagsLineLists(line, "flags"));
  EXPECT_FALSE(cpuinfoFlagsLineLists(line, "avx512"));
  EXPECT_FALSE(cpuinfoFlagsLineLists("flags without a colon", "without"));
}

}  // namespace
}  // namespace ffloc
