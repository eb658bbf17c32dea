#include "ffloc/eval/oracle_depth_source.h"


#include "ffloc/core/error.h"
#include "ffloc/core/random.h"
#include "ffloc/data/depth.h"

namespace ffloc {

void OracleDepthSource::prepare(const Scene& scene) {
  for (size_t index : scene.queryIndices())
    if (!scene.frames[index].depth)
      throw InputError(scene.root.string() + ": frame '" + scene.frames[index].name +
                       "': oracle-depth needs a depth map for every query frame, and this one has none");
}

Correspondences OracleDepthSource::correspondences(const Scene& scene, size_t query_index) {
  const Frame& frame = scene.frames.at(query_index);
  const cv::Mat1f depth = readDepthMetres(frame);

  std::vector<Eigen::Vector2d> pixels;
  std::vector<double> depths;
  const int stride = std::max(1, options_.stride);
  for (int v = 0; v < depth.rows; v += stride)
    for (int u = 0; u < depth.cols; u += stride)
      if (depth(v, u) > 0) {
        pixels.emplace_back(u, v);
        depths.push_back(depth(v, u));
      }
  // Depth lives on the distorted grid; the pairs must be in the undistorted one.
  const std::vector<Eigen::Vector2d> ideal = undistortPixels(frame.intrinsics, pixels);
  const Intrinsics pinhole = frame.intrinsics.undistorted();

  // One generator per query, so results do not depend on the order frames are visited in.
  Rng rng(options_.seed * 1000003ULL + query_index);

  Correspondences out;
  out.reserve(ideal.size());
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d high = -low;
  for (size_t i = 0; i < ideal.size(); ++i) {
    const Eigen::Vector3d world = frame.camera_to_world * pinhole.backproject(ideal[i], depths[i]);
    low = low.cwiseMin(world);
    high = high.cwiseMax(world);
    Eigen::Vector2d pixel = ideal[i];
    if (options_.pixel_noise_px > 0) pixel += options_.pixel_noise_px * Eigen::Vector2d(rng.normal(), rng.normal());
    out.add(pixel, world, std::numeric_limits<float>::infinity());
  }
  for (size_t i = 0; i < out.size(); ++i) {
    if (options_.outlier_fraction > 0 && rng.uniform() < options_.outlier_fraction) {
      const Eigen::Vector3d r(rng.uniform(), rng.uniform(), rng.uniform());
      out.points[i] = low + r.cwiseProduct(high - low);
    } else if (options_.point_noise > 0) {
      out.points[i] += options_.point_noise * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
    }
  }
  return out;
}

}  // namespace ffloc
