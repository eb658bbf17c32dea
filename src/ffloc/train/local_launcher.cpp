#include "ffloc/train/local_launcher.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <thread>

#include "ffloc/core/error.h"
#include "ffloc/core/stop_signals.h"

namespace ffloc {

int freeLoopbackPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = 0;
  socklen_t length = sizeof(address);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
    const int error = errno;
    ::close(fd);
    throw std::runtime_error(std::string("choosing a port for MASTER_PORT: ") + std::strerror(error));
  }
  ::close(fd);
  return ntohs(address.sin_port);
}

namespace {

int exitStatusOf(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 1;
}

// The ranks running, for the handler that passes a stop on to them: `kill` of the launcher (a
// scheduler's, systemd's) reached it alone, and its ranks trained on as orphans.
constexpr int kMaxLocalRanks = 4096;
pid_t running_ranks[kMaxLocalRanks];
volatile sig_atomic_t running_rank_count = 0;

volatile sig_atomic_t signal_passed_on = 0;

void passOnToRanks(int signal_number) {
  signal_passed_on = signal_number;
  for (int i = 0; i < running_rank_count; ++i)
    if (running_ranks[i] > 0) ::kill(running_ranks[i], signal_number);
}

// Passes the stop signals on to the ranks while they run; afterwards the dispositions before are
// put back and the ranks forgotten.
class SignalsPassedOn {
 public:
  ~SignalsPassedOn() {
    handler_.restore();
    running_rank_count = 0;
    signal_passed_on = 0;
  }
  // The dispositions before: in a rank before it starts its program (a signal must not be passed
  // on from there to its siblings; one ignored, as under nohup, stays ignored).
  void restore() const { handler_.restore(); }

 private:
  const StopSignalHandler handler_{passOnToRanks, StopSignalHandler::Ignored::kTaken};
};

std::string howItEnded(int status) {
  if (WIFSIGNALED(status)) return "was ended by " + signalName(WTERMSIG(status));
  return "failed (exit status " + std::to_string(exitStatusOf(status)) + ")";
}

}  // namespace

std::string localRanksProblem(int64_t ranks) {
  const int64_t most = std::max(1u, std::thread::hardware_concurrency());
  if (ranks >= 1 && ranks <= most) return "";
  return "must be in [1, " + std::to_string(most) + "] (one rank per hardware thread of this machine at most), got " +
         std::to_string(ranks);
}

int runLocalRanks(const std::vector<std::string>& arguments, int ranks) {
  if (arguments.empty()) throw std::invalid_argument("runLocalRanks: no program");
  if (const std::string problem = localRanksProblem(ranks); !problem.empty()) throw InputError("ranks: " + problem);
  if (ranks > kMaxLocalRanks) throw InputError("ranks: at most " + std::to_string(kMaxLocalRanks) + " on one machine");
  const char* address = std::getenv("MASTER_ADDR");
  const char* port = std::getenv("MASTER_PORT");
  const std::string master_addr = address && *address ? address : "127.0.0.1";
  const std::string master_port = port && *port ? port : std::to_string(freeLoopbackPort());

  std::vector<char*> argv;
  for (const std::string& argument : arguments) argv.push_back(const_cast<char*>(argument.c_str()));
  argv.push_back(nullptr);
  std::fflush(nullptr);

  std::vector<pid_t> children;
  const pid_t launcher = ::getpid();
  const SignalsPassedOn passed_on;
  for (int rank = 0; rank < ranks; ++rank) {
    const pid_t pid = ::fork();
    if (pid < 0) {
      for (pid_t child : children) ::kill(child, SIGTERM);
      for (pid_t child : children) ::waitpid(child, nullptr, 0);
      throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
    }
    if (pid == 0) {
      passed_on.restore();
      // A launcher killed outright (SIGKILL) can pass nothing on: the kernel stops the rank then.
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      if (::getppid() != launcher) ::_exit(128 + SIGTERM);
      const std::string rank_text = std::to_string(rank), size_text = std::to_string(ranks);
      ::setenv("RANK", rank_text.c_str(), 1);
      ::setenv("LOCAL_RANK", rank_text.c_str(), 1);
      ::setenv("WORLD_SIZE", size_text.c_str(), 1);
      ::setenv("LOCAL_WORLD_SIZE", size_text.c_str(), 1);
      ::setenv("MASTER_ADDR", master_addr.c_str(), 1);
      ::setenv("MASTER_PORT", master_port.c_str(), 1);
      ::execv("/proc/self/exe", argv.data());
      std::fprintf(stderr, "rank %d: cannot start %s: %s\n", rank, arguments[0].c_str(), std::strerror(errno));
      ::_exit(127);
    }
    children.push_back(pid);
    running_ranks[rank] = pid;
    running_rank_count = rank + 1;
  }

  int result = 0;
  size_t running = children.size();
  while (running > 0) {
    int status = 0;
    const pid_t done = ::waitpid(-1, &status, 0);
    if (done < 0) {
      if (errno == EINTR) continue;
      break;
    }
    const auto found = std::find(children.begin(), children.end(), done);
    if (found == children.end()) continue;
    const int rank = static_cast<int>(found - children.begin());
    *found = 0;
    running_ranks[rank] = 0;
    --running;
    const int code = exitStatusOf(status);
    if (code != 0 && result == 0) {
      result = code;
      // A rank stopped by a stop signal ends after a step the others agree on (they stop
      // at it too, rank 0 writing the checkpoint): a SIGTERM sent on to them would be their
      // second signal, which ends rank 0 in the middle of that write.
      if (signal_passed_on != 0) {
        std::fprintf(stderr, "stopping: signal %d passed on to every rank\n", static_cast<int>(signal_passed_on));
      } else if (WIFEXITED(status) && isStopSignal(code - 128)) {
        std::fprintf(stderr, "rank %d stopped by %s; the other ranks stop at the same step\n", rank,
                     signalName(code - 128).c_str());
      } else {
        // A rank that failed leaves the others waiting in a collective: stop them. A rank killed
        // outright said nothing itself.
        std::fprintf(stderr, "rank %d %s; stopping the other ranks\n", rank, howItEnded(status).c_str());
        for (pid_t child : children) {
          if (child > 0) ::kill(child, SIGTERM);
        }
      }
    }
  }
  return result;
}

}  // namespace ffloc
