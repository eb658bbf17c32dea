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

// How far distortion may move a point of the image, in image diagonals. The model is evaluated at
// the normalised coordinates of the image's own points: there, barrel distortion that does not fold
// the image moves a point by less than its distance from the principal point (under a diagonal),
// and pincushion moves a telephoto's corner a few percent. No coefficient alone is bounded, as
// narrow lenses' high-order terms are huge but harmless (a 60 mm macro lens's k2 = -500, k3 = 300
// at fx = 8000 px move a 640 x 480 image's corner 1.2 px). A pixel value in a coefficient's place
// is far beyond: k1 = 320 at fx = 500 moves that corner 100 diagonals, k1 = 1e10 by 3e9.
inline constexpr double kMaxDistortionShift = 1.0;

// What is wrong with the distortion coefficients of `camera` (OpenCV's, k1 k2 p1 p2 [k3 [k4 k5 k6
// [s1 s2 s3 s4 [taux tauy]]]]), "" when nothing is: a coefficient that is not finite ("k5 nan:
// ..."), and, when the camera has a size and positive focal lengths, a model that, evaluated along
// the lines from the principal point to the image's corners and edge midpoints, moves a point more
// than kMaxDistortionShift diagonals, or folds the image on the way to an edge's midpoint (a point
// farther out lands nearer the principal point: two directions seen at one pixel, no lens's image;
// the corners, where calibrations extrapolate, may turn back). The coefficients that are
// not 0 are named with every digit ("k1 320: moves the image corner (639, 479) by 8.2e+04 px ..."),
// and a focal length that puts that point more than kMaxPinholeTangent focal lengths out is named
// beside them. Intrinsics whose pinhole part does not fit their image (pinholeProblem) are not
// judged: their distortion is measured over the wrong image.
std::string distortionProblem(const Intrinsics& camera);

// How far from the principal point, in focal lengths, a pinhole camera's image reaches at most:
// tan(70 deg), a view 140 degrees across; wider lenses are fisheyes, which OpenCV's model is not.
inline constexpr double kMaxPinholeTangent = 2.75;

// What keeps the pinhole part of `intrinsics` from fitting a `width` x `height` image, "" when
// nothing: the size they give (when they give one) is not the image's, a focal length outside
// (0, 1000 * long side] or not finite, the principal point outside the image. Names the field.
std::string pinholeProblem(const Intrinsics& intrinsics, int width, int height);

// The checks intrinsics must pass for a `width` x `height` image, a query's or a mapping frame's:
// the size they give (when they give one) is the image's, finite focal lengths in
// (0, 1000 * long side], the principal point inside the image, distortion that passes
// distortionProblem for this size. InputError naming width, fx, fy, cx, cy or distortion.
void checkIntrinsicsFitImage(const Intrinsics& intrinsics, int width, int height);

// Resamples an image so it follows camera.undistorted(). Returns the input when not distorted.
cv::Mat undistortImage(const cv::Mat& image, const Intrinsics& camera);

}  // namespace ffloc
