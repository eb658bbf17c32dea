#pragma once

#include <memory>
#include <vector>

#include "ffloc/classical/classical_map.h"
#include "ffloc/localization/localizer.h"

namespace ffloc {

// The classical method's queries: SIFT on the query, VLAD retrieval of the top-K mapping
// images, ratio-test matching against them, and the matched keypoints' stored points. No
// mapping image is read; their descriptors are decoded once, when the localizer is made.
class ClassicalLocalizer : public Localizer {
 public:
  // InputError when the map has no images.
  explicit ClassicalLocalizer(ClassicalMap map);
  ~ClassicalLocalizer() override;

  LocalizationMethod method() const override { return LocalizationMethod::kClassical; }
  bool metric() const override { return map_.metric; }
  const std::vector<MapCamera>& cameras() const override { return cameras_; }
  std::vector<Eigen::Vector3d> mapPoints(size_t max_points) const override;
  const ClassicalMap& map() const { return map_; }

 protected:
  void predict(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
               const LocalizeOptions& options, LocalizationResult& result,
               std::optional<PnpResult>& second_estimate, PoseGuidedLooks& pose_guided) const override;

 private:
  ClassicalMap map_;
  std::vector<MapCamera> cameras_;
  std::vector<Eigen::VectorXf> globals_;
  std::vector<cv::Mat> descriptors_;  // CV_8U as stored: the keypoints that have a point
  std::vector<std::vector<uint32_t>> searched_keypoints_;  // descriptors_ row -> keypoint

  // Matches `query` against `images` (ratio test) and appends the pairs and the images to
  // `result`.
  void matchImages(const SiftFeatures& query, const std::vector<size_t>& images, LocalizationResult& result) const;
  // Appends the matches of the result's selected images that pass kNearbyPairRatio but not the
  // map's ratio and that `pose` projects within kNearbyPairAngle of their query keypoint.
  void addPairsNearPose(const SiftFeatures& query, const Pose& pose, LocalizationResult& result) const;
  // The `count` mapping images outside `exclude` that see the most of their searched points
  // inside the query's image at `pose`, each point from a direction within
  // kMaxViewingAngleDeg of the query's; best first.
  std::vector<size_t> imagesSeenFrom(const Pose& pose, const Intrinsics& camera, size_t count,
                                     const std::vector<size_t>& exclude) const;
};

}  // namespace ffloc
