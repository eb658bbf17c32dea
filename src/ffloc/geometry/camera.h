#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
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

// The bound on the magnitude of every OpenCV distortion coefficient. The coefficients act on
// normalised image coordinates (x/z, y/z), so no image size enters: ordinary lenses' radial
// coefficients stay below 1 and the rational model's numerator and denominator terms of wide-angle
// lenses reach tens, while a pixel value in a coefficient's place (a column out of place: a focal
// length, a principal point) exceeds 100 for any image wider than 200 pixels. k1 = 1e10 was read
// as a lens without a word.
inline constexpr double kMaxDistortionCoefficient = 100;

// What is wrong with one distortion coefficient, not finite or beyond kMaxDistortionCoefficient
// ("1e+10: no lens's distortion coefficient exceeds 100 in magnitude"); "" when nothing is.
std::string distortionCoefficientProblem(double coefficient);
// The same for the first such coefficient in OpenCV's order (k1 k2 p1 p2 [k3 [k4 k5 k6]]), named
// ("k1 1e+10: ...").
std::string distortionProblem(const std::vector<double>& coefficients);

// The checks intrinsics must pass for a `width` x `height` image, a query's or a mapping frame's:
// the size they give (when they give one) is the image's, finite focal lengths in
// (0, 1000 * long side], the principal point inside the image, distortion that passes
// distortionProblem. InputError naming width, fx, fy, cx, cy or distortion.
void checkIntrinsicsFitImage(const Intrinsics& intrinsics, int width, int height);

// Resamples an image so it follows camera.undistorted(). Returns the input when not distorted.
cv::Mat undistortImage(const cv::Mat& image, const Intrinsics& camera);

}  // namespace ffloc
