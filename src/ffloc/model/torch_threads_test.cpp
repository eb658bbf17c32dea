#include "ffloc/model/torch_threads.h"

#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/threads.h"

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

TEST(TorchThreads, SetsRequestedCount) {
  EXPECT_EQ(setTorchThreadCount(2), 2);
  EXPECT_EQ(at::get_num_threads(), 2);
  EXPECT_EQ(setTorchThreadCount(0), resolveThreadCount(0));
  EXPECT_EQ(at::get_num_threads(), resolveThreadCount(0));
}

// Two network passes side by side each hold one guard on their own thread: it must not change
// what other threads run with (another query's encoder, OpenCV's loops), and overlapping guards
// leave OpenBLAS as they found it whichever ends first.
TEST(TorchThreads, SingleThreadedGuardsChangeLibtorchOnTheirOwnThreadOnly) {
  setTorchThreadCount(3);
  const int opencv_threads = cv::getNumThreads();
  auto first = std::make_unique<SingleThreadedKernels>();
  EXPECT_EQ(torchThreadCount(), 1);
  EXPECT_EQ(cv::getNumThreads(), opencv_threads);
  int on_another_thread = 0;
  std::thread([&] { on_another_thread = torchThreadCount(); }).join();
  EXPECT_EQ(on_another_thread, 3);
  std::promise<void> second_held, first_ended;
  std::thread beside([&] {
    const SingleThreadedKernels second;
    on_another_thread = torchThreadCount();
    second_held.set_value();
    first_ended.get_future().wait();
    if (blasThreadCount() != 0) EXPECT_EQ(blasThreadCount(), 1);  // the second guard still holds it
  });
  second_held.get_future().wait();
  first.reset();
  first_ended.set_value();
  beside.join();
  EXPECT_EQ(on_another_thread, 1);
  EXPECT_EQ(torchThreadCount(), 3);
  if (blasThreadCount() != 0) EXPECT_EQ(blasThreadCount(), 3);
  setTorchThreadCount(0);
}

// A loop over OpenCV's pool that takes a while, for the pool to be resized under it if nothing
// prevents it.
void runOpenCvLoop() {
  std::atomic<int> chunks{0};
  cv::parallel_for_(cv::Range(0, 64), [&](const cv::Range& range) {
    cv::Mat product = cv::Mat::eye(24, 24, CV_32F);
    for (int i = range.start; i < range.end; ++i) product = product * product;
    chunks += range.end - range.start;
  });
  ASSERT_EQ(chunks.load(), 64);
}

// Two threads that ask for different counts, as two Python localizers with threads=1 and
// threads=2: each must run with its own count, and neither may resize OpenCV's pool while the
// other runs a loop in it (setLibraryThreadCount called from both threads instead crashed in TBB,
// or left a loop waiting for ever).
TEST(ThreadCountLease, LeasesOfOtherCountsNeverResizeThePoolsUnderARunningLoop) {
  std::atomic<int> wrong_counts{0};
  const auto work = [&](int threads) {
    for (int round = 0; round < 150; ++round) {
      const ThreadCountLease pools(threads);
      if (torchThreadCount() != threads || cv::getNumThreads() != std::min(threads, cv::getNumberOfCPUs()))
        ++wrong_counts;
      runOpenCvLoop();
      const ThreadCountLease keeping_the_count(std::nullopt);
      runOpenCvLoop();
    }
  };
  std::vector<std::thread> threads;
  for (const int count : {1, 2, 1, 2}) threads.emplace_back(work, count);
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(wrong_counts.load(), 0);
  setTorchThreadCount(0);
}

TEST(ThreadCountLease, ALeaseOfAnotherCountWaitsForTheOneHeld) {
  auto held = std::make_unique<ThreadCountLease>(2);
  std::atomic<bool> granted{false};
  std::thread other([&] {
    const ThreadCountLease pools(1);
    granted = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_FALSE(granted.load());
  EXPECT_EQ(torchThreadCount(), 2);
  held.reset();
  other.join();
  EXPECT_TRUE(granted.load());
  EXPECT_THROW(ThreadCountLease(-1), InputError);
  const ThreadCountLease outer(2);
  {
    // Would wait for `outer` were it not this thread's: they run at the count it holds.
    const ThreadCountLease nested(std::nullopt), same(2), other(1);
    EXPECT_EQ(torchThreadCount(), 2);
  }
  setTorchThreadCount(0);
}

// Ctrl-C in Python during a wait behind another thread's long build was heard only when the
// build ended: the wait asks the thread's StopCheck, and one that stops leaves nothing behind.
TEST(ThreadCountLease, AWaitEndsWhenAStopIsAsked) {
  auto held = std::make_unique<ThreadCountLease>(2);
  int asked = 0;
  bool stopped = false;
  std::thread waiting([&] {
    const StopCheck stop([&] { return ++asked >= 3; });
    try {
      const ThreadCountLease pools(1);
    } catch (const Stopped&) {
      stopped = true;
    }
  });
  waiting.join();
  EXPECT_TRUE(stopped);
  EXPECT_EQ(asked, 3);
  held.reset();
  std::thread([] {  // not left behind a wait that ended
    const ThreadCountLease pools(1);
    EXPECT_EQ(torchThreadCount(), 1);
  }).join();
  setTorchThreadCount(0);
}

}  // namespace
}  // namespace ffloc
