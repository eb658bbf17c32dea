#include "ffloc/classical/classical_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>

#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/geometry/triangulation.h"

namespace ffloc {
namespace {

// The median of the valid depths in the 3x3 neighbourhood of `pixel`, or 0 when fewer than
// five are valid or they spread more than `max_spread` of the median.
double robustDepth(const cv::Mat1f& depth, const Eigen::Vector2d& pixel, double max_spread) {
  const int x = static_cast<int>(std::lround(pixel.x())), y = static_cast<int>(std::lround(pixel.y()));
  if (x < 1 || y < 1 || x >= depth.cols - 1 || y >= depth.rows - 1) return 0;
  float values[9];
  int count = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const float d = depth(y + dy, x + dx);
      if (d > 0 && std::isfinite(d)) values[count++] = d;
    }
  if (count < 5) return 0;
  std::sort(values, values + count);
  const double median = values[count / 2];
  return (values[count - 1] - values[0]) <= max_spread * median ? median : 0;
}

Eigen::Vector3d backProject(const Intrinsics& camera, const Pose& camera_to_world, const Eigen::Vector2d& pixel,
                            double depth) {
  const Eigen::Vector3d in_camera((pixel.x() - camera.cx) / camera.fx * depth, (pixel.y() - camera.cy) / camera.fy * depth,
                                  depth);
  return camera_to_world * in_camera;
}

// The keypoint's track: itself first, then one linked keypoint per other image.
std::vector<Observation> trackOf(const ClassicalMap& map, size_t image, size_t keypoint,
                                 const std::vector<std::vector<std::vector<std::pair<uint32_t, uint32_t>>>>& linked,
                                 size_t max_views, double& finest_scale) {
  const ClassicalMapImage& own = map.images[image];
  std::vector<Observation> track{Observation(own.camera, own.camera_to_world, own.keypoints[keypoint])};
  finest_scale = own.working_scale;
  std::set<uint32_t> seen{static_cast<uint32_t>(image)};
  for (const auto& [other, other_keypoint] : linked[image][keypoint]) {
    if (track.size() >= max_views) break;
    if (!seen.insert(other).second) continue;
    const ClassicalMapImage& o = map.images[other];
    track.emplace_back(o.camera, o.camera_to_world, o.keypoints[other_keypoint]);
    finest_scale = std::max(finest_scale, o.working_scale);
  }
  return track;
}

}  // namespace

void ClassicalMappingOptions::check() const {
  sift.check();
  if (!(ratio > 0 && ratio <= 1)) throw InputError("ratio: must be in (0, 1]");
  if (vocabulary.words < 1) throw InputError("vocabulary.words: must be positive");
  if (vocabulary.training_descriptors < 1) throw InputError("vocabulary.training_descriptors: must be positive");
  if (map_neighbours < 1) throw InputError("map_neighbours: must be positive");
  if (!(max_depth_spread >= 0)) throw InputError("max_depth_spread: must not be negative");
  if (!(max_reprojection_error_px > 0)) throw InputError("max_reprojection_error_px: must be positive");
  if (!(min_triangulation_angle_deg >= 0 && min_triangulation_angle_deg < 90))
    throw InputError("min_triangulation_angle_deg: must be in [0, 90)");
  if (max_track_views < 2) throw InputError("max_track_views: must be at least 2");
}

ClassicalMap emptyClassicalMap(bool metric, const ClassicalMappingOptions& options) {
  ClassicalMap map;
  map.metric = metric;
  map.sift = options.sift;
  map.ratio = options.ratio;
  return map;
}

