#include "ffloc/server/localization_server.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <regex>
#include <set>
#include <stdexcept>
#include <thread>
#include <variant>
#include <vector>
#include <nlohmann/json.hpp>

#include "ffloc/core/allocator.h"
#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/core/utf8.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/localization/localization_json.h"
#include "ffloc/server/localize_request.h"
#include "ffloc/server/viewer_assets.h"

// Last: it brings <httplib.h> and so <resolv.h>, whose _res macro breaks Eigen headers included
// after it.
#include "ffloc/server/deadline_server.h"

namespace ffloc {

namespace {

// One query at a time on the model: each already uses every torch thread, and the model is
// shared. Unlike a mutex, the wait for a turn ends when the server stops: a query that has not
// started by then is not run, so a stop waits for the query running, not for every query
// waiting behind it (up to max_waiting_queries, each as long as a query takes).
class QueryTurns {
 public:
  // Waits for the model; false when the server stopped first.
  bool take() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return !running_ || stopping_; });
    if (stopping_) return false;
    running_ = true;
    return true;
  }
  void give() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      running_ = false;
    }
    changed_.notify_one();
  }
  void stop() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool running_ = false;
  bool stopping_ = false;
};

// A query's turn on the model, given back when the query ends.
class QueryTurn {
 public:
  explicit QueryTurn(QueryTurns& turns) : turns_(turns), taken_(turns.take()) {}
  ~QueryTurn() {
    if (taken_) turns_.give();
  }
  QueryTurn(const QueryTurn&) = delete;
  QueryTurn& operator=(const QueryTurn&) = delete;
  bool taken() const { return taken_; }

 private:
  QueryTurns& turns_;
  bool taken_;
};

}  // namespace

struct LocalizationServer::Http {
  explicit Http(const ServerOptions& options) : server(options.header_timeout, options.body_timeout) {}
  DeadlineServer server;
  // Every route with its method ("GET" also answers HEAD), for telling a wrong method (405) from
  // a wrong path (404) before the library reads a body.
  std::vector<std::pair<std::string, std::regex>> routes;
  QueryTurns turns;
  std::mutex log_mutex;
  // The last answers of each map, oldest first, each with the query's intrinsics (the viewer
  // draws the query camera with them).
  std::mutex recent_mutex;
  std::map<std::string, std::deque<nlohmann::json>> recent;
};

