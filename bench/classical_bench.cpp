// The classical method's query path: exact descriptor matching alone (random RootSIFT-like
// descriptors of the redkitchen sizes, each product kernel), and, when ../shared is there, whole
// queries against a map of the redkitchen mapping split and the queries' SIFT alone.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>

#include "ffloc/classical/classical_localizer.h"
#include "ffloc/classical/classical_mapper.h"
#include "ffloc/classical/descriptor_matching.h"
#include "ffloc/classical/sift_features.h"
#include "ffloc/core/threads.h"
#include "ffloc/data/dataset.h"
#include "ffloc/io/image.h"

namespace ffloc {
namespace {

cv::Mat randomDescriptors(int rows, uint64_t seed) {
  cv::Mat d(rows, 128, CV_32F);
  cv::RNG rng(seed);
  rng.fill(d, cv::RNG::UNIFORM, 0.0, 1.0);
  for (int r = 0; r < rows; ++r) cv::normalize(d.row(r), d.row(r));
  return quantizeDescriptors(d);
}

// A query of 2000 descriptors against K images of 1400 (redkitchen: 2058 query keypoints, about
// 1400 with a point per mapping image), each product kernel.
void BM_ExactMatching(benchmark::State& state) {
  const int images = static_cast<int>(state.range(0));
  const cv::Mat query = randomDescriptors(2000, 1);
  std::vector<cv::Mat> targets;
  for (int i = 0; i < images; ++i) targets.push_back(randomDescriptors(1400, 10 + i));
  std::vector<const cv::Mat*> pointers;
  for (const cv::Mat& t : targets) pointers.push_back(&t);
  const ProductKernel kernel = state.range(1) ? ProductKernel::kFastest : ProductKernel::kBlas;
  if (kernel == ProductKernel::kFastest && !hasVnniProducts()) {
    state.SkipWithError("this CPU has no AVX-512 VNNI");
    return;
  }
  for (auto _ : state) benchmark::DoNotOptimize(matchExactly(query, pointers, 0.8f, kernel));
  state.counters["GFLOP/s"] = benchmark::Counter(2.0 * 2000 * 1400 * 128 * images * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_ExactMatching)->ArgNames({"images", "vnni"})->ArgsProduct({{5, 10}, {0, 1}})->Unit(benchmark::kMillisecond);

std::filesystem::path sharedDir() {
  const char* env = std::getenv("FFLOC_SHARED_DIR");
  return env ? env : FFLOC_SHARED_DIR_DEFAULT;
}

void BM_ClassicalQueryRedkitchen(benchmark::State& state) {
  const std::filesystem::path dir = sharedDir() / "data/7scenes_redkitchen";
  if (!std::filesystem::exists(dir)) {
    state.SkipWithError("../shared/data/7scenes_redkitchen not found");
    return;
  }
  static std::unique_ptr<Scene> scene;
  static std::unique_ptr<ClassicalLocalizer> localizer;
  if (!localizer) {
    scene = std::make_unique<Scene>(loadDataset(dir));
    ClassicalMappingOptions options;
    options.quiet = true;
    ClassicalMap map = emptyClassicalMap(true, options);
    addToClassicalMap(map, *scene, scene->mappingIndices(), options);
    localizer = std::make_unique<ClassicalLocalizer>(std::move(map));
  }
  const std::vector<size_t> queries = scene->queryIndices();
  size_t next = 0;
  LocalizeOptions options;
  options.top_k = static_cast<size_t>(state.range(0));
  for (auto _ : state) {
    const Frame& frame = scene->frames[queries[next++ % queries.size()]];
    benchmark::DoNotOptimize(localizer->localize(readImageRgb(frame.image_path), frame.intrinsics, frame.name, options));
  }
}
BENCHMARK(BM_ClassicalQueryRedkitchen)->Arg(5)->Arg(10)->Unit(benchmark::kMillisecond)->Iterations(40);

// The query's SIFT alone, on 1 and 2 threads: most of a classical query.
void BM_QuerySiftRedkitchen(benchmark::State& state) {
  const std::filesystem::path dir = sharedDir() / "data/7scenes_redkitchen";
  if (!std::filesystem::exists(dir)) {
    state.SkipWithError("../shared/data/7scenes_redkitchen not found");
    return;
  }
  const Scene scene = loadDataset(dir);
  setLibraryThreadCount(static_cast<int>(state.range(0)));
  const std::vector<size_t> queries = scene.queryIndices();
  std::vector<cv::Mat> images;
  for (size_t q : queries) images.push_back(readImageRgb(scene.frames[q].image_path));
  size_t next = 0, keypoints = 0;
  for (auto _ : state) {
    const size_t q = next++ % images.size();
    const SiftFeatures features = extractSiftFeatures(images[q], scene.frames[queries[q]].intrinsics, "query");
    keypoints += features.pixels.size();
  }
  state.counters["keypoints"] = static_cast<double>(keypoints) / static_cast<double>(next);
  setLibraryThreadCount(0);
}
BENCHMARK(BM_QuerySiftRedkitchen)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->Iterations(100);

}  // namespace
}  // namespace ffloc

BENCHMARK_MAIN();
