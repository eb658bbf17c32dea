#include "ffloc/model/torch_threads.h"

#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <mutex>
#include <set>
#include <thread>

namespace ffloc {
namespace {

// The network's kernels split their work with parallelFor; compiled without OpenMP it ran every
// chunk on the calling thread, and two threads were no faster than one.
TEST(ParallelFor, RunsItsChunksOnEveryIntraOpThread) {
  const int before = at::get_num_threads();
  setTorchThreadCount(2);
  std::mutex mutex;
  std::set<std::thread::id> threads;
  std::vector<int> covered(4, 0);
  parallelFor(0, 4, 1, [&](int64_t begin, int64_t end) {
    std::lock_guard<std::mutex> lock(mutex);
    threads.insert(std::this_thread::get_id());
    for (int64_t i = begin; i < end; ++i) ++covered[i];
  });
  setTorchThreadCount(before);
  EXPECT_EQ(threads.size(), 2u);
  EXPECT_EQ(covered, std::vector<int>(4, 1));
}

TEST(ParallelFor, RunsOnTheCallingThreadWithOneThread) {
  const int before = at::get_num_threads();
  setTorchThreadCount(1);
  std::set<std::thread::id> threads;
  int64_t total = 0;
  parallelFor(0, 1000, 1, [&](int64_t begin, int64_t end) {
    threads.insert(std::this_thread::get_id());
    total += end - begin;
  });
  setTorchThreadCount(before);
  EXPECT_EQ(threads, std::set<std::thread::id>{std::this_thread::get_id()});
  EXPECT_EQ(total, 1000);
}

}  // namespace
}  // namespace ffloc