namespace {

constexpr const char* kJson = "application/json";
// A query image larger than this leaves its decoding and SIFT buffers as free heap that the next
// query, usually smaller, does not reuse: after one 36-megapixel PNG the server held 443 MB where
// it had held 185 MB, and kept them. Handed back to the kernel after such a query (a lower mmap
// threshold for every query would do it too, but made redkitchen's 640 x 480 queries re-fault
// their buffers each time: 85 -> 133 ms at the median, 2-vCPU AMD EPYC).
constexpr size_t kTrimAfterPixels = 8'000'000;
// What nginx logs for a request whose client closed the connection first; never sent, only logged.
constexpr int kClientClosedRequest = 499;

// Request text (a name, an unknown field) reaches answers and may not be UTF-8: replace rather
// than throw.
void replyError(httplib::Response& response, int status, const std::string& message) {
  response.status = status;
  response.set_content(jsonText({{"error", message}}), kJson);
  // HTTP requires a 401 to name the scheme it asks for; clients retried or failed on one without.
  if (status == 401) response.set_header("WWW-Authenticate", "Bearer");
}

// URL parameters, then (multipart) form fields; a field given twice is a request error rather
// than a silent choice between two values.
std::map<std::string, std::string> requestFields(const httplib::Request& request) {
  std::map<std::string, std::string> fields;
  auto add = [&fields](const std::string& key, const std::string& value) {
    if (!fields.emplace(key, value).second) throw InputError(key + ": given more than once");
  };
  // The library's parse drops what it cannot read: '?=5' became the field "5", and
  // 'name=a;seed=2' the name "2" ('fx=1;fy=2' was answered "fy: missing").
  // It also merges a field given twice with one value ('fx=1&fx=1'): counted here.
  const size_t query_at = request.target.find('?');
  const std::string query = query_at == std::string::npos ? "" : request.target.substr(query_at + 1);
  std::set<std::string> named;
  for (size_t start = 0; start < query.size();) {
    const size_t end = std::min(query.find('&', start), query.size());
    const std::string piece = query.substr(start, end - start);
    const size_t equals = piece.find('=');
    const auto sent = [](const std::string& text) {
      return escapeControlCharacters(httplib::detail::decode_url(text, true));
    };
    if (equals == 0) throw InputError("a query field has no name ('" + sent(piece) + "')");
    if (equals != std::string::npos && piece.find('=', equals + 1) != std::string::npos)
      throw InputError(sent(piece.substr(0, equals)) + ": '" + sent(piece) +
                       "' holds two '=': separate fields with '&' (not ';'), and write '=' in a value as %3D");
    if (!piece.empty() && !named.insert(httplib::detail::decode_url(piece.substr(0, equals), true)).second)
      throw InputError(sent(piece.substr(0, equals)) + ": given more than once");
    start = end + 1;
  }
  for (const auto& [key, value] : request.params) add(key, value);
  for (const auto& [key, part] : request.files) {
    if (key != "image") add(key, part.content);
  }
  return fields;
}

std::string notFoundMessage(const httplib::Request& request, const std::string& path) {
  return "not found: " + request.method + " " + path +
         " (known: GET /, GET /health, GET /maps, GET /maps/NAME, GET /maps/NAME/scene, POST /maps/NAME/localize, "
         "and GET /map, GET /map/scene, POST /localize on a server of one map)";
}

// cpp-httplib decodes the whole path before routing, so an encoded slash split a segment in two:
// GET /maps/s%2Fscene was answered with the scene of map 's', POST /maps/s%2Flocalize
// localized against it. For a path with an encoded slash (%2F, or the library's %u002F), the
// path as the routes must see it: each segment decoded on its own (by the library's decoder, as
// every other path is), with a '/' or '%' inside a segment encoded again so that it stays
// there. nullopt for a path without one, which request.path routes right.
std::optional<std::string> pathWithEncodedSlashes(const std::string& target) {
  const std::string sent = target.substr(0, target.find('?'));
  std::string path;
  bool slash_inside = false;
  for (size_t start = 0;;) {
    const size_t end = sent.find('/', start);
    for (const char c : httplib::detail::decode_url(sent.substr(start, end - start), false)) {
      slash_inside = slash_inside || c == '/';
      path += c == '/' ? "%2F" : c == '%' ? "%25" : std::string(1, c);
    }
    if (end == std::string::npos) break;
    path += '/';
    start = end + 1;
  }
  if (!slash_inside) return std::nullopt;
  return path;
}

// The message for an error status the HTTP library set itself, with no body.
std::string libraryErrorMessage(int status, size_t max_body_bytes) {
  switch (status) {
    case 400: return "bad request: the HTTP library could not parse the request (malformed headers or multipart form)";
    case 413:
      return "payload too large: the body is over the server's limit of " + std::to_string(max_body_bytes) + " bytes";
    case 414: return "URI too long: the path and query string are over the HTTP library's limit of 8 KiB";
    default: return "HTTP " + std::to_string(status);
  }
}

struct Refusal {
  Refusal() = default;
  Refusal(int status, std::string message, std::string allow = "")
      : status(status), message(std::move(message)), allow(std::move(allow)) {}
  int status = 0;  // 0: none
  std::string message;
  std::string allow;  // 405: the methods the path answers, for the Allow header
};

// How long a client's text (a path, a name, an error quoting a field) may run in a log line: a
// 5000-byte name was logged whole, filling the log at the client's will.
constexpr size_t kMaxLoggedNameBytes = 200;
constexpr size_t kMaxLoggedMessageBytes = 600;


const char* const kLengthRequired = "length required: send the body with a Content-Length header (no chunked transfer)";

// Why a POST's headers cannot make a query: exactly one Content-Length of decimal digits, within
// the body limit, and a body type that can hold an image.
Refusal postRefusal(const httplib::Request& request, size_t max_body_bytes) {
  const size_t lengths = request.get_header_value_count("Content-Length");
  if (lengths == 0) return {411, kLengthRequired};
  if (lengths > 1) return {400, "Content-Length: given more than once"};
  const std::string length = request.get_header_value("Content-Length");
  if (length.empty() || length.size() > 18 || length.find_first_not_of("0123456789") != std::string::npos) {
    return {400, "Content-Length: '" + length + "' is not a byte count"};
  }
  // The library would first read (and drop) the announced bytes: a client announcing more than
  // it sends was answered 408 at the body's deadline instead.
  if (std::stoull(length) > max_body_bytes) return {413, libraryErrorMessage(413, max_body_bytes)};
  // Two types, like two lengths, may be read differently by a proxy in front.
  if (request.get_header_value_count("Content-Type") > 1) return {400, "Content-Type: given more than once"};
  const std::string type = request.get_header_value("Content-Type");
  // Media types are case-insensitive: IMAGE/PNG was refused as 415.
  const std::string lower_type = asciiLowercase(type);
  const auto starts = [&](const char* prefix) { return lower_type.rfind(prefix, 0) == 0; };
  // What curl --data-binary sends without -H: the library would read the image as form fields
  // and, past 8 KiB, refuse it as too large (413), which sent users hunting for a size limit.
  if (starts("application/x-www-form-urlencoded")) {
    return {400,
            "Content-Type: the body is a URL-encoded form; send the image as the body with Content-Type image/jpeg, "
            "image/png or application/octet-stream (curl: -H 'Content-Type: image/jpeg' --data-binary @query.jpg), "
            "or as the 'image' part of a multipart form (curl: -F image=@query.jpg)"};
  }
  if (starts("multipart/form-data")) {
    const std::string shown = "Content-Type '" + escapeControlCharacters(cutText(type, kMaxLoggedNameBytes)) + "': ";
    // The HTTP library parses a form only when its type and boundary are written in lower case:
    // any other spelling passed here and the form was read as an image ("fx: missing").
    const size_t boundary = type.find("boundary=");
    if (type.rfind("multipart/form-data", 0) != 0 || boundary == std::string::npos) {
      return {415, shown + "write it 'multipart/form-data; boundary=...', in lower case and with its boundary, the "
                           "only spelling the HTTP library reads as a form"};
    }
    // The library takes all that follows 'boundary=' for the boundary: '; charset=utf-8' after it
    // made every part unreadable, refused as a malformed request.
    if (type.find(';', boundary) != std::string::npos)
      return {415, shown + "put boundary=... last, the only place the HTTP library reads it from"};
  }
  if (!type.empty() && !starts("image/") && !starts("application/octet-stream") && !starts("multipart/form-data")) {
    return {415, "Content-Type '" + type +
                     "': send an encoded image (image/jpeg, image/png, application/octet-stream) or a multipart form"};
  }
  return {};
}

// As the CLI and Python refuse their flag: a classical map ignored features= and selection=
// without a word.
void refuseSettingsTheMethodIgnores(const std::map<std::string, std::string>& fields, LocalizationMethod method) {
  for (const char* field : {"features", "selection"})
    if (fields.count(field) && !methodUsesSetting(method, field))
      throw InputError(std::string(field) + ": the map is a " + toString(method) + " map, which does not use it");
}

const std::string& imageBytes(const httplib::Request& request) {
  if (!request.is_multipart_form_data()) return request.body;
  const size_t parts = request.files.count("image");
  if (parts == 0) throw InputError("image: the multipart form has no 'image' part");
  if (parts > 1) throw InputError("image: given more than once");
  return request.files.find("image")->second.content;
}

// Counts a query from arrival to answer; refuses it when too many already wait.
class QueryTicket {
 public:
  QueryTicket(std::atomic<size_t>& in_flight, size_t max_waiting) : in_flight_(in_flight) {
    admitted_ = in_flight_.fetch_add(1) <= max_waiting;
  }
  ~QueryTicket() { in_flight_.fetch_sub(1); }
  bool admitted() const { return admitted_; }

