#pragma once

#include <signal.h>

#include <iterator>
#include <string>

namespace ffloc {

// The signals that ask an ffloc process to stop: Ctrl-C, a scheduler's or systemd's stop, a
// closed terminal.
inline constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};

bool isStopSignal(int signal_number);

// "signal 15 (Terminated)".
std::string signalName(int signal_number);

// `handler` takes the stop signals while this lives; the dispositions before come back after it.
class StopSignalHandler {
 public:
  // Whether a signal ignored when this is made (nohup, a background job of a script) stays ignored.
  enum class Ignored { kKept, kTaken };
  StopSignalHandler(void (*handler)(int), Ignored ignored);
  ~StopSignalHandler() { restore(); }
  StopSignalHandler(const StopSignalHandler&) = delete;
  StopSignalHandler& operator=(const StopSignalHandler&) = delete;

  // Puts the dispositions before back: also in a forked child, before it starts its program.
  void restore() const;

 private:
  struct sigaction before_[std::size(kStopSignals)] {};
};

}  // namespace ffloc
