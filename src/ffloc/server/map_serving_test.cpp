// A server of several maps from files: API keys (401, 403), maps replaced on disk while
// requests run, and a stop while queries are in flight.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>
#include <tuple>
#include <nlohmann/json.hpp>

#include "ffloc/classical/classical_localizer.h"
#include "ffloc/classical/classical_mapper.h"
#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/server/api_keys.h"
#include "ffloc/server/testing/raw_exchange.h"
#include "ffloc/server/localization_server.h"
#include "ffloc/synthetic/synthetic.h"
// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace ffloc {
namespace {

namespace fs = std::filesystem;

const std::string kKitchenKey = "kitchen-only-0123456789";
const std::string kEveryMapKey = "every-map-abcdefghijklmn";

std::string errorOf(const std::function<void()>& run) {
  try {
    run();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

class MapServing : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(testing::makeTempDir("ffloc_map_serving"));
    SyntheticOptions synthetic;
    synthetic.seed = 8;
    synthetic.mapping_frames = 8;
    synthetic.query_frames = 1;
    scene_ = new Scene(generateSyntheticScene(synthetic, *dir_ / "scene"));
    writeMap(*dir_ / "kitchen.ffmap", 4);
    writeMap(*dir_ / "office.ffmap", 6);
    std::ofstream(*dir_ / "keys.txt") << "# who may use what\n"
                                      << kKitchenKey << " kitchen\n\n"
                                      << kEveryMapKey << " *\n";
  }
  static void TearDownTestSuite() {
    delete scene_;
    fs::remove_all(*dir_);
    delete dir_;
  }

  // A classical map of the scene's first `images` mapping frames, written as `ffloc map` writes.
  static void writeMap(const fs::path& path, size_t images) {
    ClassicalMappingOptions mapping;
    mapping.quiet = true;
    ClassicalMap map = emptyClassicalMap(true, mapping);
    std::vector<size_t> frames = scene_->mappingIndices();
    frames.resize(images);
    addToClassicalMap(map, *scene_, frames, mapping);
    writeClassicalMap(map, path);
  }

  static ServedMap openClassical(const fs::path& path) {
    return {std::make_shared<const ClassicalLocalizer>(readClassicalMap(path)), "none"};
  }

  void SetUp() override {
    catalog_ = std::make_unique<MapCatalog>(
        std::vector<MapCatalog::Source>{{"kitchen", *dir_ / "kitchen.ffmap"}, {"office", *dir_ / "office.ffmap"}},
        openClassical, std::chrono::milliseconds(0));
    catalog_->setLog([this](const std::string& line) {
      const std::lock_guard<std::mutex> lock(catalog_log_mutex_);
      catalog_log_ << line << "\n";
    });
    ServerOptions options;
    options.port = 0;
    options.max_waiting_queries = 8;
    options.keys = ApiKeys::read(*dir_ / "keys.txt", catalog_->names());
    options.log = &log_;
    server_ = std::make_unique<LocalizationServer>(*catalog_, options);
    port_ = server_->bind();
    serving_ = std::thread([this] { server_->serve(); });
  }

  void TearDown() override {
    server_->stop();
    serving_.join();
  }

  httplib::Client client(const std::string& key = "") const {
    httplib::Client client("127.0.0.1", port_);
    client.set_read_timeout(60);
    if (!key.empty()) client.set_bearer_token_auth(key.c_str());
    return client;
  }

  const Frame& query() const {
    for (const Frame& frame : scene_->frames)
      if (frame.split == Split::kQuery) return frame;
    throw std::logic_error("no query");
  }

  std::string localizePath(const std::string& map) const {
    const Intrinsics& k = query().intrinsics;
    char text[200];
    std::snprintf(text, sizeof(text), "/maps/%s/localize?fx=%.17g&fy=%.17g&cx=%.17g&cy=%.17g", map.c_str(), k.fx, k.fy,
                  k.cx, k.cy);
    return text;
  }

  std::string queryBytes() const {
    std::ifstream file(query().image_path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(file), {});
  }

  static nlohmann::json body(const httplib::Result& result) { return nlohmann::json::parse(result->body); }

  std::string catalogLog() {
    const std::lock_guard<std::mutex> lock(catalog_log_mutex_);
    return catalog_log_.str();
  }

  static inline fs::path* dir_ = nullptr;
  static inline Scene* scene_ = nullptr;
  std::unique_ptr<MapCatalog> catalog_;
  std::unique_ptr<LocalizationServer> server_;
  std::ostringstream log_;
  std::mutex catalog_log_mutex_;
  std::ostringstream catalog_log_;  // reloads, written from request threads
  int port_ = 0;
  std::thread serving_;
};

TEST_F(MapServing, KeysDecideWhoUsesWhichMap) {
  const auto health = client().Get("/health");  // open to load balancers
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  EXPECT_EQ(body(health)["queries_in_flight"], 0) << health->body;
  EXPECT_EQ(client().Get("/maps")->status, 401);
  EXPECT_EQ(client().Get("/maps")->get_header_value("WWW-Authenticate"), "Bearer");  // as HTTP requires
  EXPECT_EQ(client("not-a-key-of-this-server").Get("/maps")->status, 401);
  EXPECT_EQ(client().Post(localizePath("kitchen").c_str(), "x", "image/png")->get_header_value("WWW-Authenticate"), "Bearer");

  const auto kitchen_only = client(kKitchenKey).Get("/maps");
  ASSERT_EQ(kitchen_only->status, 200);
  ASSERT_EQ(body(kitchen_only)["maps"].size(), 1u);
  EXPECT_EQ(body(kitchen_only)["maps"][0]["name"], "kitchen");
  EXPECT_EQ(body(kitchen_only)["maps"][0]["images"], 4);
  const auto every_map = client(kEveryMapKey).Get("/maps");
  ASSERT_EQ(body(every_map)["maps"].size(), 2u);
  EXPECT_EQ(body(every_map)["maps"][1]["images"], 6);

  const auto forbidden = client(kKitchenKey).Post(localizePath("office").c_str(), queryBytes(), "image/png");
  ASSERT_TRUE(forbidden);
  EXPECT_EQ(forbidden->status, 403);
  EXPECT_NE(body(forbidden)["error"].get<std::string>().find("office"), std::string::npos);
  EXPECT_EQ(client().Post(localizePath("kitchen").c_str(), queryBytes(), "image/png")->status, 401);
  const auto allowed = client(kKitchenKey).Post(localizePath("kitchen").c_str(), queryBytes(), "image/png");
  ASSERT_TRUE(allowed);
  EXPECT_EQ(allowed->status, 200) << allowed->body;
  EXPECT_EQ(body(allowed)["method"], "classical");
  EXPECT_EQ(client(kEveryMapKey).Post(localizePath("office").c_str(), queryBytes(), "image/png")->status, 200);
  EXPECT_EQ(client(kEveryMapKey).Get("/maps/attic")->status, 404);
  // Two keys in one request: the first decided (an outside probe), and a proxy may read the other.
  const httplib::Headers two_keys = {{"Authorization", std::string("Bearer ") + kKitchenKey},
                                     {"Authorization", std::string("Bearer ") + kEveryMapKey}};
  for (const char* path : {"/maps", "/maps/office"}) {
    const auto twice = client().Get(path, two_keys);
    ASSERT_TRUE(twice);
    EXPECT_EQ(twice->status, 400) << path;
    EXPECT_EQ(body(twice)["error"], "Authorization: given more than once") << path;
  }

  // With two maps the single-map routes do not guess which one.
  const auto ambiguous = client(kEveryMapKey).Get("/map");
  EXPECT_EQ(ambiguous->status, 404);
  EXPECT_NE(body(ambiguous)["error"].get<std::string>().find("2 maps"), std::string::npos);

  // Keys never reach the log.
  EXPECT_EQ(log_.str().find(kKitchenKey), std::string::npos);
  EXPECT_EQ(log_.str().find(kEveryMapKey), std::string::npos);
  EXPECT_NE(log_.str().find("403"), std::string::npos);
}

// The key, the map and the permission are known from the headers: twenty clients without a key
// uploading 30 MB each took 750 MiB before their 401s (found by an outside probe). Refused now
// before the body, which the client need not send.
TEST_F(MapServing, AccessIsRefusedBeforeTheBodyArrives) {
  const auto headersOnly = [&](const std::string& path, const std::string& key) {
    return testing::rawExchange(port_,
                                "POST " + path + " HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\n" +
                                    (key.empty() ? "" : "Authorization: Bearer " + key + "\r\n") +
                                    "Content-Length: 30000000\r\n\r\n",
                                    10);
  };
  for (const auto& [path, key, status] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {localizePath("kitchen"), "", "401"},
           {localizePath("office"), kKitchenKey, "403"},
           {localizePath("attic"), kEveryMapKey, "404"},
           {"/localize", kEveryMapKey, "404"}}) {
    const std::string answer = headersOnly(path, key);
    EXPECT_EQ(answer.rfind("HTTP/1.1 " + status, 0), 0u) << path << ": " << answer;
    EXPECT_NE(answer.find("Connection: close"), std::string::npos) << answer;
  }
}

