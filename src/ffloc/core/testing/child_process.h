#pragma once

#include <functional>
#include <string>

namespace ffloc::testing {

struct ChildOutput {
  int status = 0;      // as waitpid reports it
  std::string output;  // standard output and standard error together
};

// Runs `body` in a forked child whose standard output and error come back through a pipe; the
// child exits 0 if `body` returns (a body that execs or crashes never does).
ChildOutput runInChild(const std::function<void()>& body);

}  // namespace ffloc::testing
