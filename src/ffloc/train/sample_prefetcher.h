#pragma once

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "ffloc/train/training_sample.h"

namespace ffloc {

// Prepares the training samples of a run ahead of the network in background threads, so that a
// step never waits for reading, preprocessing, overlap and ground truth while the loader keeps
// up. Samples come out in order of their ordinal (0, 1, 2, ...), each the pure function
// `draw(ordinal)`, so the sequence is the same with any number of loader threads.
class SamplePrefetcher {
 public:
  using Draw = std::function<TrainingSample(int64_t ordinal)>;

  // `depth`: how many samples may be ready or in preparation beyond the next one asked for.
  SamplePrefetcher(Draw draw, int threads, int depth);
  ~SamplePrefetcher();
  SamplePrefetcher(const SamplePrefetcher&) = delete;
  SamplePrefetcher& operator=(const SamplePrefetcher&) = delete;

  // The next sample in order; rethrows the error its preparation raised.
  TrainingSample next();
  // Seconds next() has spent waiting for a sample that was not ready yet.
  double waitedSeconds() const { return waited_seconds_; }

 private:
  struct Slot {
    TrainingSample sample;
    std::exception_ptr error;
  };
  void work();

  Draw draw_;
  int depth_;
  std::mutex mutex_;
  std::condition_variable ready_, space_;
  std::map<int64_t, Slot> done_;
  int64_t next_to_start_ = 0, next_to_take_ = 0;
  bool stopping_ = false;
  double waited_seconds_ = 0;
  std::vector<std::thread> threads_;
};

}  // namespace ffloc
