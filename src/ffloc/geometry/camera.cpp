#include "ffloc/geometry/camera.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"

namespace ffloc {

Eigen::Matrix3d Intrinsics::K() const {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = fx;
  K(1, 1) = fy;
  K(0, 2) = cx;
  K(1, 2) = cy;
  return K;
}

cv::Mat Intrinsics::cvK() const {
  return (cv::Mat_<double>(3, 3) << fx, 0, cx, 0, fy, cy, 0, 0, 1);
}

cv::Mat Intrinsics::cvDistortion() const {
  if (!hasDistortion()) return cv::Mat();
  return cv::Mat(distortion, true).reshape(1, 1);
}

bool Intrinsics::hasDistortion() const {
  for (double d : distortion)
    if (d != 0.0) return true;
  return false;
}

bool Intrinsics::isValid() const {
  return std::isfinite(fx) && std::isfinite(fy) && std::isfinite(cx) && std::isfinite(cy) && fx > 0 &&
         fy > 0 && width > 0 && height > 0;
}

Eigen::Vector2d Intrinsics::project(const Eigen::Vector3d& p) const {
  return {fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy};
}

Eigen::Vector3d Intrinsics::backproject(const Eigen::Vector2d& pixel, double depth) const {
  return {(pixel.x() - cx) / fx * depth, (pixel.y() - cy) / fy * depth, depth};
}

Intrinsics Intrinsics::scaled(double sx, double sy, int new_width, int new_height) const {
  // Pixel centres sit at integer coordinates, so a pixel edge at -0.5 must stay at -0.5 after
  // scaling: c' = (c + 0.5) * s - 0.5.
  Intrinsics out = *this;
  out.fx = fx * sx;
  out.fy = fy * sy;
  out.cx = (cx + 0.5) * sx - 0.5;
  out.cy = (cy + 0.5) * sy - 0.5;
  out.width = new_width;
  out.height = new_height;
  return out;
}

Intrinsics Intrinsics::cropped(int x0, int y0, int new_width, int new_height) const {
  Intrinsics out = *this;
  out.cx = cx - x0;
  out.cy = cy - y0;
  out.width = new_width;
  out.height = new_height;
  return out;
}

Intrinsics Intrinsics::undistorted() const {
  Intrinsics out = *this;
  out.distortion.clear();
  return out;
}

std::vector<Eigen::Vector2d> undistortPixels(const Intrinsics& camera,
                                             const std::vector<Eigen::Vector2d>& pixels) {
  if (!camera.hasDistortion() || pixels.empty()) return pixels;
  std::vector<cv::Point2d> in(pixels.size()), out;
  for (size_t i = 0; i < pixels.size(); ++i) in[i] = {pixels[i].x(), pixels[i].y()};
  const cv::Mat K = camera.cvK();
  cv::undistortPoints(in, out, K, camera.cvDistortion(), cv::noArray(), K,
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 1e-10));
  std::vector<Eigen::Vector2d> result(out.size());
  for (size_t i = 0; i < out.size(); ++i) result[i] = {out[i].x, out[i].y};
  return result;
}

cv::Mat undistortImage(const cv::Mat& image, const Intrinsics& camera) {
  if (!camera.hasDistortion()) return image;
  cv::Mat out;
  cv::undistort(image, out, camera.cvK(), camera.cvDistortion(), camera.cvK());
  return out;
}

std::string distortionCoefficientProblem(double coefficient) {
  if (std::isfinite(coefficient) && std::abs(coefficient) <= kMaxDistortionCoefficient) return "";
  std::ostringstream what;
  what << coefficient << ": ";
  if (std::isfinite(coefficient))
    what << "no lens's distortion coefficient exceeds " << kMaxDistortionCoefficient << " in magnitude";
  else
    what << "distortion coefficients must be finite";
  return what.str();
}

std::string distortionProblem(const std::vector<double>& coefficients) {
  // OpenCV's order, up to its longest form (thin prism and tilt terms).
  static const char* const kNames[] = {"k1", "k2", "p1", "p2", "k3", "k4", "k5",
                                       "k6", "s1", "s2", "s3", "s4", "taux", "tauy"};
  for (size_t i = 0; i < coefficients.size(); ++i) {
    const std::string problem = distortionCoefficientProblem(coefficients[i]);
    if (!problem.empty())
      return (i < std::size(kNames) ? kNames[i] : "coefficient " + std::to_string(i + 1)) + " " + problem;
  }
  return "";
}

void checkIntrinsicsFitImage(const Intrinsics& k, int width, int height) {
  if ((k.width != 0 || k.height != 0) && (k.width != width || k.height != height))
    throw InputError("width, height: the intrinsics are for a " + std::to_string(k.width) + "x" +
                     std::to_string(k.height) + " image, but the image is " + std::to_string(width) + "x" +
                     std::to_string(height));
  // A field of view of a few thousandths of a degree, or of nearly 180 degrees, is no camera's: a
  // focal length of 4e-320 px gave infinite errors scored as an evaluation.
  const double absurd = 1000.0 * std::max(width, height), least = std::max(width, height) / 1000.0;
  auto focal = [&](const char* field, double value) {
    if (!(std::isfinite(value) && value >= least && value <= absurd)) {
      std::ostringstream what;
      what << field << ": focal length " << value << " px is not in [" << least << ", " << absurd << "] for a " << width
           << "x" << height << " image";
      throw InputError(what.str());
    }
  };
  focal("fx", k.fx);
  focal("fy", k.fy);
  if (!(std::isfinite(k.cx) && std::isfinite(k.cy) && k.cx >= 0 && k.cx <= width && k.cy >= 0 && k.cy <= height)) {
    std::ostringstream what;
    what << "cx, cy: the principal point (" << k.cx << ", " << k.cy << ") lies outside the " << width << "x" << height
         << " image (intrinsics must be in pixels of the image given)";
    throw InputError(what.str());
  }
  const std::string distortion = distortionProblem(k.distortion);
  if (!distortion.empty()) throw InputError("distortion: " + distortion);
}

}  // namespace ffloc