// With the image as the body, every field is in the URL: a missing or malformed field, or one
// the map's method does not use, was refused only once a 30 MB body had been read. Refused now
// from the headers; a form may carry its fields in the body, so it is read first.
TEST_F(MapServing, FieldsInTheUrlAreCheckedBeforeTheBodyArrives) {
  const Intrinsics& k = query().intrinsics;
  const std::string intrinsics = "fx=" + std::to_string(k.fx) + "&fy=" + std::to_string(k.fy) +
                                 "&cx=" + std::to_string(k.cx) + "&cy=" + std::to_string(k.cy);
  const auto headersOnly = [&](const std::string& target, const std::string& type) {
    return testing::rawExchange(port_,
                                "POST " + target + " HTTP/1.1\r\nHost: x\r\nContent-Type: " + type +
                                    "\r\nAuthorization: Bearer " + kEveryMapKey +
                                    "\r\nContent-Length: 30000000\r\n\r\n",
                                10);
  };
  for (const auto& [query_text, error] : std::vector<std::pair<std::string, std::string>>{
           {"fy=1&cx=1&cy=1", "fx: missing"},
           {"fx=abc&fy=1&cx=1&cy=1", "fx: "},
           {intrinsics + "&top_k=0", "top_k: "},
           {intrinsics + "&features=500", "features: the map is a classical map, which does not use it"},
           {intrinsics + "&colour=red", "colour: unknown field"}}) {
    const std::string answer = headersOnly("/maps/kitchen/localize?" + query_text, "image/png");
    EXPECT_EQ(answer.rfind("HTTP/1.1 400", 0), 0u) << query_text << ": " << answer;
    EXPECT_NE(answer.find("{\"error\":\"" + error), std::string::npos) << query_text << ": " << answer;
    EXPECT_NE(answer.find("Connection: close"), std::string::npos) << answer;
  }
  // Fields that pass wait for the body, as does a form whatever its URL says: the client's 2 s
  // pass with no answer.
  for (const auto& [query_text, type] : std::vector<std::pair<std::string, std::string>>{
           {intrinsics, "image/png"}, {"", "multipart/form-data; boundary=xyz"}}) {
    const std::string answer = testing::rawExchange(
        port_,
        "POST /maps/kitchen/localize?" + query_text + " HTTP/1.1\r\nHost: x\r\nContent-Type: " + type +
            "\r\nAuthorization: Bearer " + kEveryMapKey + "\r\nContent-Length: 30000000\r\n\r\n",
        2);
    EXPECT_EQ(answer, "") << type;
  }
  // And answer as before once it comes.
  const auto answer = client(kEveryMapKey).Post(localizePath("kitchen").c_str(), queryBytes(), "image/png");
  ASSERT_TRUE(answer);
  EXPECT_EQ(answer->status, 200) << answer->body;
}

