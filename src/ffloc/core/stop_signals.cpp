#include "ffloc/core/stop_signals.h"

#include <algorithm>
#include <cstring>

namespace ffloc {

bool isStopSignal(int signal_number) {
  return std::find(std::begin(kStopSignals), std::end(kStopSignals), signal_number) != std::end(kStopSignals);
}

std::string signalName(int signal_number) {
  const char* name = ::strsignal(signal_number);
  return "signal " + std::to_string(signal_number) + (name ? std::string(" (") + name + ")" : "");
}

StopSignalHandler::StopSignalHandler(void (*handler)(int), Ignored ignored) {
  struct sigaction taking {};
  taking.sa_handler = handler;
  // Without it a read or write in progress fails with EINTR, and a checkpoint being written or a
  // request being read would fail for a signal that asked for an orderly stop.
  taking.sa_flags = SA_RESTART;
  sigemptyset(&taking.sa_mask);
  for (size_t i = 0; i < std::size(kStopSignals); ++i) {
    if (::sigaction(kStopSignals[i], nullptr, &before_[i]) != 0) continue;
    if (ignored == Ignored::kKept && before_[i].sa_handler == SIG_IGN) continue;
    ::sigaction(kStopSignals[i], &taking, nullptr);
  }
}

void StopSignalHandler::restore() const {
  for (size_t i = 0; i < std::size(kStopSignals); ++i) ::sigaction(kStopSignals[i], &before_[i], nullptr);
}

}  // namespace ffloc
