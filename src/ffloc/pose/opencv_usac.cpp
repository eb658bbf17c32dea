#include "ffloc/pose/opencv_usac.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace ffloc {

std::optional<Pose> opencvUsacPnp(const std::vector<Eigen::Vector2d>& pixels,
                                  const std::vector<Eigen::Vector3d>& points,
                                  const Intrinsics& camera, const PnpOptions& options) {
  std::vector<cv::Point3d> object_points;
  std::vector<cv::Point2d> image_points;
  object_points.reserve(points.size());
  image_points.reserve(pixels.size());
  for (size_t i = 0; i < points.size(); ++i) {
    object_points.emplace_back(points[i].x(), points[i].y(), points[i].z());
    image_points.emplace_back(pixels[i].x(), pixels[i].y());
  }

  cv::UsacParams params;
  params.confidence = options.success_probability;
  params.isParallel = false;  // a parallel run is not reproducible for a given seed
  params.loMethod = cv::LOCAL_OPTIM_INNER_AND_ITER_LO;
  params.maxIterations = options.max_iterations;
  params.randomGeneratorState = static_cast<int>(options.seed & 0x7fffffff);
  params.sampler = cv::SAMPLING_UNIFORM;
  params.score = cv::SCORE_METHOD_MSAC;
  params.threshold = options.inlier_threshold_px;

  try {
    cv::Mat K = camera.cvK();
    cv::Mat rvec, tvec, inliers;
    if (!cv::solvePnPRansac(object_points, image_points, K, cv::noArray(), rvec, tvec, inliers, params))
      return std::nullopt;
    if (rvec.empty() || tvec.empty()) return std::nullopt;
    if (options.refine && inliers.total() >= 3) {
      std::vector<cv::Point3d> inlier_object_points;
      std::vector<cv::Point2d> inlier_image_points;
      inliers = inliers.reshape(1, 1);
      for (int j = 0; j < static_cast<int>(inliers.total()); ++j) {
        const int i = inliers.at<int>(j);
        inlier_object_points.push_back(object_points[i]);
        inlier_image_points.push_back(image_points[i]);
      }
      rvec.convertTo(rvec, CV_64F);
      tvec.convertTo(tvec, CV_64F);
      cv::solvePnPRefineLM(inlier_object_points, inlier_image_points, K, cv::noArray(), rvec, tvec);
    }
    cv::Mat rotation;
    cv::Rodrigues(rvec, rotation);
    rotation.convertTo(rotation, CV_64F);
    tvec.convertTo(tvec, CV_64F);
    Pose world_to_camera;
    cv::cv2eigen(rotation, world_to_camera.R);
    Eigen::Vector3d t;
    cv::cv2eigen(tvec.reshape(1, 3), t);
    world_to_camera.t = t;
    if (!world_to_camera.isFinite()) return std::nullopt;
    return world_to_camera;
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
}

}  // namespace ffloc