TEST_F(MapServing, AMapReplacedOnDiskIsServedWithoutARestartAndNoRequestFails) {
  std::atomic<bool> done{false};
  std::atomic<int> answered{0};
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::thread load([&] {
    httplib::Client http = client(kEveryMapKey);
    while (!done) {
      const auto answer = http.Post(localizePath("kitchen").c_str(), queryBytes(), "image/png");
      if (!answer || answer->status != 200) {
        const std::lock_guard<std::mutex> lock(failures_mutex);
        failures.push_back(answer ? std::to_string(answer->status) + " " + answer->body : "no answer");
      }
      ++answered;
    }
  });
  while (answered < 2) std::this_thread::sleep_for(std::chrono::milliseconds(5));

  // As `ffloc map` replaces a map: written beside it, then renamed over it.
  writeMap(*dir_ / "kitchen.next.ffmap", 7);
  fs::rename(*dir_ / "kitchen.next.ffmap", *dir_ / "kitchen.ffmap");
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  int images = 0;
  while (images != 7 && std::chrono::steady_clock::now() < deadline) {
    images = body(client(kEveryMapKey).Get("/maps/kitchen"))["images"].get<int>();
  }
  const int before = answered;
  while (answered < before + 2) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  done = true;
  load.join();
  EXPECT_EQ(images, 7);
  EXPECT_TRUE(failures.empty()) << failures.size() << " failed, first: " << failures.front();
  EXPECT_NE(catalogLog().find("reloaded"), std::string::npos);

  // A broken replacement leaves the previous map serving.
  std::ofstream(*dir_ / "kitchen.broken", std::ios::binary) << "not a map";
  fs::rename(*dir_ / "kitchen.broken", *dir_ / "kitchen.ffmap");
  EXPECT_EQ(client(kEveryMapKey).Post(localizePath("kitchen").c_str(), queryBytes(), "image/png")->status, 200);
  EXPECT_EQ(body(client(kEveryMapKey).Get("/maps/kitchen"))["images"], 7);
  EXPECT_NE(catalogLog().find("does not open"), std::string::npos);
  writeMap(*dir_ / "kitchen.ffmap", 4);
}

