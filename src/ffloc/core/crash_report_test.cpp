#include "ffloc/core/crash_report.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>
#include <utility>

namespace ffloc {
namespace {

struct Crash {
  int status = 0;
  std::string error_output;
};

// A child process installs the report and crashes; its standard error comes back through a pipe.
Crash crashInChild(int signal_number) {
  int pipe_ends[2];
  EXPECT_EQ(pipe(pipe_ends), 0);
  const pid_t child = fork();
  if (child == 0) {
    dup2(pipe_ends[1], STDERR_FILENO);
    close(pipe_ends[0]);
    installCrashReport("crash-probe");
    if (signal_number == SIGSEGV) {
      volatile int* nowhere = nullptr;
      *nowhere = 1;
    }
    raise(signal_number);
    _exit(0);
  }
  close(pipe_ends[1]);
  Crash crash;
  char buffer[4096];
  for (ssize_t got; (got = read(pipe_ends[0], buffer, sizeof(buffer))) > 0;) crash.error_output.append(buffer, got);
  close(pipe_ends[0]);
  waitpid(child, &crash.status, 0);
  return crash;
}

TEST(CrashReport, ACrashWritesItsSignalAndStackThenEndsAsTheSignalWould) {
  for (const auto& [signal_number, name] : {std::pair{SIGSEGV, "SIGSEGV"}, std::pair{SIGABRT, "SIGABRT"}}) {
    const Crash crash = crashInChild(signal_number);
    ASSERT_TRUE(WIFSIGNALED(crash.status)) << name << ": " << crash.error_output;
    EXPECT_EQ(WTERMSIG(crash.status), signal_number) << crash.error_output;
    EXPECT_NE(crash.error_output.find(std::string("crash-probe: crashed with ") + name), std::string::npos)
        << crash.error_output;
    // backtrace_symbols_fd writes one "binary(+offset)[address]" line per frame.
    EXPECT_NE(crash.error_output.find(")[0x"), std::string::npos) << crash.error_output;
  }
}

}  // namespace
}  // namespace ffloc
