#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <thread>
#include <vector>

#include "command_model.h"
#include "command_options.h"
#include "commands.h"
#include "ffloc/core/allocator.h"
#include "ffloc/core/error.h"
#include "ffloc/core/host_address.h"
#include "ffloc/core/stop_signals.h"
#include "ffloc/core/threads.h"
#include "ffloc/pipeline/map_localizer.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/server/localization_server.h"

namespace ffloc::cli {
namespace {

struct ServeArguments {
  std::vector<std::string> maps;
  std::string maps_folder;
  std::string keys_path;
  ModelArguments model;
  QueryArguments query;
  std::string host = "127.0.0.1";
  int port = 8080;
  size_t max_body_mb = 32;
  size_t max_waiting = 4;
  size_t max_connections = 64;
  size_t max_pending_connections = 256;
  double header_timeout_s = 10;
  double body_timeout_s = 60;
  std::vector<std::string> method_flags_given;  // of those that apply to one method only
};

// A flag that no served map's method uses would be ignored without a word, as localize refuses it
// (an outside probe: --features on a server of classical maps was advertised as a default).
void refuseOptionsNoMapUses(const std::vector<std::string>& flags_given, const MapCatalog& catalog) {
  for (const std::string& flag : flags_given) {
    std::vector<LocalizationMethod> methods;
    bool used = false;
    for (const std::string& name : catalog.names()) {
      const std::shared_ptr<const ServedMap> map = catalog.get(name);
      if (!map) continue;
      const LocalizationMethod method = map->localizer->method();
      used = used || methodUsesSetting(method, methodSettingOfFlag().at(flag));
      if (std::find(methods.begin(), methods.end(), method) == methods.end()) methods.push_back(method);
    }
    if (!used && methods.size() == 1)
      throw InputError(flag + ": every map served is a " + toString(methods[0]) + " map, which does not use it");
  }
}

// A stop signal (SIGINT, SIGTERM, SIGHUP) stops the server through a pipe: the handler only
// writes one byte (all a signal handler may safely do), and a waiting thread reads it and stops
// the server. Masks would not do, as OpenBLAS starts its threads before main() with nothing
// blocked.
int stop_pipe[2] = {-1, -1};

extern "C" void writeStopByte(int signal) {
  const int saved_errno = errno;
  const char byte = static_cast<char>(signal);
  [[maybe_unused]] const ssize_t written = write(stop_pipe[1], &byte, 1);
  errno = saved_errno;
}

int openStopPipe() {
  if (pipe2(stop_pipe, O_CLOEXEC) != 0 || fcntl(stop_pipe[1], F_SETFL, O_NONBLOCK) != 0)
    throw std::runtime_error("serve: cannot create the signal pipe");
  return stop_pipe[0];
}

class StopOnSignal {
 public:
  explicit StopOnSignal(LocalizationServer& server)
      : read_end_(openStopPipe()), handler_(writeStopByte, StopSignalHandler::Ignored::kKept) {
    waiter_ = std::thread([this, &server] {
      char signal = 0;
      ssize_t got = 0;
      do {
        got = read(read_end_, &signal, 1);
      } while (got < 0 && errno == EINTR);
      if (got != 1 || signal == 0) return;
      handler_.restore();  // a second Ctrl-C ends the process at once
      std::cerr << signalName(signal) << ": stopping once the query being localized is answered (again to quit now)\n";
      server.stop();
    });
  }
  ~StopOnSignal() {
    handler_.restore();
    const char wake = 0;
    [[maybe_unused]] const ssize_t written = write(stop_pipe[1], &wake, 1);
    waiter_.join();
    close(stop_pipe[0]);
    close(stop_pipe[1]);
  }