// A file written over in place (`cp` over it: the same inode) that does not open leaves the
// version the server opened serving, as a broken replacement by rename does: the maps a server
// holds are its own copies (readMapFile's snapshot; a FastForward map read through the file's
// mapping ended the server with SIGBUS once the file was cut short). Served again from the file
// once it opens.
TEST_F(MapServing, AMapWrittenOverInPlaceThatDoesNotOpenKeepsTheServedVersion) {
  ASSERT_EQ(client(kEveryMapKey).Post(localizePath("kitchen").c_str(), queryBytes(), "image/png")->status, 200);
  std::ofstream(*dir_ / "kitchen.ffmap", std::ios::binary | std::ios::trunc) << "cut short";
  EXPECT_EQ(client(kEveryMapKey).Post(localizePath("kitchen").c_str(), queryBytes(), "image/png")->status, 200);
  EXPECT_EQ(body(client(kEveryMapKey).Get("/maps/kitchen"))["images"], 4);
  EXPECT_EQ(body(client().Get("/health"))["status"], "ok");
  EXPECT_NE(catalogLog().find("the changed file does not open, still serving the previous one"), std::string::npos);

  writeMap(*dir_ / "kitchen.next.ffmap", 5);
  fs::copy_file(*dir_ / "kitchen.next.ffmap", *dir_ / "kitchen.ffmap", fs::copy_options::overwrite_existing);
  fs::remove(*dir_ / "kitchen.next.ffmap");
  EXPECT_EQ(client(kEveryMapKey).Post(localizePath("kitchen").c_str(), queryBytes(), "image/png")->status, 200);
  EXPECT_EQ(body(client(kEveryMapKey).Get("/maps/kitchen"))["images"], 5);
  writeMap(*dir_ / "kitchen.ffmap", 4);
}