ClassicalMappingReport addToClassicalMap(ClassicalMap& map, const Scene& scene, const std::vector<size_t>& frames,
                                         const ClassicalMappingOptions& options) {
  options.check();
  const auto start = std::chrono::steady_clock::now();
  ClassicalMappingReport report;
  if (!map.images.empty() && map.metric != scene.metric)
    throw InputError(scene.root.string() + ": the map is " + (map.metric ? "metric" : "not metric") +
                     " and this dataset is " + (scene.metric ? "metric" : "not metric"));
  map.metric = scene.metric;

  std::map<std::string, Pose> mapped;
  std::map<std::string, size_t> previous;  // the map's images before this append, by name
  for (size_t i = 0; i < map.images.size(); ++i) {
    mapped.emplace(map.images[i].name, map.images[i].camera_to_world);
    previous.emplace(map.images[i].name, i);
  }
  const size_t first_new = map.images.size();
  std::vector<size_t> new_frames;  // scene frame of each new image
  {
    ProgressBar progress("features", frames.size(), options.quiet);
    for (size_t f = 0; f < frames.size(); ++f) {
      const Frame& frame = scene.frames.at(frames[f]);
      progress.update(f + 1);
      if (const auto [found, added] = mapped.emplace(frame.name, frame.camera_to_world); !added) {
        requireSamePoseAsMapped(scene.root, frame.name, found->second, frame.camera_to_world);
        if (const auto image = previous.find(frame.name); image != previous.end())
          requireSameCameraAsMapped(scene.root, frame.name, map.images[image->second].camera, frame.intrinsics.undistorted());
        ++report.skipped_duplicates;
        continue;
      }
      if (!frame.intrinsics.isValid())
        throw InputError(scene.root.string() + ": frame '" + frame.name + "': invalid intrinsics");
      const SiftFeatures features = extractSiftFeatures(frame, map.sift);
      if (features.descriptors.rows < 2) {
        report.featureless.push_back(frame.name);
        continue;
      }
      ClassicalMapImage image;
      image.name = frame.name;
      image.camera_to_world = frame.camera_to_world;
      image.camera = frame.intrinsics.undistorted();
      image.working_scale = features.working_scale;
      image.keypoints = features.pixels;
      image.descriptors = quantizeDescriptors(features.descriptors);
      image.points.assign(features.pixels.size(), Eigen::Vector3d::Zero());
      image.point_views.assign(features.pixels.size(), 0);
      image.depth_lifted = options.use_depth && frame.depth.has_value();
      if (image.depth_lifted) {
        const cv::Mat1f depth = readDepthMetres(frame);
        for (size_t k = 0; k < features.pixels.size(); ++k) {
          const double d = robustDepth(depth, features.distorted_pixels[k], options.max_depth_spread);
          if (d <= 0) continue;
          image.points[k] = backProject(image.camera, image.camera_to_world, features.pixels[k], d);
          image.point_views[k] = 1;
        }
      }
      map.images.push_back(std::move(image));
      new_frames.push_back(frames[f]);
    }
    progress.finish();
  }
  report.added = map.images.size() - first_new;
  if (map.images.empty())
    throw InputError(scene.root.string() + ": no mapping image has usable features (SIFT found fewer than two "
                                           "keypoints in every image)");

  std::vector<cv::Mat> descriptors(map.images.size());
  for (size_t i = 0; i < map.images.size(); ++i) descriptors[i] = dequantizeDescriptors(map.images[i].descriptors);
  if (map.vocabulary.empty()) {
    std::vector<const cv::Mat*> training;
    for (const cv::Mat& d : descriptors) training.push_back(&d);
    map.vocabulary = VladVocabulary::train(training, options.vocabulary);
  }
  for (size_t i = first_new; i < map.images.size(); ++i)
    map.images[i].global_descriptor = map.vocabulary.describe(descriptors[i]);

  // Each new image is linked with its most similar images, old and new.
  std::vector<Eigen::VectorXf> globals;
  for (const ClassicalMapImage& image : map.images) globals.push_back(image.global_descriptor);
  std::set<std::pair<size_t, size_t>> pairs;
  for (size_t i = first_new; i < map.images.size(); ++i) {
    size_t taken = 0;
    for (size_t j : rankBySimilarity(globals, globals[i])) {
      if (j == i) continue;
      if (taken++ >= static_cast<size_t>(options.map_neighbours)) break;
      pairs.emplace(std::min(i, j), std::max(i, j));
    }
  }
  {
    std::map<size_t, std::vector<size_t>> partners;  // i -> every j > i it is linked with
    for (const auto& [i, j] : pairs) partners[i].push_back(j);
    ProgressBar progress("links", partners.size(), options.quiet);
    size_t done = 0;
    for (const auto& [i, others] : partners) {
      std::vector<const cv::Mat*> targets;
      for (size_t j : others) targets.push_back(&map.images[j].descriptors);
      const auto matches = matchExactly(map.images[i].descriptors, targets, map.ratio);
      for (size_t o = 0; o < others.size(); ++o) {
        const size_t j = others[o];
        for (const auto& [ki, kj] : matches[o]) {
          map.images[i].links.push_back({static_cast<uint32_t>(ki), static_cast<uint32_t>(j), static_cast<uint32_t>(kj)});
          map.images[j].links.push_back({static_cast<uint32_t>(kj), static_cast<uint32_t>(i), static_cast<uint32_t>(ki)});
          report.links += 2;
        }
      }
      progress.update(++done);
    }
    progress.finish();
  }

  // linked[image][keypoint]: (other image, other keypoint), for the points of the new images.
  std::vector<std::vector<std::vector<std::pair<uint32_t, uint32_t>>>> linked(map.images.size());
  for (size_t i = 0; i < map.images.size(); ++i) {
    linked[i].resize(map.images[i].keypoints.size());
    for (const KeypointLink& link : map.images[i].links)
      linked[i][link.keypoint].emplace_back(link.other_image, link.other_keypoint);
  }
  TriangulationOptions triangulation;
  triangulation.min_angle_deg = options.min_triangulation_angle_deg;
  std::vector<bool> inliers;
  ProgressBar progress("points", map.images.size() - first_new, options.quiet);
  for (size_t i = first_new; i < map.images.size(); ++i) {
    ClassicalMapImage& image = map.images[i];
    for (size_t k = 0; k < image.keypoints.size(); ++k) {
      double finest_scale = 1;
      const std::vector<Observation> track = trackOf(map, i, k, linked, options.max_track_views, finest_scale);
      const double threshold = options.max_reprojection_error_px / finest_scale;
      if (image.depth_lifted) {
        if (image.point_views[k] == 0) continue;
        // The other views that see the lifted point where their keypoint is.
        int views = 1;
        for (size_t v = 1; v < track.size(); ++v) views += reprojectionError(track[v], image.points[k]) <= threshold;
        image.point_views[k] = static_cast<uint8_t>(std::min(views, 255));
        continue;
      }
      if (track.size() < 2) continue;
      triangulation.max_reprojection_error_px = threshold;
      const std::optional<Eigen::Vector3d> point = triangulateRobust(track, triangulation, &inliers);
      // The point must explain the keypoint itself, or it belongs to another one.
      if (!point || inliers.empty() || !inliers[0]) continue;
      image.points[k] = *point;
      image.point_views[k] = static_cast<uint8_t>(std::min<long>(std::count(inliers.begin(), inliers.end(), true), 255));
    }
    report.points += image.pointCount();
    if (image.depth_lifted) report.points_from_depth += image.pointCount();
    progress.update(i - first_new + 1);
  }
  progress.finish();
  // A map of no point localizes nothing: every depth map of a dataset invalid (all zero, or a
  // depth scale off by 1e12) gave one with exit 0 and no word (an outside probe).
  const auto has_points = [](const ClassicalMapImage& image) { return image.pointCount() > 0; };
  const auto lifted = [](const ClassicalMapImage& image) { return image.depth_lifted; };
  if (std::none_of(map.images.begin(), map.images.end(), has_points))
    throw InputError(scene.root.string() + ": no mapping image gave a 3D point: " +
                     (std::any_of(map.images.begin(), map.images.end(), lifted)
                          ? "the depth maps hold no valid depth at the keypoints (all zero, or a wrong depth scale?); "
                            "without their depth the keypoints are triangulated (ClassicalMappingOptions::use_depth)"
                          : "no keypoint was matched in enough views to be triangulated"));
  report.seconds = secondsSince(start);
  return report;
}

}  // namespace ffloc
