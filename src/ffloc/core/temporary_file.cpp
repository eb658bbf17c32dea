#include "ffloc/core/temporary_file.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstring>
#include <mutex>

#include "ffloc/core/stop_signals.h"

namespace ffloc {
namespace {

constexpr int kSlots = 8;
constexpr size_t kMaxPath = 4096;
// Read by the signal handler: a slot's path is written before it is marked in use, and unmarked
// before it is reused.
char slot_paths[kSlots][kMaxPath];
std::atomic<bool> slot_used[kSlots];

void installHandlersWhereDefault() {
  static std::once_flag once;
  std::call_once(once, [] {
    for (const int signal_number : kStopSignals) {
      struct sigaction current {};
      if (::sigaction(signal_number, nullptr, &current) != 0 || current.sa_handler != SIG_DFL) continue;
      struct sigaction cleanup {};
      cleanup.sa_handler = removeTemporaryFilesAndRaise;
      sigemptyset(&cleanup.sa_mask);
      ::sigaction(signal_number, &cleanup, nullptr);
    }
  });
}

int takeSlot(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;
  static std::mutex taking;
  const std::lock_guard<std::mutex> lock(taking);
  for (int i = 0; i < kSlots; ++i) {
    if (slot_used[i].load(std::memory_order_acquire)) continue;
    std::memcpy(slot_paths[i], path.c_str(), path.size() + 1);
    slot_used[i].store(true, std::memory_order_release);
    return i;
  }
  return -1;
}

}  // namespace

void removeTemporaryFilesAndRaise(int signal_number) {
  for (int i = 0; i < kSlots; ++i)
    if (slot_used[i].load(std::memory_order_acquire)) ::unlink(slot_paths[i]);
  std::signal(signal_number, SIG_DFL);
  // Inside a handler the signal is blocked: unblocked, it ends the process here as its default
  // action would, before this function could return.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, signal_number);
  ::sigprocmask(SIG_UNBLOCK, &signals, nullptr);
  std::raise(signal_number);
  ::_exit(128 + signal_number);
}

TemporaryFile::TemporaryFile(std::filesystem::path path) : path_(std::move(path)) {
  installHandlersWhereDefault();
  slot_ = takeSlot(path_.string());
}

TemporaryFile::~TemporaryFile() {
  if (slot_ >= 0) slot_used[slot_].store(false, std::memory_order_release);
  if (!kept_) ::unlink(path_.c_str());
}

void TemporaryFile::keep() {
  kept_ = true;
  if (slot_ >= 0) slot_used[slot_].store(false, std::memory_order_release);
  slot_ = -1;
}

}  // namespace ffloc
