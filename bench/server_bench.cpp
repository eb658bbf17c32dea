// What the HTTP server adds to a query: decoding the request and the round trip over loopback,
// against the same localisation called directly (a random tiny model keeps the network's share
// small, so the overhead shows).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "ffloc/synthetic/synthetic.h"
#include "ffloc/io/image.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/fastforward_localizer.h"
#include "ffloc/pipeline/mapper.h"
#include "ffloc/server/localization_server.h"
#include "ffloc/server/localize_request.h"

// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace {

namespace fs = std::filesystem;
using namespace ffloc;

std::string encodedTexture(int width, int height, const std::string& extension) {
  cv::Mat noise(height / 8, width / 8, CV_8UC3);
  cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::Mat image;
  cv::resize(noise, image, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);
  std::vector<uchar> bytes;
  cv::imencode(extension, image, bytes);
  return std::string(bytes.begin(), bytes.end());
}

void BM_ParseRequest(benchmark::State& state, const std::string& extension) {
  const int width = static_cast<int>(state.range(0)), height = width * 3 / 4;
  const std::string bytes = encodedTexture(width, height, extension);
  const std::map<std::string, std::string> fields = {
      {"fx", "500"}, {"fy", "500"}, {"cx", std::to_string(width / 2)}, {"cy", std::to_string(height / 2)}};
  for (auto _ : state) benchmark::DoNotOptimize(parseLocalizeRequest(fields, bytes, LocalizeOptions{}));
  state.SetLabel(std::to_string(width) + "x" + std::to_string(height) + extension + ", " +
                 std::to_string(bytes.size() / 1024) + " KiB");
}
BENCHMARK_CAPTURE(BM_ParseRequest, jpeg, std::string(".jpg"))->Arg(640)->Arg(1280)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ParseRequest, png, std::string(".png"))->Arg(640)->Arg(1280)->Unit(benchmark::kMillisecond);

// A served synthetic scene (6 mapping images, 256x192) with the random tiny model.
struct ServedScene {
  fs::path dir = fs::temp_directory_path() / "ffloc_server_bench";
  Scene scene;
  LoadedModel model;
  std::shared_ptr<Localizer> localizer;
  std::unique_ptr<MapCatalog> catalog;
  std::unique_ptr<LocalizationServer> server;
  std::thread serving;
  int port = 0;
  LocalizeOptions options;
  const Frame* query = nullptr;
  std::string query_bytes;

  ServedScene() {
    setTorchThreadCount(1);
    fs::remove_all(dir);
    SyntheticOptions synthetic;
    synthetic.seed = 5;
    synthetic.mapping_frames = 6;
    synthetic.query_frames = 1;
    scene = generateSyntheticScene(synthetic, dir);
    model = loadModel("random:tiny:3");
    MappingOptions mapping;
    mapping.quiet = true;
    mapping.long_side = 256;
    MapFile map = emptyMap(model, true);
    addToMap(map, model, scene, {0, 1, 2, 3, 4, 5}, mapping);
    localizer = std::make_shared<FastForwardLocalizer>(*model.model, std::move(map));
    catalog = std::make_unique<MapCatalog>("scene", ServedMap{localizer, "random tiny"});
    options.top_k = 4;
    options.num_features = 300;
    options.long_side = 256;
    ServerOptions server_options;
    server_options.port = 0;
    server_options.localize = options;
    server = std::make_unique<LocalizationServer>(*catalog, server_options);
    port = server->bind();
    serving = std::thread([this] { server->serve(); });
    query = &scene.frames.back();
    std::ifstream file(query->image_path, std::ios::binary);
    query_bytes.assign(std::istreambuf_iterator<char>(file), {});
  }
  ~ServedScene() {
    server->stop();
    serving.join();
    fs::remove_all(dir);
  }
  std::string localizePath() const {
    const Intrinsics& k = query->intrinsics;
    return "/localize?fx=" + std::to_string(k.fx) + "&fy=" + std::to_string(k.fy) + "&cx=" + std::to_string(k.cx) +
           "&cy=" + std::to_string(k.cy);
  }
};

ServedScene& servedScene() {
  static ServedScene scene;
  return scene;
}

void BM_HealthRoundTrip(benchmark::State& state) {
  httplib::Client client("127.0.0.1", servedScene().port);
  client.set_keep_alive(true);
  client.set_tcp_nodelay(true);
  for (auto _ : state) {
    const auto reply = client.Get("/health");
    if (!reply || reply->status != 200) state.SkipWithError("GET /health failed");
  }
}
BENCHMARK(BM_HealthRoundTrip)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_LocalizeDirect(benchmark::State& state) {
  ServedScene& served = servedScene();
  for (auto _ : state) {
    benchmark::DoNotOptimize(served.localizer->localize(readImageRgb(served.query->image_path),
                                                        served.query->intrinsics, "q", served.options));
  }
}
BENCHMARK(BM_LocalizeDirect)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LocalizeOverHttp(benchmark::State& state) {
  ServedScene& served = servedScene();
  httplib::Client client("127.0.0.1", served.port);
  client.set_keep_alive(true);
  client.set_tcp_nodelay(true);
  client.set_read_timeout(300);
  const std::string path = served.localizePath();
  for (auto _ : state) {
    const auto reply = client.Post(path.c_str(), served.query_bytes, "image/png");
    if (!reply || reply->status != 200) state.SkipWithError("POST /localize failed");
  }
}
BENCHMARK(BM_LocalizeOverHttp)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
