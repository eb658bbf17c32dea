#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

namespace ffloc {

// Computes produce(i) for i = 0 .. count - 1 on `workers` threads of its own and hands each
// result to consume(i, result) on the calling thread in order of i, as soon as it and every one
// before it is ready: the caller sees what the serial loop would, in the same order, while the
// items are made in parallel. The first failure in order of i (an exception from produce(i) or
// consume(i)) is rethrown after the workers finish the item each holds; nothing after it is
// consumed. With workers <= 1 it is the serial loop, on the calling thread.
template <typename Result, typename Produce, typename Consume>
void forEachInOrder(size_t count, int workers, Produce produce, Consume consume) {
  if (workers <= 1 || count <= 1) {
    for (size_t i = 0; i < count; ++i) consume(i, produce(i));
    return;
  }
  struct Slot {
    bool ready = false;
    std::optional<Result> result;
    std::exception_ptr error;
  };
  std::vector<Slot> slots(count);
  std::mutex mutex;
  std::condition_variable finished;
  std::atomic<size_t> next{0};
  std::atomic<bool> stop{false};
  const auto work = [&] {
    while (!stop) {
      const size_t i = next++;
      if (i >= count) return;
      Slot made;
      try {
        made.result.emplace(produce(i));
      } catch (...) {
        made.error = std::current_exception();
        stop = true;  // every item before this one is already taken, so the caller still gets them
      }
      made.ready = true;
      {
        const std::lock_guard<std::mutex> lock(mutex);
        slots[i] = std::move(made);
      }
      finished.notify_all();
    }
  };
  struct Pool {
    std::vector<std::thread> threads;
    std::atomic<bool>& stop;
    ~Pool() {
      stop = true;
      for (std::thread& thread : threads) thread.join();
    }
  } pool{{}, stop};
  const size_t thread_count = std::min(count, static_cast<size_t>(workers));
  for (size_t t = 0; t < thread_count; ++t) pool.threads.emplace_back(work);
  for (size_t i = 0; i < count; ++i) {
    Slot slot;
    {
      std::unique_lock<std::mutex> lock(mutex);
      finished.wait(lock, [&] { return slots[i].ready; });
      slot = std::move(slots[i]);
    }
    if (slot.error) std::rethrow_exception(slot.error);
    consume(i, std::move(*slot.result));
  }
}

}  // namespace ffloc