 private:
  std::atomic<size_t>& in_flight_;
  bool admitted_ = false;
};

// The map a request names: NAME of /maps/NAME/... (`matches` as its route matched the path), or
// the only map of the server for /map and /localize; a 404 when there is none.
std::variant<std::string, Refusal> requestedMap(const std::smatch& matches, const MapCatalog& maps) {
  if (matches.size() > 1) return matches[1].str();
  if (maps.names().size() == 1) return maps.names().front();
  return Refusal{404, "this server holds " + std::to_string(maps.names().size()) +
                          " maps: name one, as GET /maps/NAME or POST /maps/NAME/localize (GET /maps lists them)"};
}

nlohmann::json mapSummary(const std::string& name, const ServedMap& map) {
  return {{"name", name},
          {"method", toString(map.localizer->method())},
          {"images", map.localizer->cameras().size()},
          {"model", map.model_description}};
}

nlohmann::json intrinsicsJson(const Intrinsics& k) {
  return {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"width", k.width}, {"height", k.height}};
}

// GET /maps/NAME/scene: points as one flat array x0, y0, z0, x1, ... in single precision, which is
// what the page uploads to the graphics card and a third of the text of [x, y, z] triples at
// full precision.
nlohmann::json sceneJson(const std::string& name, const Localizer& localizer, size_t max_points,
                         const std::deque<nlohmann::json>& recent) {
  nlohmann::json cameras = nlohmann::json::array();
  for (const MapCamera& camera : localizer.cameras()) {
    cameras.push_back({{"name", camera.name},
                       {"camera_to_world", matrix4Json(camera.camera_to_world.matrix())},
                       {"intrinsics", intrinsicsJson(camera.intrinsics)}});
  }
  nlohmann::json points = nlohmann::json::array();
  for (const Eigen::Vector3d& point : localizer.mapPoints(max_points)) {
    for (int axis = 0; axis < 3; ++axis) points.push_back(static_cast<float>(point[axis]));
  }
  return {{"name", name},
          {"method", toString(localizer.method())},
          {"metric", localizer.metric()},
          {"cameras", cameras},
          {"points", points},
          {"recent", nlohmann::json(recent)}};
}

}  // namespace

