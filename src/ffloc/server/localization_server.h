#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <ostream>
#include <string>

#include "ffloc/localization/localizer.h"
#include "ffloc/server/api_keys.h"
#include "ffloc/server/localize_request.h"
#include "ffloc/server/map_catalog.h"

namespace ffloc {

// HTTP front of one or more maps (a MapCatalog): maps and models are loaded once, then every
// request is one query (docs/server.md).
//   GET  /health                {"status": "ok", ...}, open to every client
//   GET  /maps                  the maps this client may use: name, method, images, model
//   GET  /maps/NAME             a map's images, model and the request defaults
//   POST /maps/NAME/localize    an encoded image as the body (fields as URL parameters) or as
//                               the "image" part of a multipart form (fields as URL parameters
//                               or form fields); answers what `ffloc localize --json` prints
//   GET  /maps/NAME/scene       what the viewer draws: the mapping cameras, a subsample of the
//                               map's points and the last answers of POST /maps/NAME/localize
//   GET  /map, GET /map/scene, POST /localize   the same for a server of one map
//   GET  /                      the map viewer, a page (with its scripts under /viewer/) compiled
//                               into the server; open to every client, as it holds no map data
// Bad requests get status 400 and {"error": "<field>: <what>"}; without a valid key (when the
// server has keys) 401, a map the key may not use 403, an unknown map 404, a body over
// max_body_bytes 413, a POST without Content-Length 411, a query beyond max_waiting_queries 503 (and so is a connection beyond max_pending_connections),
// a request whose headers or body arrive slower than their deadline 408 (and the connection is
// closed). A query whose client has disconnected while it waited is dropped unrun.
struct ServerOptions {
  std::string host = "127.0.0.1";  // loopback: serving other machines is a choice (0.0.0.0)
  int port = 8080;                 // 0: any free port, see LocalizationServer::bind()
  size_t max_body_bytes = size_t{32} << 20;
  // Queries waiting while one runs. The HTTP library's threads are few (8 on small machines), so
  // without a bound, waiting queries would take every thread and /health would stop answering.
  size_t max_waiting_queries = 4;
  // Connections served at once, one thread each. The HTTP library's default (8 on small
  // machines) let 32 keep-alive clients hold every thread, so queries were never refused as busy
  // and /health waited seconds behind them (scripts/load_test.sh).
  size_t max_connections = 64;
  // Accepted connections waiting for a thread; beyond them a connection is answered 503 at once
  // and closed, so that clients opening connections faster than they are served cannot pile up.
  size_t max_pending_connections = 256;
  // How long each request may take to arrive, in total: its headers from its first byte, then
  // its body. The HTTP library bounds each read (5 s), not the request, so clients trickling one
  // header line every 2 s held connection threads for as long as they liked.
  std::chrono::milliseconds header_timeout{10000};
  std::chrono::milliseconds body_timeout{60000};
  RequestLimits limits;
  LocalizeOptions localize;  // per-request defaults; requests may override K, N, seed, selection
  std::ostream* log = nullptr;  // one line per request when set (never a key)
  std::optional<ApiKeys> keys;  // none: every client may use every map
  size_t recent_answers = 20;     // kept per map for GET /maps/NAME/scene
  size_t max_scene_points = 20000;  // points in GET /maps/NAME/scene, spread over the map

  // The server starts max(max_connections, max_waiting_queries + 2) threads at once, and each
  // waiting query holds one with its body: --max-waiting 100000 started 32,000 threads (3.7 GB)
  // and, as they were still being created, ignored SIGTERM.
  static constexpr size_t kMaxConnections = 4096;
  static constexpr size_t kMaxWaitingQueries = 256;
  // InputError naming the field for a value out of range, or a default of `localize` beyond
  // what a request may ask for (`limits`).
  void check() const;
};

class LocalizationServer {
 public:
  // `maps` must outlive the server; InputError from options.check().
  LocalizationServer(const MapCatalog& maps, ServerOptions options);
  ~LocalizationServer();
  LocalizationServer(const LocalizationServer&) = delete;
  LocalizationServer& operator=(const LocalizationServer&) = delete;

  // Binds the socket and returns the port. InputError naming host and port when that fails.
  int bind();
  // Answers requests until stop(); binds first when bind() was not called. std::runtime_error
  // when the socket fails for another reason than stop().
  void serve();
  // From any thread, before or while serve() runs: the query being localized finishes and is
  // answered; requests still arriving and queries waiting their turn are answered 503 without
  // waiting for their clients; then serve() returns (at once, when it had not started listening
  // yet).
  void stop();
  // Queries admitted and not yet answered: the one being localized and those waiting their turn
  // (GET /health says it as "queries_in_flight").
  size_t queriesInFlight() const { return queries_in_flight_.load(); }

 private:
  struct Http;
  const MapCatalog& maps_;
  ServerOptions options_;
  std::unique_ptr<Http> http_;
  int bound_port_ = -1;
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> serving_{false};
  std::atomic<size_t> queries_in_flight_{0};  // running and waiting
};

}  // namespace ffloc
