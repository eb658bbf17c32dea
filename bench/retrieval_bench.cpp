// Brute-force global-descriptor retrieval: one query ranked against M mapping descriptors with the
// localizer's topKBySimilarity (vector-of-vectors database, cosine per row), for descriptor
// lengths 2048 (the large encoder, 2 x 1024) and 384 (the small preset, 2 x 192). Reports time
// per query and the descriptor matrix's float32 size; docs/pipeline.md ("Retrieval") draws the
// line where brute force stops being fine from these numbers.
//
// `contiguous` ranks the same data stored as one column-major float32 matrix of unit-norm columns
// (scores = one matrix-vector product): a reference for how much a flat layout would gain.
//
// `thumbnailRecall` is a network-free floor for the recall that `ffloc retrieval` measures: each
// image's descriptor is its 16x12 colour thumbnail, mean removed, L2-normalised. It runs once per
// shared dataset and reports recall@K as counters (skipped when the shared data are absent).
#include <benchmark/benchmark.h>

#include <Eigen/Core>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "ffloc/data/dataset.h"
#include "ffloc/io/image.h"
#include "ffloc/retrieval/image_selection.h"
#include "ffloc/retrieval/retrieval_recall.h"

namespace {

constexpr size_t kTopK = 20;  // the outdoor preset's K

// xorshift64*: fills gigabytes of test descriptors in seconds (the values only need to differ).
struct FastRandom {
  uint64_t state;
  float symmetric() {
    state ^= state >> 12;
    state ^= state << 25;
    state ^= state >> 27;
    return static_cast<float>((state * 0x2545F4914F6CDD1DULL) >> 40) * (2.0f / 16777216.0f) - 1.0f;
  }
};

void normalize(float* values, int64_t length) {
  double norm2 = 0;
  for (int64_t i = 0; i < length; ++i) norm2 += static_cast<double>(values[i]) * values[i];
  const float inv = static_cast<float>(1.0 / std::sqrt(norm2));
  for (int64_t i = 0; i < length; ++i) values[i] *= inv;
}

std::vector<float> randomDescriptor(FastRandom& rng, int64_t length) {
  std::vector<float> out(static_cast<size_t>(length));
  for (float& v : out) v = rng.symmetric();
  normalize(out.data(), length);
  return out;
}

// One database at a time is kept across the benchmark's repeated calls: the largest is 8 GB.
template <typename Database>
struct Cache {
  int64_t count = -1, length = -1;
  std::unique_ptr<Database> database;
};

const std::vector<std::vector<float>>& rowsDatabase(int64_t count, int64_t length) {
  static Cache<std::vector<std::vector<float>>> cache;
  if (cache.count != count || cache.length != length) {
    cache.database.reset();
    FastRandom rng{0x9e3779b97f4a7c15ULL ^ static_cast<uint64_t>(count * 4099 + length)};
    auto database = std::make_unique<std::vector<std::vector<float>>>();
    database->reserve(static_cast<size_t>(count));
    for (int64_t i = 0; i < count; ++i) database->push_back(randomDescriptor(rng, length));
    cache = {count, length, std::move(database)};
  }
  return *cache.database;
}

const Eigen::MatrixXf& contiguousDatabase(int64_t count, int64_t length) {
  static Cache<Eigen::MatrixXf> cache;
  if (cache.count != count || cache.length != length) {
    cache.database.reset();
    FastRandom rng{0x9e3779b97f4a7c15ULL ^ static_cast<uint64_t>(count * 4099 + length)};
    auto database = std::make_unique<Eigen::MatrixXf>(length, count);
    for (int64_t i = 0; i < count; ++i) {
      float* column = database->col(i).data();
      for (int64_t j = 0; j < length; ++j) column[j] = rng.symmetric();
      normalize(column, length);
    }
    cache = {count, length, std::move(database)};
  }
  return *cache.database;
}

void reportSize(benchmark::State& state, int64_t count, int64_t length) {
  state.counters["matrix_GB"] = 4.0 * static_cast<double>(count) * static_cast<double>(length) / 1e9;
  state.counters["queries_per_second"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void topKBySimilarityBruteForce(benchmark::State& state) {
  const int64_t count = state.range(0), length = state.range(1);
  const auto& database = rowsDatabase(count, length);
  FastRandom rng{17};
  const std::vector<float> query = randomDescriptor(rng, length);
  for (auto _ : state) {
    const std::vector<size_t> top = ffloc::topKBySimilarity(database, query, kTopK);
    benchmark::DoNotOptimize(top.data());
  }
  reportSize(state, count, length);
}

void contiguousBruteForce(benchmark::State& state) {
  const int64_t count = state.range(0), length = state.range(1);
  const Eigen::MatrixXf& database = contiguousDatabase(count, length);
  FastRandom rng{17};
  const std::vector<float> query_values = randomDescriptor(rng, length);
  const Eigen::Map<const Eigen::VectorXf> query(query_values.data(), length);
  Eigen::VectorXf scores(count);
  std::vector<size_t> order(static_cast<size_t>(count));
  for (auto _ : state) {
    scores.noalias() = database.transpose() * query;
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + kTopK, order.end(),
                      [&](size_t a, size_t b) { return scores[a] > scores[b] || (scores[a] == scores[b] && a < b); });
    benchmark::DoNotOptimize(order.data());
  }
  reportSize(state, count, length);
}

std::vector<float> thumbnailDescriptor(const std::filesystem::path& image_path) {
  cv::Mat thumbnail;
  cv::resize(ffloc::readImageRgb(image_path), thumbnail, cv::Size(16, 12), 0, 0, cv::INTER_AREA);
  std::vector<float> out(thumbnail.ptr<uint8_t>(), thumbnail.ptr<uint8_t>() + thumbnail.total() * thumbnail.channels());
  // Without the mean, every thumbnail is close to the all-grey direction and brightness dominates.
  const float mean = std::accumulate(out.begin(), out.end(), 0.0f) / static_cast<float>(out.size());
  for (float& v : out) v -= mean;
  normalize(out.data(), static_cast<int64_t>(out.size()));
  return out;
}

void thumbnailRecall(benchmark::State& state, const std::string& dataset) {
  const char* env = std::getenv("FFLOC_SHARED_DIR");
  const std::filesystem::path dir = std::filesystem::path(env && *env ? env : FFLOC_SHARED_DIR_DEFAULT) / "data" / dataset;
  if (!std::filesystem::exists(dir)) {
    state.SkipWithError(("shared dataset " + dir.string() + " not found").c_str());
    return;
  }
  const ffloc::Scene scene = ffloc::loadDataset(dir);
  std::vector<ffloc::Pose> mapping_poses, query_poses;
  std::vector<std::vector<float>> mapping_descriptors, query_descriptors;
  for (auto _ : state) {
    mapping_poses.clear();
    query_poses.clear();
    mapping_descriptors.clear();
    query_descriptors.clear();
    for (size_t i : scene.mappingIndices()) {
      mapping_poses.push_back(scene.frames[i].camera_to_world);
      mapping_descriptors.push_back(thumbnailDescriptor(scene.frames[i].image_path));
    }
    for (size_t i : scene.queryIndices()) {
      query_poses.push_back(scene.frames[i].camera_to_world);
      query_descriptors.push_back(thumbnailDescriptor(scene.frames[i].image_path));
    }
  }
  const ffloc::RetrievalRecall result =
      ffloc::measureRetrievalRecall(mapping_poses, query_poses, mapping_descriptors, query_descriptors);
  for (const ffloc::RecallAtK& recall : result.recall)
    state.counters["recall@" + std::to_string(recall.k)] = recall.retrieval;
  state.counters["median_rank"] = result.median_rank;
  state.counters["mapping"] = static_cast<double>(mapping_poses.size());
  state.counters["queries"] = static_cast<double>(query_poses.size());
}

void databaseSizes(benchmark::internal::Benchmark* bench) {
  for (int64_t length : {2048, 384})
    for (int64_t count : {1000, 10000, 100000, 1000000}) bench->Args({count, length});
}

}  // namespace

BENCHMARK(topKBySimilarityBruteForce)->Apply(databaseSizes)->ArgNames({"M", "dim"})->Unit(benchmark::kMillisecond);
BENCHMARK(contiguousBruteForce)->Apply(databaseSizes)->ArgNames({"M", "dim"})->Unit(benchmark::kMillisecond);

// Reading the images dominates: one pass is enough.
BENCHMARK_CAPTURE(thumbnailRecall, redkitchen, "7scenes_redkitchen")->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(thumbnailRecall, stairs_sample, "7scenes_stairs_kapture_sample/stairs")
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(thumbnailRecall, fox, "instant_ngp_fox")->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(thumbnailRecall, fountain, "strecha_fountain_p11")->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(thumbnailRecall, herzjesu, "strecha_herzjesu_p8")->Iterations(1)->Unit(benchmark::kSecond);

BENCHMARK_MAIN();
