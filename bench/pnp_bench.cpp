// PnP solvers on real geometry: 7-Scenes redkitchen query frames through the oracle-depth
// source (the query's own depth and ground-truth pose), 1 px pixel noise, a share of the 3D
// points replaced at random (first argument, percent) and Gaussian noise on the others (second
// argument, millimetres), which mimics a coordinate regressor's error. Reports time per
// estimate and accuracy counters.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <map>

#include "ffloc/data/dataset.h"
#include "ffloc/eval/metrics.h"
#include "ffloc/eval/oracle_depth_source.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {
namespace {

constexpr size_t kQueryFrames = 20;

struct Query {
  Pose camera_to_world;
  Intrinsics camera;
  Correspondences correspondences;
};

std::filesystem::path datasetDir() {
  const char* env = std::getenv("FFLOC_SHARED_DIR");
  const std::filesystem::path shared = env && *env ? env : FFLOC_SHARED_DIR_DEFAULT;
  return shared / "data" / "7scenes_redkitchen";
}

std::vector<Query> loadQueries(int outlier_percent, int noise_mm) {
  if (!std::filesystem::exists(datasetDir())) return {};
  const Scene scene = loadDataset(datasetDir());
  OracleDepthOptions oracle;
  oracle.pixel_noise_px = 1.0;
  oracle.outlier_fraction = 0.01 * outlier_percent;
  oracle.point_noise = 0.001 * noise_mm;
  oracle.seed = 2024;
  OracleDepthSource source(oracle);
  const std::vector<size_t> all = scene.queryIndices();
  std::vector<Query> queries;
  for (size_t k = 0; k < kQueryFrames && k < all.size(); ++k) {
    const size_t index = all[k * all.size() / kQueryFrames];
    const Frame& frame = scene.frames[index];
    queries.push_back({frame.camera_to_world, frame.intrinsics.undistorted(), source.correspondences(scene, index)});
  }
  return queries;
}

const std::vector<Query>& queries(int outlier_percent, int noise_mm) {
  static std::map<std::pair<int, int>, std::vector<Query>> loaded;
  const std::pair<int, int> key(outlier_percent, noise_mm);
  auto it = loaded.find(key);
  if (it == loaded.end()) it = loaded.emplace(key, loadQueries(outlier_percent, noise_mm)).first;
  return it->second;
}

void BM_Pnp(benchmark::State& state, PnpSolver solver) {
  const std::vector<Query>& frames = queries(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  if (frames.empty()) {
    state.SkipWithError(("7scenes_redkitchen not found under " + datasetDir().string()).c_str());
    return;
  }
  PnpOptions options;
  options.solver = solver;
  std::vector<FrameResult> results;
  size_t run = 0;
  for (auto _ : state) {
    const Query& q = frames[run % frames.size()];
    options.seed = run++;
    const PnpResult pose = estimatePose(q.correspondences, q.camera, options);
    benchmark::DoNotOptimize(pose);
    FrameResult r;
    r.status = pose.status;
    r.inliers = pose.inliers;
    r.translation_error = pose.ok() ? translationError(pose.camera_to_world, q.camera_to_world) : 0;
    r.rotation_error_deg = pose.ok() ? rotationErrorDeg(pose.camera_to_world, q.camera_to_world) : 0;
    results.push_back(r);
  }
  const MethodSummary s = summarize(results);
  state.counters["median_t_cm"] = 100.0 * s.median_translation;
  state.counters["median_r_deg"] = s.median_rotation_deg;
  state.counters["pct_5cm5deg"] = s.accuracy_percent[0];
  state.counters["failures"] = s.failed;
}

// {outlier %, 3D noise mm}: the foundation issue's case, a stress case, regression-like noise.
void cases(benchmark::internal::Benchmark* b) {
  b->ArgNames({"outlier_pct", "noise_mm"})->Args({30, 0})->Args({70, 0})->Args({30, 20});
  b->Unit(benchmark::kMillisecond)->Iterations(5 * kQueryFrames);
}
BENCHMARK_CAPTURE(BM_Pnp, lo_ransac, PnpSolver::kLoRansac)->Apply(cases);
BENCHMARK_CAPTURE(BM_Pnp, opencv_usac, PnpSolver::kOpenCvUsac)->Apply(cases);

}  // namespace
}  // namespace ffloc

BENCHMARK_MAIN();