 private:
  const int read_end_;
  const StopSignalHandler handler_;
  std::thread waiter_;
};

int runServe(const ServeArguments& args) {
  // glibc gives threads that allocate at once arenas of their own (up to 8 per core), and keeps
  // what each arena once held: as more of the 64 connection threads served, the server's RSS
  // grew from 248 to 333 MiB between 1,000 and 10,000 requests of the load test, and stayed at
  // 197-200 MiB with two arenas (docs/server.md, "Memory under load"). Queries run one at a
  // time, so one arena costs no contention that shows, and every query finds the pages an
  // earlier one faulted in: redkitchen's classical queries took 91-94 ms at the median (p90
  // 111-114, RSS +14-17 MiB over 30) with one, 104-106 ms (p90 156-158, +62 MiB) with two.
  AllocatorOptions allocator;
  allocator.max_arenas = 1;
  configureAllocator(allocator);
  setLibraryThreadCount(args.model.threads);
  ServerOptions options;
  options.host = args.host;
  options.port = args.port;
  options.max_body_bytes = args.max_body_mb << 20;
  options.max_waiting_queries = args.max_waiting;
  options.max_connections = args.max_connections;
  options.max_pending_connections = args.max_pending_connections;
  const auto milliseconds = [](double seconds) { return std::chrono::milliseconds(std::llround(seconds * 1000)); };
  options.header_timeout = milliseconds(args.header_timeout_s);
  options.body_timeout = milliseconds(args.body_timeout_s);
  options.localize = localizeOptions(args.query);
  options.log = &std::cerr;

  std::vector<MapCatalog::Source> sources;
  for (const std::string& map : args.maps) sources.push_back(MapCatalog::parseSource(map));
  if (!args.maps_folder.empty()) {
    for (MapCatalog::Source& source : MapCatalog::sourcesInFolder(args.maps_folder)) sources.push_back(std::move(source));
  }
  if (sources.empty()) throw InputError("--map: give at least one map (--map [NAME=]PATH or --maps DIR)");
  // Each map keeps the model it was built with alive through its localizer's owner.
  const MapOpener open = [&](const std::filesystem::path& path) {
    auto opened = std::make_shared<MapLocalizer>(openMapLocalizer(path, [&] { return loadCommandModel(args.model); }));
    ServedMap map;
    map.model_description = opened->model ? opened->model->description : opened->description;
    map.localizer = std::shared_ptr<const Localizer>(opened, opened->localizer.get());
    const std::string warm_up = warmUp(*map.localizer, options.localize);
    std::cerr << "map: " << path.string() << ", " << opened->description << " (" << warm_up << ")\n";
    return map;
  };
  MapCatalog catalog(std::move(sources), open);
  catalog.setLog([](const std::string& line) { std::cerr << line << "\n"; });
  bool fastforward_served = false;
  for (const std::string& name : catalog.names())
    if (const std::shared_ptr<const ServedMap> map = catalog.get(name))
      fastforward_served = fastforward_served || map->localizer->method() == LocalizationMethod::kFastForward;
  // N was announced on a server of classical maps alone, which never read it (an outside review).
  std::cerr << "K = " << options.localize.top_k;
  if (fastforward_served) std::cerr << ", N = " << options.localize.num_features << " (FastForward maps)";
  std::cerr << " unless a request says\n";
  refuseOptionsNoMapUses(args.method_flags_given, catalog);
  if (!args.keys_path.empty()) options.keys = ApiKeys::read(args.keys_path, catalog.names());

  LocalizationServer server(catalog, options);
  const int port = server.bind();
  // An IPv6 address goes in brackets in a URL: http://::1:8080 is no address.
  const std::string address =
      (args.host.find(':') != std::string::npos ? "[" + args.host + "]" : args.host) + ":" + std::to_string(port);
  if (!options.keys) {
    std::cerr << "no --keys: every client that reaches " << address << " may use every map"
              << (isLoopbackHost(args.host) ? " (loopback only: other machines cannot)" : " (not loopback: any machine on the network can)")
              << "\n";
  }
  StopOnSignal stop_on_signal(server);
  std::cerr << "listening on http://" << address << " (" << catalog.names().size()
            << " map(s): GET /health, GET /maps, GET /maps/NAME, GET /maps/NAME/scene, POST /maps/NAME/localize"
            << (catalog.names().size() == 1 ? ", GET /map, POST /localize" : "") << "; Ctrl-C stops)\n"
            << "map viewer: http://" << address << "/\n";
  server.serve();
  std::cerr << "stopped\n";
  return 0;
}

}  // namespace

void registerServeCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<ServeArguments>();
  CLI::App* cmd = app.add_subcommand(
      "serve",
      "Serve a map over HTTP: the model and the map are loaded once, then each POST /localize (an image and its "
      "intrinsics) answers the pose as 'ffloc localize --json' prints it (docs/server.md).");
  cmd->add_option("--map", args->maps,
                  "Map file from 'ffloc map', as [NAME=]PATH (NAME: the file's stem); repeat for more maps. A file "
                  "replaced on disk is reloaded without a restart");
  cmd->add_option("--maps", args->maps_folder, "A folder whose *.ffmap files are all served, named by stem");
  cmd->add_option("--keys", args->keys_path,
                  "API keys: one '<key> <map>[,<map>...]' or '<key> *' a line; clients send 'Authorization: Bearer "
                  "<key>' (without it every client may use every map)");
  addModelOptions(*cmd, args->model, "fastforward maps: the model the map was built with (as for 'ffloc map')");
  addQueryOptions(*cmd, args->query);
  cmd->add_option("--host", args->host, "Address to listen on (0.0.0.0: every interface; with --keys, as a rule)")
      // Empty, the library bound the IPv6 loopback while the start-up message said any machine
      // could reach the server.
      ->check(CLI::Validator(
          [](const std::string& host) {
            return host.empty() ? std::string("empty: name an address (127.0.0.1: this machine only, 0.0.0.0: every "
                                              "interface)")
                                : std::string();
          },
          "ADDRESS"))
      ->capture_default_str();
  cmd->add_option("--port", args->port, "TCP port (0: any free one, printed at start)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  cmd->add_option("--max-body-mb", args->max_body_mb, "Largest request body accepted, in MiB")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  cmd->add_option("--max-waiting", args->max_waiting,
                  "Queries that may wait while one runs, a thread each; more are answered 503 (busy)")
      ->check(CLI::Range(size_t{0}, ServerOptions::kMaxWaitingQueries))
      ->capture_default_str();
  cmd->add_option("--max-connections", args->max_connections,
                  "Connections served at once, a thread each; more wait for a thread")
      ->check(CLI::Range(size_t{1}, ServerOptions::kMaxConnections))
      ->capture_default_str();
  cmd->add_option("--max-pending-connections", args->max_pending_connections,
                  "Connections that may wait for a thread; more are answered 503 (busy) at once and closed")
      ->check(CLI::Range(0, 65536))
      ->capture_default_str();
  cmd->add_option("--header-timeout", args->header_timeout_s,
                  "Seconds a request's headers may take to arrive, in all; slower clients get 408 and are disconnected")
      ->check(secondsIn(0.1, 3600))
      ->capture_default_str();
  cmd->add_option("--body-timeout", args->body_timeout_s,
                  "Seconds a request's body may take to arrive after its headers, in all (408 past it)")
      ->check(secondsIn(0.1, 3600))
      ->capture_default_str();
  for (const char* path_flag : {"--map", "--maps", "--keys"}) cmd->get_option(path_flag)->check(nonEmptyPath());
  cmd->callback([cmd, args, &run] {
    args->method_flags_given = flagsGiven(*cmd, methodSettingOfFlag());
    run = [args] { return runServe(*args); };
  });
}

}  // namespace ffloc::cli