// Under load (the full suite beside other work) the stop came 150 ms after the clients started
// and before the server had accepted any: the kernel had completed their connections, closing
// the listening socket reset them, and the test blamed the server. The stop now waits until every
// client's query is admitted or answered, so each must be answered.
TEST_F(MapServing, StopAnswersEveryAcceptedQuery) {
  constexpr int kClients = 6;
  std::vector<httplib::Error> errors(kClients, httplib::Error::Unknown);
  std::vector<int> statuses(kClients, 0);
  std::atomic<int> finished{0};
  std::vector<std::thread> clients;
  for (int i = 0; i < kClients; ++i) {
    clients.emplace_back([&, i] {
      const auto answer = client(kEveryMapKey).Post(localizePath("office").c_str(), queryBytes(), "image/png");
      errors[static_cast<size_t>(i)] = answer.error();
      if (answer) statuses[static_cast<size_t>(i)] = answer->status;
      ++finished;
    });
  }
  // Queries take tens of milliseconds one at a time: stop while one runs and others wait.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (server_->queriesInFlight() + static_cast<size_t>(finished.load()) < kClients &&
         std::chrono::steady_clock::now() < give_up)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const size_t in_flight = server_->queriesInFlight();
  server_->stop();
  for (std::thread& thread : clients) thread.join();
  for (int i = 0; i < kClients; ++i) {
    const size_t c = static_cast<size_t>(i);
    EXPECT_EQ(errors[c], httplib::Error::Success) << "client " << i << ": " << httplib::to_string(errors[c]);
    EXPECT_TRUE(statuses[c] == 200 || statuses[c] == 503) << "client " << i << ": " << statuses[c];
  }
  EXPECT_GE(in_flight, 1u) << "every query was answered before the stop: nothing was left to answer at it";
}

TEST(ApiKeys, FileErrorsNameTheLine) {
  const fs::path dir = testing::makeTempDir("ffloc_keys");
  const auto errorFor = [&](const std::string& text) {
    std::ofstream(dir / "keys.txt", std::ios::trunc) << text;
    return errorOf([&] { ApiKeys::read(dir / "keys.txt", {"kitchen", "office"}); });
  };
  EXPECT_NE(errorFor("short kitchen\n").find("keys.txt:1"), std::string::npos);
  EXPECT_NE(errorFor("short kitchen\n").find("shorter than 16"), std::string::npos);
  EXPECT_NE(errorFor("# c\n0123456789abcdef attic\n").find("keys.txt:2"), std::string::npos);
  EXPECT_NE(errorFor("0123456789abcdef attic\n").find("'attic'"), std::string::npos);
  EXPECT_NE(errorFor("0123456789abcdef *\n0123456789abcdef kitchen\n").find("given twice"), std::string::npos);
  EXPECT_NE(errorFor("0123456789abcdef\n").find("expected"), std::string::npos);
  EXPECT_NE(errorFor("\n# nothing\n").find("holds no key"), std::string::npos);
  EXPECT_NE(errorFor("0123456789abcd\x01f kitchen\n").find("only printable ASCII"), std::string::npos);
  EXPECT_NE(errorFor("0123456789abcdef kitchen,\n").find("an empty map name"), std::string::npos);
  EXPECT_NE(errorFor("0123456789abcdef kitchen office\n").find("expected"), std::string::npos);
  // A comment after the maps was refused though the docs allowed it (an outside probe).
  std::ofstream(dir / "keys.txt", std::ios::trunc) << "0123456789abcdef kitchen # the kitchen's tablet\n";
  EXPECT_EQ(ApiKeys::read(dir / "keys.txt", {"kitchen", "office"}).decide("Bearer 0123456789abcdef", "kitchen"),
            ApiKeys::Decision::kAllowed);
  // A byte order mark became part of the first key, which then never matched (second probe).
  std::ofstream(dir / "keys.txt", std::ios::trunc) << "\xEF\xBB\xBF" "0123456789abcdef kitchen\n";
  EXPECT_EQ(ApiKeys::read(dir / "keys.txt", {"kitchen", "office"}).decide("Bearer 0123456789abcdef", "kitchen"),
            ApiKeys::Decision::kAllowed);

  std::ofstream(dir / "keys.txt", std::ios::trunc) << "0123456789abcdef kitchen,office\r\n";
  const ApiKeys keys = ApiKeys::read(dir / "keys.txt", {"kitchen", "office"});
  EXPECT_EQ(keys.decide("Bearer 0123456789abcdef", "office"), ApiKeys::Decision::kAllowed);
  EXPECT_EQ(keys.decide("bearer 0123456789abcdef", "kitchen"), ApiKeys::Decision::kAllowed);
  EXPECT_EQ(keys.decide("Bearer 0123456789abcde", "kitchen"), ApiKeys::Decision::kUnauthenticated);
  EXPECT_EQ(keys.decide("Bearer 0123456789abcdefg", "kitchen"), ApiKeys::Decision::kUnauthenticated);
  EXPECT_EQ(keys.decide("0123456789abcdef", "kitchen"), ApiKeys::Decision::kUnauthenticated);
  EXPECT_EQ(keys.decide("", ""), ApiKeys::Decision::kUnauthenticated);
  fs::remove_all(dir);
}

