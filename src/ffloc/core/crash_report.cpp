#include "ffloc/core/crash_report.h"

#include <execinfo.h>
#include <signal.h>
#include <unistd.h>

#include <cstring>
#include <initializer_list>

namespace ffloc {

namespace {

const char* crash_program = "ffloc";
// A stack overflow leaves no stack for the handler; this one is the main thread's.
alignas(16) char alternate_stack[64 * 1024];

void writeText(const char* text) {
  ssize_t ignored = ::write(STDERR_FILENO, text, std::strlen(text));
  (void)ignored;
}

const char* signalName(int signal_number) {
  switch (signal_number) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    default: return "SIGABRT";
  }
}

// Only async-signal-safe calls: write, backtrace (its library loaded beforehand) and
// backtrace_symbols_fd, which allocates nothing.
void reportCrash(int signal_number) {
  writeText("\n");
  writeText(crash_program);
  writeText(": crashed with ");
  writeText(signalName(signal_number));
  writeText(". This is a bug; please report it with the command and this stack (resolve the\n"
            "addresses with: addr2line -f -C -e <binary> <offset>):\n");
  void* frames[64];
  const int count = backtrace(frames, 64);
  backtrace_symbols_fd(frames, count, STDERR_FILENO);
  // SA_RESETHAND restored the default action: the signal now ends the process as usual.
  raise(signal_number);
}

}  // namespace

void installCrashReport(const char* program) {
  crash_program = program;
  // backtrace() loads libgcc's unwinder on its first call, which is not safe inside a handler.
  void* warm_up[1];
  backtrace(warm_up, 1);
  stack_t stack{};
  stack.ss_sp = alternate_stack;
  stack.ss_size = sizeof(alternate_stack);
  sigaltstack(&stack, nullptr);
  struct sigaction action {};
  action.sa_handler = reportCrash;
  action.sa_flags = SA_RESETHAND | SA_ONSTACK;
  sigemptyset(&action.sa_mask);
  for (const int signal_number : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) sigaction(signal_number, &action, nullptr);
}

}  // namespace ffloc
