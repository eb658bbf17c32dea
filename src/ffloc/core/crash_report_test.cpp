#include "ffloc/core/crash_report.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <string>
#include <utility>

#include "ffloc/core/testing/child_process.h"

namespace ffloc {
namespace {

// A child process installs the report and crashes.
testing::ChildOutput crashInChild(int signal_number) {
  return testing::runInChild([signal_number] {
    installCrashReport("crash-probe");
    if (signal_number == SIGSEGV) {
      volatile int* nowhere = nullptr;
      *nowhere = 1;
    }
    raise(signal_number);
  });
}

TEST(CrashReport, ACrashWritesItsSignalAndStackThenEndsAsTheSignalWould) {
  for (const auto& [signal_number, name] : {std::pair{SIGSEGV, "SIGSEGV"}, std::pair{SIGABRT, "SIGABRT"}}) {
    const testing::ChildOutput crash = crashInChild(signal_number);
    ASSERT_TRUE(WIFSIGNALED(crash.status)) << name << ": " << crash.output;
    EXPECT_EQ(WTERMSIG(crash.status), signal_number) << crash.output;
    EXPECT_NE(crash.output.find(std::string("crash-probe: crashed with ") + name), std::string::npos)
        << crash.output;
    // backtrace_symbols_fd writes one "binary(+offset)[address]" line per frame.
    EXPECT_NE(crash.output.find(")[0x"), std::string::npos) << crash.output;
  }
}

}  // namespace
}  // namespace ffloc