TEST(MapCatalogSources, NamesComeFromTheFlagOrTheFileStem) {
  EXPECT_EQ(MapCatalog::parseSource("kitchen=/maps/k.ffmap").name, "kitchen");
  EXPECT_EQ(MapCatalog::parseSource("kitchen=/maps/k.ffmap").path, "/maps/k.ffmap");
  EXPECT_EQ(MapCatalog::parseSource("/maps/office.ffmap").name, "office");
  const fs::path dir = testing::makeTempDir("ffloc_catalog");
  EXPECT_NE(errorOf([&] { MapCatalog::sourcesInFolder(dir); }).find("no .ffmap"), std::string::npos);
  const auto empty = [](const fs::path&) { return ServedMap{}; };
  EXPECT_NE(errorOf([&] { MapCatalog({{"a", dir / "x.ffmap"}, {"a", dir / "y.ffmap"}}, empty); }).find("given twice"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { MapCatalog({{"a/b", dir / "x.ffmap"}}, empty); }).find("'a/b'"), std::string::npos);
  // Listed, but not reachable at /maps/NAME (an outside probe): clients rewrite '.' and '..', and
  // '%', '?' and '#' change the URL.
  for (const std::string name : {".", "..", "sp%20ace", "a?b", "a#b"}) {
    EXPECT_NE(errorOf([&] { MapCatalog({{name, dir / "x.ffmap"}}, empty); })
                  .find("map name '" + name + "' cannot be reached as /maps/NAME"),
              std::string::npos)
        << name;
  }
  fs::remove_all(dir);
}

TEST_F(MapServing, TheViewerPageIsOpenAndTheSceneNeedsAKey) {
  const auto page = client().Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_EQ(page->get_header_value("Content-Type"), "text/html");
  EXPECT_NE(page->body.find("/viewer/viewer.js"), std::string::npos);
  const auto script = client().Get("/viewer/three.module.min.js");
  ASSERT_TRUE(script);
  EXPECT_EQ(script->status, 200);
  EXPECT_GT(script->body.size(), 100000u);
  EXPECT_EQ(client().Get("/viewer/three.LICENSE")->status, 200);
  EXPECT_EQ(client().Get("/maps/kitchen/scene")->status, 401);
  EXPECT_EQ(client(kKitchenKey).Get("/maps/office/scene")->status, 403);
}

// Range is ignored: one request for 2700 overlapping ranges of the viewer's script, open without a
// key, had the library build a 1.8 GB answer in memory (an outside probe); JSON came cut short.
TEST_F(MapServing, RangesAreIgnoredAndEveryAnswerIsWhole) {
  std::string ranges = "bytes=0-";
  for (int i = 0; i < 200; ++i) ranges += ",0-";
  const auto script = client().Get("/viewer/three.module.min.js", {{"Range", ranges}});
  ASSERT_TRUE(script);
  EXPECT_EQ(script->status, 200);
  EXPECT_EQ(script->body, client().Get("/viewer/three.module.min.js")->body);
  const auto health = client().Get("/health", {{"Range", "bytes=0-5"}});
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  EXPECT_EQ(nlohmann::json::parse(health->body)["status"], "ok") << health->body;
  // One the library cannot parse was refused 416, "HTTP 416", before any route: said plainly.
  const auto garbled = client().Get("/health", {{"Range", "items=0-1"}});
  ASSERT_TRUE(garbled);
  EXPECT_EQ(garbled->status, 400);
  EXPECT_EQ(nlohmann::json::parse(garbled->body)["error"],
            "Range: 'items=0-1' is no byte range; this server sends whole answers, so send no Range header");
}

