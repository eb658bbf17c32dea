#include "ffloc/classical/classical_localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"

namespace ffloc {
namespace {

using Clock = std::chrono::steady_clock;

constexpr uint8_t kMinPointViews = 2;

// SIFT rarely matches a surface seen from directions further apart than this (on the synthetic
// tuning scenes, with every query looking again: 45 degrees marked 219 queries `localized`, 60
// degrees 221).
constexpr double kMaxViewingAngleDeg = 60;

// The nearby pairs (docs/classical.md, "Nearby pairs"): matches that pass this looser ratio test
// and that the pose projects within this angle of their query keypoint, 4 px at a 540 px focal
// length. Below kMinNearbyPairRadiusPx (a focal length under 400 px) the look is not taken: SIFT's
// pixel noise fills the radius, and on the 256 x 192 tuning scenes (216 px) the pairs it kept
// close to wrong poses made them `localized`.
constexpr float kNearbyPairRatio = 0.9f;
constexpr double kNearbyPairAngle = 0.0075;
constexpr double kMinNearbyPairRadiusPx = 3;

}  // namespace

ClassicalLocalizer::ClassicalLocalizer(ClassicalMap map) : map_(std::move(map)) {
  if (map_.images.empty()) throw InputError("map: holds no images");
  for (const ClassicalMapImage& image : map_.images) {
    cameras_.push_back({image.name, image.camera_to_world, image.camera});
    globals_.push_back(image.global_descriptor);
    // Only keypoints whose point another view confirms are searched: the others cannot give a
    // correspondence worth having (on redkitchen, leaving out the unconfirmed depth points
    // changes no accuracy column by more than one query and saves 8 % of the query time), and
    // the search is 20 % (redkitchen) to 45 % (Strecha) smaller.
    cv::Mat with_points;
    std::vector<uint32_t> keypoints;
    for (size_t k = 0; k < image.keypoints.size(); ++k) {
      if (image.point_views[k] < kMinPointViews) continue;
      with_points.push_back(image.descriptors.row(static_cast<int>(k)));
      keypoints.push_back(static_cast<uint32_t>(k));
    }
    descriptors_.push_back(with_points);
    searched_keypoints_.push_back(std::move(keypoints));
  }
}

ClassicalLocalizer::~ClassicalLocalizer() = default;

std::vector<Eigen::Vector3d> ClassicalLocalizer::mapPoints(size_t max_points) const {
  size_t total = 0;
  for (const ClassicalMapImage& image : map_.images) total += image.pointCount();
  std::vector<Eigen::Vector3d> points;
  if (total == 0 || max_points == 0) return points;
  // Rounding up a max_points near 2^64 wrapped the stride to 0 (SIGFPE in Python's Map.points).
  const size_t wanted = std::min(total, max_points);
  const size_t stride = (total + wanted - 1) / wanted;
  points.reserve(wanted);
  size_t index = 0;
  for (const ClassicalMapImage& image : map_.images) {
    for (size_t k = 0; k < image.points.size(); ++k) {
      if (image.point_views[k] == 0) continue;
      if (index++ % stride == 0) points.push_back(image.points[k]);
    }
  }
  return points;
}

void ClassicalLocalizer::predict(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                                 const LocalizeOptions& options, LocalizationResult& result,
                                 std::optional<PnpResult>& /*second_estimate*/, PoseGuidedLooks& pose_guided) const {
  auto start = Clock::now();
  auto query = std::make_shared<const SiftFeatures>(extractSiftFeatures(rgb, intrinsics, name, map_.sift));
  result.camera = intrinsics.undistorted();
  result.timings.features = secondsSince(start);

  start = Clock::now();
  std::vector<size_t> ranked = rankBySimilarity(globals_, map_.vocabulary.describe(query->descriptors));
  if (ranked.size() > options.top_k) ranked.resize(options.top_k);
  result.timings.retrieval = secondsSince(start);

  start = Clock::now();
  matchImages(*query, ranked, result);
  result.timings.matching = secondsSince(start);

  const size_t top_k = options.top_k;
  pose_guided.more_images = [this, query, ranked, top_k](const Pose& pose, LocalizationResult& again) {
    matchImages(*query, imagesSeenFrom(pose, again.camera, top_k, ranked), again);
  };
  if (kNearbyPairAngle * result.camera.fx >= kMinNearbyPairRadiusPx)
    pose_guided.nearby_pairs = [this, query](const Pose& pose, LocalizationResult& again) {
      addPairsNearPose(*query, pose, again);
    };
}

void ClassicalLocalizer::matchImages(const SiftFeatures& query, const std::vector<size_t>& images,
                                     LocalizationResult& result) const {
  std::vector<const cv::Mat*> selected;
  for (size_t index : images) selected.push_back(&descriptors_[index]);
  const std::vector<std::vector<std::pair<int, int>>> matches =
      matchExactly(quantizeDescriptors(query.descriptors), selected, map_.ratio);
  for (size_t r = 0; r < images.size(); ++r) {
    const ClassicalMapImage& image = map_.images[images[r]];
    for (const auto& [q, row] : matches[r]) {
      const uint32_t k = searched_keypoints_[images[r]][row];
      // More views behind a point, more trust: 1 + views passes the paper's tau = 1.5 always.
      result.correspondences.add(query.pixels[q], image.points[k], 1.0f + image.point_views[k]);
    }
    result.selected.push_back(images[r]);
  }
}

void ClassicalLocalizer::addPairsNearPose(const SiftFeatures& query, const Pose& pose, LocalizationResult& result) const {
  std::vector<const cv::Mat*> selected;
  for (size_t index : result.selected) selected.push_back(&descriptors_[index]);
  std::vector<std::vector<float>> distance_ratios;
  const std::vector<std::vector<std::pair<int, int>>> matches = matchExactly(
      quantizeDescriptors(query.descriptors), selected, kNearbyPairRatio, ProductKernel::kFastest, &distance_ratios);
  const Pose world_to_query = pose.inverse();
  const double radius = kNearbyPairAngle * result.camera.fx;
  for (size_t r = 0; r < result.selected.size(); ++r) {
    const ClassicalMapImage& image = map_.images[result.selected[r]];
    for (size_t m = 0; m < matches[r].size(); ++m) {
      if (distance_ratios[r][m] < map_.ratio) continue;  // passed the map's own test: already a pair
      const auto [q, row] = matches[r][m];
      const uint32_t k = searched_keypoints_[result.selected[r]][row];
      const Eigen::Vector3d in_query = world_to_query * image.points[k];
      if (in_query.z() <= 0 || (result.camera.project(in_query) - query.pixels[q]).norm() > radius) continue;
      result.correspondences.add(query.pixels[q], image.points[k], 1.0f + image.point_views[k]);
    }
  }
}

std::vector<size_t> ClassicalLocalizer::imagesSeenFrom(const Pose& pose, const Intrinsics& camera, size_t count,
                                                       const std::vector<size_t>& exclude) const {
  const Pose world_to_query = pose.inverse();
  const double min_cos = std::cos(kMaxViewingAngleDeg * M_PI / 180.0);
  std::vector<bool> excluded(map_.images.size(), false);
  for (size_t i : exclude) excluded[i] = true;
  std::vector<std::pair<size_t, size_t>> seen;  // (points seen, image)
  for (size_t i = 0; i < map_.images.size(); ++i) {
    if (excluded[i]) continue;
    const ClassicalMapImage& image = map_.images[i];
    size_t points = 0;
    for (uint32_t k : searched_keypoints_[i]) {
      const Eigen::Vector3d& point = image.points[k];
      const Eigen::Vector3d in_query = world_to_query * point;
      if (in_query.z() <= 0) continue;
      const Eigen::Vector2d pixel = camera.project(in_query);
      if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() >= camera.width || pixel.y() >= camera.height) continue;
      const Eigen::Vector3d to_query = (pose.centre() - point).normalized();
      const Eigen::Vector3d to_image = (image.camera_to_world.centre() - point).normalized();
      if (to_query.dot(to_image) >= min_cos) ++points;
    }
    if (points > 0) seen.emplace_back(points, i);
  }
  std::stable_sort(seen.begin(), seen.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<size_t> images;
  for (size_t r = 0; r < seen.size() && r < count; ++r) images.push_back(seen[r].second);
  return images;
}

}  // namespace ffloc
