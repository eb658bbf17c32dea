#include "ffloc/train/sample_prefetcher.h"

#include <algorithm>
#include <chrono>

#include "ffloc/core/clock.h"

namespace ffloc {

SamplePrefetcher::SamplePrefetcher(Draw draw, int threads, int depth)
    : draw_(std::move(draw)), depth_(std::max(depth, 1)) {
  for (int i = 0; i < std::max(threads, 1); ++i) threads_.emplace_back([this] { work(); });
}

SamplePrefetcher::~SamplePrefetcher() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  space_.notify_all();
  ready_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

void SamplePrefetcher::work() {
  while (true) {
    int64_t ordinal = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      space_.wait(lock, [&] { return stopping_ || next_to_start_ < next_to_take_ + depth_; });
      if (stopping_) return;
      ordinal = next_to_start_++;
    }
    Slot slot;
    try {
      slot.sample = draw_(ordinal);
    } catch (...) {
      slot.error = std::current_exception();
    }
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      done_.emplace(ordinal, std::move(slot));
    }
    ready_.notify_all();
  }
}

TrainingSample SamplePrefetcher::next() {
  const auto start = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(mutex_);
  ready_.wait(lock, [&] { return done_.count(next_to_take_) > 0; });
  waited_seconds_ += secondsSince(start);
  Slot slot = std::move(done_.at(next_to_take_));
  done_.erase(next_to_take_);
  ++next_to_take_;
  lock.unlock();
  space_.notify_all();
  if (slot.error) std::rethrow_exception(slot.error);
  return std::move(slot.sample);
}

}  // namespace ffloc
