#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <thread>

#include "command_model.h"
#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/pipeline/localizer.h"
#include "ffloc/pipeline/model_loader.h"
#include "ffloc/server/localization_server.h"

namespace ffloc::cli {
namespace {

struct ServeArguments {
  std::string map_path;
  std::string model = "default";
  std::string host = "127.0.0.1";
  int port = 8080;
  std::string preset = "indoor";
  size_t top_k = 0;      // 0: the preset's
  int64_t features = 0;  // 0: the preset's
  std::string dtype = "f32";
  int threads = 0;
  size_t max_body_mb = 32;
  size_t max_waiting = 4;
};

// SIGINT and SIGTERM stop the server through a pipe: the handler only writes one byte (all a
// signal handler may safely do), and a waiting thread reads it and stops the server. Masks
// would not do, as OpenBLAS starts its threads before main() with nothing blocked.
int stop_pipe[2] = {-1, -1};

extern "C" void writeStopByte(int signal) {
  const int saved_errno = errno;
  const char byte = static_cast<char>(signal);
  [[maybe_unused]] const ssize_t written = write(stop_pipe[1], &byte, 1);
  errno = saved_errno;
}

class StopOnSignal {
 public:
  explicit StopOnSignal(LocalizationServer& server) {
    if (pipe2(stop_pipe, O_CLOEXEC) != 0 || fcntl(stop_pipe[1], F_SETFL, O_NONBLOCK) != 0)
      throw std::runtime_error("serve: cannot create the signal pipe");
    struct sigaction action = {};
    action.sa_handler = writeStopByte;
    action.sa_flags = SA_RESTART;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &previous_interrupt_);
    sigaction(SIGTERM, &action, &previous_terminate_);
    waiter_ = std::thread([this, &server] {
      char signal = 0;
      ssize_t got = 0;
      do {
        got = read(stop_pipe[0], &signal, 1);
      } while (got < 0 && errno == EINTR);
      if (got != 1 || signal == 0) return;
      restoreHandlers();  // a second Ctrl-C ends the process at once
      std::cerr << "signal " << int(signal) << ": stopping after the requests in flight (again to quit now)\n";
      server.stop();
    });
  }
  ~StopOnSignal() {
    restoreHandlers();
    const char wake = 0;
    [[maybe_unused]] const ssize_t written = write(stop_pipe[1], &wake, 1);
    waiter_.join();
    close(stop_pipe[0]);
    close(stop_pipe[1]);
  }

 private:
  void restoreHandlers() {
    sigaction(SIGINT, &previous_interrupt_, nullptr);
    sigaction(SIGTERM, &previous_terminate_, nullptr);
  }

  struct sigaction previous_interrupt_ = {}, previous_terminate_ = {};
  std::thread waiter_;
};

void runServe(const ServeArguments& args) {
  ServerOptions options;
  options.host = args.host;
  options.port = args.port;
  options.max_body_bytes = args.max_body_mb << 20;
  options.max_waiting_queries = args.max_waiting;
  // Formats whose header parseLocalizeRequest cannot read are bounded by OpenCV's own limit.
  setenv("OPENCV_IO_MAX_IMAGE_PIXELS", std::to_string(options.limits.max_image_pixels).c_str(), /*overwrite=*/0);
  options.localize = LocalizeOptions::preset(args.preset);
  if (args.top_k > 0) options.localize.top_k = args.top_k;
  if (args.features > 0) options.localize.num_features = args.features;
  options.log = &std::cerr;

  const LoadedModel model = loadCommandModel(args.model, args.dtype, args.threads);
  const Localizer localizer(*model.model, readMapFile(args.map_path, model.id));
  std::cerr << "map: " << args.map_path << ", " << localizer.map().images.size() << " images; K = "
            << options.localize.top_k << ", N = " << options.localize.num_features << " unless a request says\n";

  LocalizationServer server(localizer, options, model.description);
  const int port = server.bind();
  StopOnSignal stop_on_signal(server);
  std::cerr << "listening on http://" << args.host << ":" << port
            << " (GET /health, GET /map, POST /localize; Ctrl-C stops)\n";
  server.serve();
  std::cerr << "stopped\n";
}

}  // namespace

void registerServeCommand(CLI::App& app) {
  auto args = std::make_shared<ServeArguments>();
  CLI::App* cmd = app.add_subcommand(
      "serve",
      "Serve a map over HTTP: the model and the map are loaded once, then each POST /localize (an image and its "
      "intrinsics) answers the pose as 'ffloc localize --json' prints it (docs/server.md).");
  cmd->add_option("--map", args->map_path, "Map file from 'ffloc map'")->required();
  cmd->add_option("--model", args->model, "The model the map was built with (same forms as for 'ffloc map')")
      ->capture_default_str();
  cmd->add_option("--host", args->host, "Address to listen on (0.0.0.0: every interface)")->capture_default_str();
  cmd->add_option("--port", args->port, "TCP port (0: any free one, printed at start)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  cmd->add_option("--preset", args->preset, "Request defaults: indoor (K=10, N=1500) or outdoor (K=20, N=3000)")
      ->capture_default_str();
  cmd->add_option("--top-k", args->top_k, "Default mapping images per query (overrides the preset)");
  cmd->add_option("--features", args->features, "Default map tokens per query (overrides the preset)");
  cmd->add_option("--dtype", args->dtype, "Network precision: f32, or bf16 (encoder, decoder and DPT head)")
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "libtorch threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--max-body-mb", args->max_body_mb, "Largest request body accepted, in MiB")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  cmd->add_option("--max-waiting", args->max_waiting,
                  "Queries that may wait while one runs; more are answered 503 (busy)")
      ->capture_default_str();
  cmd->callback([args] { runServe(*args); });
}

}  // namespace ffloc::cli
