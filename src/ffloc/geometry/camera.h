#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

namespace ffloc {

// A pinhole camera with optional OpenCV distortion coefficients (k1, k2, p1, p2[, k3[, k4, k5,
// k6]]), in pixels of an image of width x height. Pixel centres are at integer coordinates
// (OpenCV convention): the top-left pixel's centre is (0, 0).
struct Intrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
  std::vector<double> distortion;

  Eigen::Matrix3d K() const;
  cv::Mat cvK() const;
  cv::Mat cvDistortion() const;
  bool hasDistortion() const;
  bool isValid() const;

  // Pinhole projection of a point in camera coordinates (no distortion).
  Eigen::Vector2d project(const Eigen::Vector3d& camera_point) const;
  // The camera-frame point at z-depth `depth` seen at pixel (u, v) of an undistorted image.
  Eigen::Vector3d backproject(const Eigen::Vector2d& pixel, double depth) const;

  // Scaled by (sx, sy): the intrinsics of the same image resized by those factors.
  Intrinsics scaled(double sx, double sy, int new_width, int new_height) const;
  // The intrinsics of the window [x0, x0+w) x [y0, y0+h) of this image.
  Intrinsics cropped(int x0, int y0, int new_width, int new_height) const;
  // The same camera with no distortion (what undistortImage produces).
  Intrinsics undistorted() const;
};

// Maps distorted pixel coordinates to the pixels an ideal pinhole camera with the same K would
// see. Identity without distortion.
std::vector<Eigen::Vector2d> undistortPixels(const Intrinsics& camera,
                                             const std::vector<Eigen::Vector2d>& pixels);

// The checks intrinsics must pass for a `width` x `height` image, a query's or a mapping frame's:
// the size they give (when they give one) is the image's, finite focal lengths in
// (0, 1000 * long side], the principal point inside the image, finite distortion. InputError
// naming width, fx, fy, cx, cy or distortion.
void checkIntrinsicsFitImage(const Intrinsics& intrinsics, int width, int height);

// Resamples an image so it follows camera.undistorted(). Returns the input when not distorted.
cv::Mat undistortImage(const cv::Mat& image, const Intrinsics& camera);

}  // namespace ffloc
