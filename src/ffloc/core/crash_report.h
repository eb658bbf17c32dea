#pragma once

namespace ffloc {

// On SIGSEGV, SIGBUS, SIGFPE, SIGILL or SIGABRT, writes the signal and the calling thread's stack
// to standard error, then lets the signal end the process as it would have (the same exit
// status, a core where cores are enabled). A crash on a lent machine, with no debugger there,
// otherwise left only "Segmentation fault". `program` names the process in the report.
void installCrashReport(const char* program);

}  // namespace ffloc
