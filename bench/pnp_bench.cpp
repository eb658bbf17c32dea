// PnP solvers on real geometry: 7-Scenes redkitchen query frames, 5000 pairs per frame from
// the ground-truth depth and pose, 1 px pixel noise, a share of the world points (first
// benchmark argument, percent) replaced by random points in the frame's box, and optionally
// Gaussian noise on the other world points (second argument, millimetres), which mimics the
// error of regressed scene coordinates. Reports time per estimate and accuracy counters.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "ffloc/pose/pnp.h"

namespace ffloc {
namespace {

constexpr int kQueryFrames = 20;
constexpr int kFirstQueryFrame = 600;  // split_query.txt: frames 600-996
constexpr int kFrameStep = 20;
constexpr int kPairsPerFrame = 5000;
constexpr double kPixelNoise = 1.0;

struct Query {
  Pose camera_to_world;
  Correspondences correspondences;
};

Intrinsics redkitchenCamera() {
  Intrinsics camera;
  camera.fx = camera.fy = 585;
  camera.cx = 320;
  camera.cy = 240;
  camera.width = 640;
  camera.height = 480;
  return camera;
}

std::filesystem::path datasetDir() {
  const char* env = std::getenv("FFLOC_SHARED_DIR");
  const std::filesystem::path shared = env && *env ? env : FFLOC_SHARED_DIR_DEFAULT;
  return shared / "data" / "7scenes_redkitchen";
}

bool readPose(const std::filesystem::path& path, Pose* pose) {
  std::ifstream in(path);
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      if (!(in >> T(r, c))) return false;
  *pose = Pose::fromMatrix(T);
  return true;
}

std::vector<Query> loadQueries(double outlier_fraction, double world_noise) {
  const Intrinsics camera = redkitchenCamera();
  std::vector<Query> queries;
  std::mt19937_64 rng(2024);
  for (int f = 0; f < kQueryFrames; ++f) {
    char stem[32];
    std::snprintf(stem, sizeof(stem), "frame-%06d", kFirstQueryFrame + f * kFrameStep);
    const std::filesystem::path dir = datasetDir();
    Query q;
    const cv::Mat depth = cv::imread((dir / (std::string(stem) + ".depth.png")).string(), cv::IMREAD_ANYDEPTH);
    if (depth.empty() || depth.type() != CV_16UC1 || !readPose(dir / (std::string(stem) + ".pose.txt"), &q.camera_to_world))
      return {};
    std::vector<Eigen::Vector2i> valid;
    for (int v = 0; v < depth.rows; ++v)
      for (int u = 0; u < depth.cols; ++u) {
        const uint16_t d = depth.at<uint16_t>(v, u);
        if (d != 0 && d != 65535) valid.emplace_back(u, v);
      }
    if (valid.size() < static_cast<size_t>(kPairsPerFrame)) return {};
    std::shuffle(valid.begin(), valid.end(), rng);
    std::normal_distribution<double> noise(0, kPixelNoise), point_noise(0, 1);
    std::uniform_real_distribution<double> unit(0, 1);
    for (int i = 0; i < kPairsPerFrame; ++i) {
      const Eigen::Vector2d pixel = valid[i].cast<double>();
      const double z = 0.001 * depth.at<uint16_t>(valid[i].y(), valid[i].x());
      q.correspondences.add(pixel + Eigen::Vector2d(noise(rng), noise(rng)),
                            q.camera_to_world * camera.backproject(pixel, z), 2.0f);
    }
    Eigen::Vector3d low = q.correspondences.points[0], high = low;
    for (const Eigen::Vector3d& p : q.correspondences.points) {
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
    for (Eigen::Vector3d& p : q.correspondences.points) {
      if (unit(rng) < outlier_fraction)
        p = low + (high - low).cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
      else
        p += world_noise * Eigen::Vector3d(point_noise(rng), point_noise(rng), point_noise(rng));
    }
    queries.push_back(std::move(q));
  }
  return queries;
}

const std::vector<Query>& queries(int outlier_percent, int world_noise_mm) {
  static std::map<std::pair<int, int>, std::vector<Query>> loaded;
  const std::pair<int, int> key(outlier_percent, world_noise_mm);
  auto it = loaded.find(key);
  if (it == loaded.end()) it = loaded.emplace(key, loadQueries(0.01 * outlier_percent, 0.001 * world_noise_mm)).first;
  return it->second;
}

double median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void BM_Pnp(benchmark::State& state, PnpSolver solver) {
  const std::vector<Query>& frames = queries(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  if (frames.empty()) {
    state.SkipWithError(("7scenes_redkitchen not found under " + datasetDir().string()).c_str());
    return;
  }
  PnpOptions options;
  options.solver = solver;
  std::vector<double> translation_cm, rotation_deg;
  int within = 0, failures = 0, inliers = 0;
  size_t run = 0;
  for (auto _ : state) {
    const Query& q = frames[run % frames.size()];
    options.seed = run++;
    const PnpResult result = estimatePose(q.correspondences, redkitchenCamera(), options);
    benchmark::DoNotOptimize(result);
    if (!result.ok()) {
      ++failures;
      translation_cm.push_back(1e9);
      rotation_deg.push_back(180);
      continue;
    }
    const double t = 100.0 * translationError(result.camera_to_world, q.camera_to_world);
    const double r = rotationErrorDeg(result.camera_to_world, q.camera_to_world);
    translation_cm.push_back(t);
    rotation_deg.push_back(r);
    if (t < 5.0 && r < 5.0) ++within;
    inliers += result.inliers;
  }
  state.counters["median_t_cm"] = median(translation_cm);
  state.counters["median_r_deg"] = median(rotation_deg);
  state.counters["max_t_cm"] = *std::max_element(translation_cm.begin(), translation_cm.end());
  state.counters["pct_5cm5deg"] = 100.0 * within / static_cast<double>(run);
  state.counters["failures"] = failures;
  state.counters["mean_inliers"] = inliers / static_cast<double>(std::max<size_t>(run - failures, 1));
}

// {outlier %, world noise mm}: the brief's case, a stress case, regression-like noise.
void cases(benchmark::internal::Benchmark* b) {
  b->ArgNames({"outlier_pct", "noise_mm"})->Args({30, 0})->Args({70, 0})->Args({30, 20});
  b->Unit(benchmark::kMillisecond)->Iterations(5 * kQueryFrames);
}
BENCHMARK_CAPTURE(BM_Pnp, lo_ransac, PnpSolver::kLoRansac)->Apply(cases);
BENCHMARK_CAPTURE(BM_Pnp, opencv_usac, PnpSolver::kOpenCvUsac)->Apply(cases);

}  // namespace
}  // namespace ffloc

BENCHMARK_MAIN();
