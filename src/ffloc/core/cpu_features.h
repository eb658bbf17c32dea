#pragma once

#include <string>

namespace ffloc {

// Whether the kernel lists `flag` (e.g. "avx512_bf16", "amx_bf16") among this CPU's flags in
// /proc/cpuinfo. False where that file cannot be read.
bool cpuHasFlag(const std::string& flag);

// Whether `flag` is one of the words after the colon of a /proc/cpuinfo "flags" line. The kernel
// pads some flags with several spaces (AMD EPYC: "pti        vmmcall"), so words are split on
// any run of blanks; an empty flag is never listed.
bool cpuinfoFlagsLineLists(const std::string& flags_line, const std::string& flag);

// Whether bfloat16 matrix products run natively here (AMX or AVX512-BF16, which oneDNN uses).
// Without either, libtorch emulates bf16 products element by element, far slower than float32
// (docs/benchmarks.md): inference then widens its layers to float32 (model/bfloat16_kernels.h),
// and bf16 training, which goes through autograd, stays slow.
bool cpuHasNativeBfloat16();

// Without native bf16, writes to stderr that bf16 is emulated and slow here, ending with `advice`
// (what to use instead). Silent on CPUs with native bf16.
void warnIfBfloat16IsEmulated(const std::string& advice);

}  // namespace ffloc
