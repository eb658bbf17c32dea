#include "ffloc/core/testing/child_process.h"

#include <sys/wait.h>
#include <unistd.h>

namespace ffloc::testing {

ChildOutput runInChild(const std::function<void()>& body) {
  ChildOutput child;
  int pipe_ends[2];
  if (pipe(pipe_ends) != 0) {
    child.status = -1;
    return child;
  }
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(pipe_ends[1], STDOUT_FILENO);
    dup2(pipe_ends[1], STDERR_FILENO);
    close(pipe_ends[0]);
    body();
    _exit(0);
  }
  close(pipe_ends[1]);
  char buffer[4096];
  for (ssize_t got; (got = read(pipe_ends[0], buffer, sizeof(buffer))) > 0;) child.output.append(buffer, got);
  close(pipe_ends[0]);
  waitpid(pid, &child.status, 0);
  return child;
}

}  // namespace ffloc::testing