// A classical map's description listed FastForward's defaults too (an outside review).
TEST_F(MapServing, AMapsDefaultsAreThoseItsMethodReads) {
  const nlohmann::json described = body(client(kEveryMapKey).Get("/maps/kitchen"));
  ASSERT_EQ(described["method"], "classical") << described;
  EXPECT_EQ(described["defaults"], (nlohmann::json{{"top_k", ServerOptions().localize.top_k}, {"seed", 0}}))
      << described;
}

// The library's own connection headers contradicted the server's: a refusal that closes the
// connection also offered `Keep-Alive`, `Connection: close` came twice when the client had asked
// for it too, and HEAD answers offered byte ranges the server ignores.
TEST_F(MapServing, ConnectionHeadersSayWhatTheServerDoes) {
  const auto count = [](const std::string& answer, const std::string& header) {
    size_t found = 0;
    for (size_t at = answer.find(header); at != std::string::npos; at = answer.find(header, at + 1)) ++found;
    return found;
  };
  const std::string head = testing::rawExchange(port_, "HEAD / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(head.rfind("HTTP/1.1 200", 0), 0u) << head;
  EXPECT_EQ(count(head, "Accept-Ranges: none\r\n"), 1u) << head;
  EXPECT_EQ(count(head, "Accept-Ranges:"), 1u) << head;
  const std::string refused = testing::rawExchange(
      port_, "POST " + localizePath("kitchen") + " HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Length: 5\r\n\r\n");
  EXPECT_EQ(refused.rfind("HTTP/1.1 401", 0), 0u) << refused;
  EXPECT_EQ(count(refused, "Connection: close\r\n"), 1u) << refused;
  EXPECT_EQ(count(refused, "Keep-Alive:"), 0u) << refused;
  httplib::Client keeping = client();
  keeping.set_keep_alive(true);
  const auto kept = keeping.Get("/health");
  ASSERT_TRUE(kept);
  EXPECT_FALSE(kept->get_header_value("Keep-Alive").empty());
  EXPECT_EQ(kept->get_header_value("Connection"), "");
}

TEST_F(MapServing, TheSceneHoldsTheCamerasPointsAndTheLastAnswers) {
  const auto empty = client(kKitchenKey).Get("/maps/kitchen/scene");
  ASSERT_TRUE(empty);
  ASSERT_EQ(empty->status, 200) << empty->body;
  const nlohmann::json before = body(empty);
  EXPECT_EQ(before["method"], "classical");
  ASSERT_EQ(before["cameras"].size(), 4u);
  EXPECT_EQ(before["cameras"][0]["camera_to_world"].size(), 4u);
  EXPECT_GT(before["cameras"][0]["intrinsics"]["width"].get<int>(), 0);
  EXPECT_GT(before["points"].size(), 0u);
  EXPECT_EQ(before["points"].size() % 3, 0u);
  EXPECT_TRUE(before["recent"].empty());

  // More answers than kept: the oldest go, the newest is last, the other map keeps none.
  const size_t kept = ServerOptions().recent_answers;
  nlohmann::json last;
  for (size_t i = 0; i < kept + 2; ++i) {
    const auto answer = client(kKitchenKey).Post((localizePath("kitchen") + "&name=q" + std::to_string(i)).c_str(),
                                                 queryBytes(), "image/png");
    ASSERT_EQ(answer->status, 200);
    last = body(answer);
  }
  const nlohmann::json after = body(client(kKitchenKey).Get("/maps/kitchen/scene"));
  ASSERT_EQ(after["recent"].size(), kept);
  EXPECT_EQ(after["recent"].back()["answer"], last);
  EXPECT_EQ(after["recent"].front()["answer"]["name"], "q2");
  EXPECT_DOUBLE_EQ(after["recent"].back()["intrinsics"]["fx"].get<double>(), query().intrinsics.fx);
  EXPECT_TRUE(body(client(kEveryMapKey).Get("/maps/office/scene"))["recent"].empty());
}

}  // namespace
}  // namespace ffloc
