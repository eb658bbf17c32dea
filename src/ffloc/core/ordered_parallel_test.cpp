#include "ffloc/core/ordered_parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace ffloc {
namespace {

// Later items finish first (each sleeps less than the one before), yet the caller receives
// them in order, each once, made on threads other than its own.
TEST(ForEachInOrder, ConsumesInOrderWhatWorkersMadeOutOfOrder) {
  const size_t count = 12;
  const std::thread::id caller = std::this_thread::get_id();
  std::set<std::thread::id> makers;
  std::mutex makers_mutex;
  std::vector<size_t> seen;
  forEachInOrder<std::string>(
      count, 3,
      [&](size_t i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2 * (count - i)));
        const std::lock_guard<std::mutex> lock(makers_mutex);
        makers.insert(std::this_thread::get_id());
        return "item " + std::to_string(i);
      },
      [&](size_t i, std::string&& item) {
        EXPECT_EQ(std::this_thread::get_id(), caller);
        EXPECT_EQ(item, "item " + std::to_string(i));
        seen.push_back(i);
      });
  ASSERT_EQ(seen.size(), count);
  for (size_t i = 0; i < count; ++i) EXPECT_EQ(seen[i], i);
  EXPECT_EQ(makers.count(caller), 0u);
  EXPECT_GE(makers.size(), 2u);
}

// The first failure in order is the one rethrown, after everything before it was consumed and
// nothing after it; workers stop taking items once one failed.
TEST(ForEachInOrder, RethrowsTheFirstFailureInOrderAndConsumesNothingAfterIt) {
  std::vector<size_t> seen;
  std::atomic<size_t> made{0};
  try {
    forEachInOrder<size_t>(
        1000, 2,
        [&](size_t i) {
          ++made;
          if (i == 7) {
            std::this_thread::sleep_for(std::chrono::milliseconds(20));  // item 9 fails first in time
            throw std::runtime_error("item 7 failed");
          }
          if (i == 9) throw std::runtime_error("item 9 failed");
          return i;
        },
        [&](size_t i, size_t&&) { seen.push_back(i); });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "item 7 failed");
  }
  EXPECT_EQ(seen, (std::vector<size_t>{0, 1, 2, 3, 4, 5, 6}));
  EXPECT_LT(made.load(), 1000u);
}

TEST(ForEachInOrder, OneWorkerIsTheSerialLoopOnTheCallingThread) {
  const std::thread::id caller = std::this_thread::get_id();
  std::vector<size_t> seen;
  forEachInOrder<size_t>(
      5, 1,
      [&](size_t i) {
        EXPECT_EQ(std::this_thread::get_id(), caller);
        return i * i;
      },
      [&](size_t i, size_t&& square) { seen.push_back(square + i); });
  EXPECT_EQ(seen, (std::vector<size_t>{0, 2, 6, 12, 20}));
}

}  // namespace
}  // namespace ffloc
