#include "ffloc/geometry/camera.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <tuple>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"

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

namespace {

// OpenCV's order, up to its longest form (thin prism and tilt terms).
const char* const kDistortionNames[] = {"k1", "k2", "p1", "p2", "k3", "k4", "k5",
                                        "k6", "s1", "s2", "s3", "s4", "taux", "tauy"};

std::string coefficientName(size_t i) {
  return i < std::size(kDistortionNames) ? kDistortionNames[i] : "coefficient " + std::to_string(i + 1);
}

std::string pixelText(const cv::Point2d& p) { return "(" + formatNumber(p.x) + ", " + formatNumber(p.y) + ")"; }

}  // namespace

std::string distortionProblem(const Intrinsics& camera) {
  const std::vector<double>& d = camera.distortion;
  for (size_t i = 0; i < d.size(); ++i)
    if (!std::isfinite(d[i])) return coefficientName(i) + " " + formatNumber(d[i]) + ": distortion coefficients must be finite";
  // Judged over the image the rest describes: a principal point or focal length in other units
  // was blamed on a coefficient (an outside probe); pinholeProblem names those.
  if (!camera.hasDistortion() || !camera.isValid() || !pinholeProblem(camera, camera.width, camera.height).empty())
    return "";
  std::string named;
  for (size_t i = 0; i < d.size(); ++i)
    if (d[i] != 0.0) named += (named.empty() ? "" : ", ") + coefficientName(i) + " " + formatNumber(d[i]);
  const size_t n = d.size();
  if (n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
    return named + ": " + std::to_string(n) + " coefficients, where OpenCV's model takes 4, 5, 8, 12 or 14";

  // Corners and edge midpoints (pixel centres), each approached from the principal point in steps
  // fine enough to see a radial term turn back between the centre and the border.
  const double right = camera.width - 1, bottom = camera.height - 1;
  const cv::Point2d border[] = {{0, 0},         {right, 0},          {right, bottom},     {0, bottom},
                                {right / 2, 0}, {right, bottom / 2}, {right / 2, bottom}, {0, bottom / 2}};
  constexpr int kSteps = 32;
  const cv::Point2d centre(camera.cx, camera.cy);
  std::vector<cv::Point2d> undistorted;
  std::vector<cv::Point3d> rays;
  for (const cv::Point2d& end : border)
    for (int step = 1; step <= kSteps; ++step) {
      undistorted.push_back(centre + (end - centre) * (static_cast<double>(step) / kSteps));
      rays.emplace_back((undistorted.back().x - camera.cx) / camera.fx, (undistorted.back().y - camera.cy) / camera.fy, 1);
    }
  std::vector<cv::Point2d> distorted;
  cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera.cvK(), camera.cvDistortion(), distorted);

  const auto where = [&](size_t i) {
    if ((i + 1) % kSteps != 0) return "the pixel " + pixelText(undistorted[i]);
    return std::string(i / kSteps < 4 ? "the image corner " : "the image edge's midpoint ") + pixelText(undistorted[i]);
  };
  size_t worst = 0;
  double worst_shift = -1;
  for (size_t i = 0; i < distorted.size(); ++i) {
    const double shift = cv::norm(distorted[i] - undistorted[i]);
    if (!std::isfinite(shift)) return named + ": sends " + where(i) + " to infinity";
    if (shift > worst_shift) std::tie(worst, worst_shift) = std::tie(i, shift);
  }
  const double diagonal = std::hypot(camera.width, camera.height);
  if (worst_shift > kMaxDistortionShift * diagonal) {
    std::ostringstream what;
    what << named << ": moves " << where(worst) << " by " << std::setprecision(2) << worst_shift
         << " px, more than the " << camera.width << "x" << camera.height << " image's diagonal (" << std::setprecision(4)
         << diagonal << " px): no lens's distortion does";
    // A focal length a few pixels long puts the image's border tens of focal lengths out, where
    // any coefficient explodes: the coefficients were blamed for the focal length (an outside probe).
    const cv::Point2d ray((undistorted[worst].x - camera.cx) / camera.fx, (undistorted[worst].y - camera.cy) / camera.fy);
    if (cv::norm(ray) > kMaxPinholeTangent) {
      what << "; or the focal length is wrong: fx " << formatNumber(camera.fx) << ", fy " << formatNumber(camera.fy)
           << " put that point " << std::setprecision(3) << cv::norm(ray) << " focal lengths from the principal point, "
           << std::setprecision(3) << 2 * std::atan(cv::norm(ray)) * 180 / M_PI << " deg across, wider than a pinhole lens sees";
    }
    return what.str();
  }
  // Folds are looked for on the way to the edges' midpoints only: a calibration fitted on the
  // image's inner part may turn back in its corners (a wide lens's k1 = -0.4 does past r = 0.91)
  // and still be the camera's own; one that folds before reaching an edge cannot be. A principal
  // point on an edge has no way to go there.
  for (size_t i = 4 * kSteps; i < distorted.size(); i += kSteps) {
    if (cv::norm(undistorted[i + kSteps - 1] - centre) < 1) continue;
    double reach = 0;
    for (size_t j = i; j < i + kSteps; ++j) {
      const double next = cv::norm(distorted[j] - centre);
      if (!(next > reach))
        return named + ": folds the image: on the way from the principal point to " + where(i + kSteps - 1) +
               ", " + where(j) + " lands no farther out than the point before it (no lens's distortion does)";
      reach = next;
    }
  }
  return "";
}

std::string pinholeProblem(const Intrinsics& k, int width, int height) {
  std::ostringstream what;
  if ((k.width != 0 || k.height != 0) && (k.width != width || k.height != height)) {
    what << "width, height: the intrinsics are for a " << k.width << "x" << k.height << " image, but the image is "
         << width << "x" << height;
    return what.str();
  }
  // A field of view of a few thousandths of a degree, or of nearly 180 degrees, is no camera's: a
  // focal length of 4e-320 px gave infinite errors scored as an evaluation.
  const double absurd = 1000.0 * std::max(width, height), least = std::max(width, height) / 1000.0;
  for (const auto& [field, value] : {std::pair{"fx", k.fx}, {"fy", k.fy}}) {
    if (!(std::isfinite(value) && value >= least && value <= absurd)) {
      what << field << ": focal length " << value << " px is not in [" << least << ", " << absurd << "] for a " << width
           << "x" << height << " image";
      return what.str();
    }
  }
  // With pixel centres at integers (OpenCV's convention, ours) the image spans [-0.5, width - 0.5];
  // with pixel corners there (COLMAP's and NeRF's exports may be so) [0, width]. Either is taken.
  const auto inside = [](double c, int size) { return std::isfinite(c) && c >= -0.5 && c <= size; };
  if (!(inside(k.cx, width) && inside(k.cy, height))) {
    what << "cx, cy: the principal point (" << k.cx << ", " << k.cy << ") lies outside the " << width << "x" << height
         << " image (intrinsics must be in pixels of the image given)";
    return what.str();
  }
  return "";
}

void checkIntrinsicsFitImage(const Intrinsics& k, int width, int height) {
  if (const std::string pinhole = pinholeProblem(k, width, height); !pinhole.empty()) throw InputError(pinhole);
  Intrinsics sized = k;
  sized.width = width;
  sized.height = height;
  const std::string distortion = distortionProblem(sized);
  if (!distortion.empty()) throw InputError("distortion: " + distortion);
}

}  // namespace ffloc
