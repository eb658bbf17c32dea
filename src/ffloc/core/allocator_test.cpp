#include "ffloc/core/allocator.h"

#include <gtest/gtest.h>

#include <sys/resource.h>

#include <cstdlib>
#include <vector>

namespace ffloc {
namespace {

long minorPageFaults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}

// The frame-by-frame pattern of mapping: a few buffers of some MiB each, written, then freed.
// Returns the page faults of one such frame.
long pageFaultsOfOneFrame(size_t buffers, size_t bytes) {
  const long before = minorPageFaults();
  std::vector<char*> blocks;
  for (size_t b = 0; b < buffers; ++b) {
    char* block = static_cast<char*>(std::malloc(bytes));
    for (size_t i = 0; i < bytes; i += 4096) static_cast<volatile char*>(block)[i] = 1;
    blocks.push_back(block);
  }
  for (char* block : blocks) std::free(block);
  return minorPageFaults() - before;
}

#if defined(__GLIBC__)
TEST(Allocator, FreedFrameBuffersAreReusedWithoutAskingTheKernelAgain) {
  configureAllocator();
  const size_t buffers = 3, bytes = size_t{12} << 20;
  pageFaultsOfOneFrame(buffers, bytes);  // the first frame grows the heap
  const long pages = static_cast<long>(buffers * bytes / 4096);
  long worst = 0;
  for (int frame = 0; frame < 3; ++frame) worst = std::max(worst, pageFaultsOfOneFrame(buffers, bytes));
  // glibc's defaults give back the 36 MiB at every free and fault all 9216 pages in again.
  EXPECT_LT(worst, pages / 20) << "of " << pages << " pages per frame";
}
#endif

}  // namespace
}  // namespace ffloc