void ServerOptions::check() const {
  if (max_connections < 1 || max_connections > kMaxConnections)
    throw InputError("max_connections: must be in [1, " + std::to_string(kMaxConnections) + "], got " +
                     std::to_string(max_connections));
  if (max_waiting_queries > kMaxWaitingQueries)
    throw InputError("max_waiting_queries: must be in [0, " + std::to_string(kMaxWaitingQueries) + "], got " +
                     std::to_string(max_waiting_queries));
  // A default beyond what a request may ask for was advertised by GET /maps/NAME, and the same
  // value sent back was refused (an outside probe).
  if (localize.top_k > limits.max_top_k)
    throw InputError("top_k: " + std::to_string(localize.top_k) + " is more than a request may ask for (" +
                     std::to_string(limits.max_top_k) + ")");
  if (localize.num_features > limits.max_features)
    throw InputError("num_features: " + std::to_string(localize.num_features) + " is more than a request may ask for (" +
                     std::to_string(limits.max_features) + ")");
}

LocalizationServer::LocalizationServer(const MapCatalog& maps, ServerOptions options)
    : maps_(maps), options_(std::move(options)), http_(std::make_unique<Http>(options_)) {
  options_.check();
  httplib::Server& server = http_->server;
  server.set_payload_max_length(options_.max_body_bytes);
  http_->server.setConnectionLimits(std::max<size_t>(options_.max_connections, options_.max_waiting_queries + 2),
                                    options_.max_pending_connections);
  // Without it, small answers wait on Nagle's algorithm: 28 ms per GET /health over loopback
  // instead of 0.5 ms, both with the machine loaded (docs/server.md, "Overhead").
  server.set_tcp_nodelay(true);
  // SO_REUSEADDR so a restart can take the port at once, but not the library's default
  // SO_REUSEPORT, with which a second server on the same port binds silently and the kernel
  // shares requests between two maps.
  server.set_socket_options([](socket_t socket) {
    const int yes = 1;
    setsockopt(socket, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });

  // One line a request: when (UTC), from whom, its method, its path and what came of it. Without
  // the first two no line could be matched with a client's or a proxy's log (an outside review).
  auto log = [this](const httplib::Request& request, const std::string& outcome) {
    if (!options_.log) return;
    const std::string line = utcTimestamp(std::chrono::system_clock::now()) + " " + request.remote_addr + " " +
                             request.method + " " + cutText(request.path, kMaxLoggedNameBytes) + " " + outcome;
    std::lock_guard<std::mutex> lock(http_->log_mutex);
    *options_.log << escapeControlCharacters(line) << std::endl;
  };

  const auto get = [this](const std::string& pattern, httplib::Server::Handler handler) {
    http_->server.Get(pattern, std::move(handler));
    http_->routes.emplace_back("GET", std::regex(pattern));
  };
  const auto post = [this](const std::string& pattern, httplib::Server::Handler handler) {
    http_->server.Post(pattern, std::move(handler));
    http_->routes.emplace_back("POST", std::regex(pattern));
  };

  // The request's Authorization header, or a 400 when it is given twice: the first decided, and a
  // proxy in front may read the other (as for Content-Length).
  const auto authorization = [](const httplib::Request& request) -> std::variant<std::string, Refusal> {
    if (request.get_header_value_count("Authorization") > 1) return Refusal{400, "Authorization: given more than once"};
    return request.get_header_value("Authorization");
  };
  const char* const unauthorized = "unauthorized: send 'Authorization: Bearer <key>' with a key of this server";

  // Whether the request may use the map its route names: its key (on a server with keys) and the
  // map's existence. Decided from the headers, so a POST is refused before its body is read
  // (twenty clients without a key uploading 30 MB each took 750 MiB before their 401s).
  const auto accessRefusal = [this, authorization, unauthorized](const httplib::Request& request,
                                                   const std::smatch& matches) -> std::variant<std::string, Refusal> {
    std::variant<std::string, Refusal> named = requestedMap(matches, maps_);
    if (std::holds_alternative<Refusal>(named)) return named;
    const std::string& name = std::get<std::string>(named);
    if (options_.keys) {
      const std::variant<std::string, Refusal> key = authorization(request);
      if (std::holds_alternative<Refusal>(key)) return key;
      switch (options_.keys->decide(std::get<std::string>(key), name)) {
        case ApiKeys::Decision::kAllowed: break;
        case ApiKeys::Decision::kUnauthenticated:
          return Refusal{401, unauthorized};
        case ApiKeys::Decision::kForbidden:
          return Refusal{403, "forbidden: this key may not use map '" + name + "'"};
      }
    }
    const std::vector<std::string>& names = maps_.names();
    if (std::find(names.begin(), names.end(), name) == names.end())
      return Refusal{404, "map '" + name + "': no such map (GET /maps lists them)"};
    return named;
  };

  // The name and map of a request, when the client may use it; a null map with the refusal set
  // otherwise.
  auto authorizedMap = [this, accessRefusal](const httplib::Request& request, httplib::Response& response)
      -> std::pair<std::string, std::shared_ptr<const ServedMap>> {
    const std::variant<std::string, Refusal> access = accessRefusal(request, request.matches);
    if (const Refusal* refusal = std::get_if<Refusal>(&access)) {
      replyError(response, refusal->status, refusal->message);
      return {};
    }
    const std::string& name = std::get<std::string>(access);
    std::shared_ptr<const ServedMap> map = maps_.get(name);
    if (!map) replyError(response, 404, "map '" + name + "': no such map (GET /maps lists them)");
    return {name, map};
  };

  // Open to every client, for load balancers: says nothing a key would protect beyond the count.
  get("/health", [this, log](const httplib::Request& request, httplib::Response& response) {
    const nlohmann::json body = {
        {"status", "ok"}, {"maps", maps_.names().size()}, {"queries_in_flight", queriesInFlight()}};
    response.set_content(jsonText(body), kJson);
    log(request, "200");
  });

  get("/maps", [this, log, authorization, unauthorized](const httplib::Request& request, httplib::Response& response) {
    std::vector<std::string> names = maps_.names();
    if (options_.keys) {
      const std::variant<std::string, Refusal> given = authorization(request);
      if (const Refusal* refusal = std::get_if<Refusal>(&given)) {
        replyError(response, refusal->status, refusal->message);
        return;
      }
      const std::string& key = std::get<std::string>(given);
      if (options_.keys->decide(key, "") != ApiKeys::Decision::kAllowed) {
        replyError(response, 401, unauthorized);
        return;
      }
      names = options_.keys->allowedMaps(key, names);
    }
    nlohmann::json list = nlohmann::json::array();
    for (const std::string& name : names) list.push_back(mapSummary(name, *maps_.get(name)));
    response.set_content(jsonText({{"maps", list}}), kJson);
    log(request, "200");
  });

  const auto describeMap = [this, log, authorizedMap](const httplib::Request& request, httplib::Response& response) {
    const auto [name, map] = authorizedMap(request, response);
    if (!map) return;
    const Localizer& localizer = *map->localizer;
    nlohmann::json names = nlohmann::json::array();
    for (const MapCamera& camera : localizer.cameras()) names.push_back(camera.name);
    nlohmann::json body = mapSummary(name, *map);
    body["names"] = names;
    body["metric"] = localizer.metric();
    body["model_id"] = localizer.modelId();
    // Only what this map's method reads: a classical map listed FastForward's features and
    // selection (an outside review).
    nlohmann::json defaults = {{"top_k", options_.localize.top_k}, {"seed", options_.localize.seed}};
    if (methodUsesSetting(localizer.method(), "features")) defaults["features"] = options_.localize.num_features;
    if (methodUsesSetting(localizer.method(), "selection"))
      defaults["selection"] = toString(options_.localize.selection);
    body["defaults"] = defaults;
    response.set_content(jsonText(body), kJson);
    log(request, "200");
  };
  get("/map", describeMap);
  get(R"(/maps/([^/]+))", describeMap);

  const auto describeScene = [this, log, authorizedMap](const httplib::Request& request, httplib::Response& response) {
    const auto [name, map] = authorizedMap(request, response);
    if (!map) return;
    std::deque<nlohmann::json> recent;
    {
      std::lock_guard<std::mutex> lock(http_->recent_mutex);
      const auto found = http_->recent.find(name);
      if (found != http_->recent.end()) recent = found->second;
    }
    response.set_content(jsonText(sceneJson(name, *map->localizer, options_.max_scene_points, recent)), kJson);
    log(request, "200");
  };
  get("/map/scene", describeScene);
  get(R"(/maps/([^/]+)/scene)", describeScene);

  for (const ViewerAsset& asset : viewerAssets()) {
    get(asset.route, [asset](const httplib::Request&, httplib::Response& response) {
      response.set_content(reinterpret_cast<const char*>(asset.bytes), asset.size, asset.content_type);
    });
  }

  // The body limit of the HTTP library holds only for bodies that announce their length, so a
  // chunked upload or one without Content-Length is refused before it is read.
  // Checked before the body is read: a request whose length is ambiguous (two headers, which a
  // proxy in front may read differently: request smuggling) or not a number is refused, and
  // so is a body that cannot be an image. So are a path no route serves (404) and a method its
  // route does not answer (405): the library would read a PUT's body first, and refuse a form
  // body as too large (413).
  const auto refusalBeforeBody = [this, accessRefusal](const httplib::Request& request) -> Refusal {
    // "Transfer-Encoding : chunked" is no header the library knows, but a lenient proxy in front
    // may read it as one and split the body elsewhere (RFC 9112 5.1 asks for a 400).
    for (const auto& [name, value] : request.headers)
      if (name.find_first_of(" \t") != std::string::npos)
        return {400, "header '" + escapeControlCharacters(cutText(name, kMaxLoggedNameBytes)) +
                         "': whitespace in a field name"};
    // The library reads no body of a GET: one sent was parsed as the next request, whose answer
    // a proxy in front would hand to another client (found by an outside probe).
    if (request.method == "GET" || request.method == "HEAD") {
      const std::string length = request.get_header_value("Content-Length");
      if (request.has_header("Transfer-Encoding") || length.find_first_not_of('0') != std::string::npos)
        return {400, "a " + request.method + " request carries no body; this one announced " +
                         (request.has_header("Transfer-Encoding")
                              ? std::string("a chunked one")
                              : escapeControlCharacters(cutText(length, kMaxLoggedNameBytes)) + " bytes")};
    }
    // The library reads a body that is both chunked and of a Content-Length as chunked: past
    // the body limit, and with a request hidden after the last chunk run as a second one, which
    // a proxy in front that goes by Content-Length never saw (request smuggling).
    if (request.has_header("Transfer-Encoding")) {
      if (!request.has_header("Content-Length")) return {411, kLengthRequired};
      return {400, "Transfer-Encoding and Content-Length: both given, so the body's length is ambiguous; send one "
                   "Content-Length"};
    }
    // The library inflates a gzip or deflate body as it reads it, past the body limit (309 KiB
    // became 300 MB) and before any key was checked; images are compressed already.
    if (request.has_header("Content-Encoding") && request.get_header_value("Content-Encoding") != "identity") {
      return {415, "Content-Encoding '" + escapeControlCharacters(request.get_header_value("Content-Encoding")) +
                       "': not accepted; send the image as it is (JPEG and PNG are compressed already)"};
    }
    const std::optional<std::string> split_path = pathWithEncodedSlashes(request.target);
    const std::string& path = split_path ? *split_path : request.path;
    std::string allow;
    for (const auto& [method, pattern] : http_->routes) {
      std::smatch match;
      if (!std::regex_match(path, match, pattern)) continue;
      // A route that matches a path with an encoded slash holds it in its map's name (NAME is
      // the one part of a route that is not fixed text, and no fixed text holds '%'). No map
      // has that name, whatever the method, as names hold no '/'. Where the slash falls
      // elsewhere, no route matches (404 below).
      if (split_path) {
        return {404, "map '" + httplib::detail::decode_url(match[1], false) +
                         "': no such map (map names hold no '/'; GET /maps lists them)"};
      }
      if (method == request.method || (method == "GET" && request.method == "HEAD")) {
        if (request.method != "POST") return Refusal{};
        const std::variant<std::string, Refusal> access = accessRefusal(request, match);
        if (const Refusal* refusal = std::get_if<Refusal>(&access)) return *refusal;
        const Refusal refusal = postRefusal(request, options_.max_body_bytes);
        if (refusal.status != 0 || request.is_multipart_form_data()) return refusal;
        // The body is the image alone, so every field is in the URL: a query missing fx was
        // refused only once its image had arrived.
        const std::shared_ptr<const ServedMap> map = maps_.get(std::get<std::string>(access));
        if (!map) return Refusal{};  // gone since: the route answers 404
        try {
          const std::map<std::string, std::string> fields = requestFields(request);
          refuseSettingsTheMethodIgnores(fields, map->localizer->method());
          parseLocalizeFields(fields, options_.localize, options_.limits);
        } catch (const InputError& e) {
          return {400, e.what()};
        }
        return Refusal{};
      }
      allow += (allow.empty() ? "" : ", ") + (method == "GET" ? std::string("GET, HEAD") : method);
    }
    if (allow.empty()) return {404, notFoundMessage(request, path)};
    return {405, "method not allowed: " + request.method + " " + path + "; this route answers " + allow, allow};
  };
  const auto reply = [](httplib::Response& response, const Refusal& refusal) {
    replyError(response, refusal.status, refusal.message);
    if (!refusal.allow.empty()) response.set_header("Allow", refusal.allow);
    DeadlineServer::closeAfterAnswer(response);
  };
  server.set_pre_routing_handler([refusalBeforeBody, reply](const httplib::Request& request, httplib::Response& response) {
    // Range is ignored, as HTTP allows: every answer is whole. The library built a multi-range
    // answer in memory, one copy of the body per range, overlapping ones too (an outside probe:
    // one 8 KB request without a key, 2700 ranges of a 670 KB viewer asset, 1.8 GB), and cut JSON
    // answers short. The request is the library's own, not const; only this handler sees it first.
    const_cast<httplib::Request&>(request).ranges.clear();
    const Refusal refusal = refusalBeforeBody(request);
    if (refusal.status == 0) return httplib::Server::HandlerResponse::Unhandled;
    reply(response, refusal);
    return httplib::Server::HandlerResponse::Handled;
  });
  // A client that asks before sending its body is told a refusal (413 included) at once rather
  // than invited to send a body that will be refused.
  server.set_expect_100_continue_handler([refusalBeforeBody, reply](const httplib::Request& request,
                                                                     httplib::Response& response) {
    const Refusal refusal = refusalBeforeBody(request);
    if (refusal.status == 0) return 100;
    reply(response, refusal);
    return refusal.status;
  });

  const auto localize = [this, log, authorizedMap](const httplib::Request& request, httplib::Response& response) {
    const auto start = std::chrono::steady_clock::now();
    const auto [name, map] = authorizedMap(request, response);
    if (!map) return;
    const QueryTicket ticket(queries_in_flight_, options_.max_waiting_queries);
    if (!ticket.admitted()) {
      replyError(response, 503,
                 "busy: one query is running and " + std::to_string(options_.max_waiting_queries) +
                     " are waiting; retry later");
      return;
    }
    if (DeadlineServer::clientDisconnected()) {
      replyError(response, kClientClosedRequest, "client closed the connection before its query started; not run");
      return;
    }
    LocalizeRequest query;
    try {
      const std::map<std::string, std::string> fields = requestFields(request);
      refuseSettingsTheMethodIgnores(fields, map->localizer->method());
      query = parseLocalizeRequest(fields, imageBytes(request), options_.localize, options_.limits);
    } catch (const InputError& e) {
      replyError(response, 400, e.what());
      return;
    }
    // Asked on this thread, the connection's, between the query's stages.
    query.options.stop_requested = [] { return DeadlineServer::clientDisconnected(); };
    nlohmann::json body;
    try {
      const QueryTurn turn(http_->turns);
      if (!turn.taken()) {
        replyError(response, 503,
                   "server stopping: the query had not started when the server began to stop; retry later");
        DeadlineServer::closeAfterAnswer(response);
        return;
      }
      // A client that left while its query waited (a timeout, a user giving up) would never
      // read the answer: the query is dropped rather than holding the model for nothing. One
      // that leaves while its query runs is stopped at the next stage (stop_requested).
      if (DeadlineServer::clientDisconnected()) {
        replyError(response, kClientClosedRequest, "client closed the connection while its query waited; not run");
        return;
      }
      const LocalizationResult result = map->localizer->localize(query.rgb, query.intrinsics, query.name, query.options);
      body = localizationJson(query.name, result, *map->localizer);
      if (query.rgb.total() > kTrimAfterPixels) {
        query.rgb.release();
        returnFreeMemory();
      }
    } catch (const InputError& e) {
      replyError(response, 400, e.what());
      return;
    } catch (const QueryStopped& e) {
      replyError(response, kClientClosedRequest,
                 std::string("client closed the connection while its query ran; ") + e.what());
      return;
    }
    response.set_content(jsonText(body), kJson);
    if (options_.recent_answers > 0) {
      std::lock_guard<std::mutex> lock(http_->recent_mutex);
      std::deque<nlohmann::json>& recent = http_->recent[name];
      recent.push_back({{"answer", body}, {"intrinsics", intrinsicsJson(query.intrinsics)}});
      while (recent.size() > options_.recent_answers) recent.pop_front();
    }
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    log(request, "200 " + cutText(query.name, kMaxLoggedNameBytes) + " " + body["status"].get<std::string>() + " " +
        std::to_string(body["inliers"].get<int>()) + " inliers, " + std::to_string(static_cast<int>(ms)) + " ms");
  };
  post("/localize", localize);
  post(R"(/maps/([^/]+)/localize)", localize);

  // Every status >= 400, ours and the library's (404, 413, ...), answers JSON and is logged.
  server.set_error_handler([this, log](const httplib::Request& request, httplib::Response& response) {
    // The library reports a request cut at its deadline, or by a stop, as malformed (400); the
    // connection ends after the answer.
    if (const DeadlineServer::RequestCut cut = DeadlineServer::requestCut(); cut.status != 0) {
      replyError(response, cut.status, cut.message);
      DeadlineServer::closeAfterAnswer(response);
    } else if (response.status == 400 && response.body.empty() && DeadlineServer::clientDisconnected()) {
      // Logged as a request the library could not parse, which counted phones on a flaky network
      // as broken clients (an outside probe). A client that only half-closed may still read it.
      replyError(response, 400, "bad request: the client closed its side of the connection before the body had all arrived");
      DeadlineServer::closeAfterAnswer(response);
    } else if (response.status == 416) {
      // The library refuses a Range header it cannot parse before any route is chosen, and every
      // answer here is whole (Range is ignored): "HTTP 416" on a POST /localize said nothing.
      replyError(response, 400, "Range: '" + escapeControlCharacters(cutText(request.get_header_value("Range"),
                                                                            kMaxLoggedNameBytes)) +
                                    "' is no byte range; this server sends whole answers, so send no Range header");
      DeadlineServer::closeAfterAnswer(response);
    }
    // The library's own refusals (a header it could not parse) leave the rest of what the client
    // sent unread: read on as the next request, text inside an over-long header ran as one.
    if (response.body.empty()) {
      replyError(response, response.status, libraryErrorMessage(response.status, options_.max_body_bytes));
      DeadlineServer::closeAfterAnswer(response);
    }
    const nlohmann::json body = nlohmann::json::parse(response.body, nullptr, false);
    const std::string message = body.is_object() && body.contains("error") ? body["error"].get<std::string>() : "";
    log(request, std::to_string(response.status) + " " + cutText(message, kMaxLoggedMessageBytes));
  });

  server.set_exception_handler([](const httplib::Request&, httplib::Response& response, std::exception_ptr exception) {
    std::string what = "unknown exception";
    try {
      std::rethrow_exception(exception);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    replyError(response, 500, "internal error: " + what);  // logged by the error handler
  });
}

LocalizationServer::~LocalizationServer() { stop(); }

int LocalizationServer::bind() {
  if (bound_port_ >= 0) return bound_port_;
  httplib::Server& server = http_->server;
  if (options_.port == 0) {
    bound_port_ = server.bind_to_any_port(options_.host);
  } else if (server.bind_to_port(options_.host, options_.port)) {
    bound_port_ = options_.port;
  }
  if (bound_port_ < 0) {
    throw InputError("host " + options_.host + ", port " + std::to_string(options_.port) +
                     ": cannot listen there (address in use, not an address of this machine, or a privileged port)");
  }
  return bound_port_;
}

// The HTTP library's stop() does nothing before its listen loop has started, so stop() and serve()
// meet through two flags: whichever runs second sees the other's.
void LocalizationServer::serve() {
  bind();
  serving_ = true;
  const bool listened = !stop_requested_ && http_->server.listen_after_bind();
  serving_ = false;
  if (!listened && !stop_requested_)
    throw std::runtime_error("serve: the socket on port " + std::to_string(bound_port_) + " failed while listening");
}

void LocalizationServer::stop() {
  stop_requested_ = true;
  http_->turns.stop();
  while (serving_ && !http_->server.is_running()) std::this_thread::yield();
  http_->server.stop();
}

}  // namespace ffloc
