#include "ffloc/eval/sift_baseline_source.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/io/image.h"

namespace ffloc {
namespace {

using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

Eigen::Map<const RowMatrixXf> asEigen(const cv::Mat& m) {
  return Eigen::Map<const RowMatrixXf>(m.ptr<float>(), m.rows, m.cols);
}

// RootSIFT (Arandjelovic & Zisserman 2012): L1-normalise, then square-root, so Euclidean
// distance compares descriptors like the Hellinger kernel; it matches better than raw SIFT.
void toRootSift(cv::Mat& descriptors) {
  for (int r = 0; r < descriptors.rows; ++r) {
    float* row = descriptors.ptr<float>(r);
    double l1 = 0;
    for (int c = 0; c < descriptors.cols; ++c) l1 += std::abs(row[c]);
    const double inv = l1 > 0 ? 1.0 / l1 : 0.0;
    for (int c = 0; c < descriptors.cols; ++c) row[c] = static_cast<float>(std::sqrt(std::abs(row[c]) * inv));
  }
}

// A FLANN kd-forest over one image's descriptors. cvflann draws its random split dimensions from
// std::rand, so the generator is seeded right before the build to make runs repeatable.
std::unique_ptr<cv::flann::Index> buildIndex(const cv::Mat& descriptors, const SiftBaselineOptions& options) {
  cvflann::seed_random(static_cast<unsigned>(options.seed));
  return std::make_unique<cv::flann::Index>(descriptors, cv::flann::KDTreeIndexParams(std::max(1, options.flann_trees)),
                                            cvflann::FLANN_DIST_L2);
}

// Ratio-test matches (query row, target row) of `query` against `target`'s index. One query row
// per target row: the closest wins, so one keypoint cannot pin several others to its point.
std::vector<std::pair<int, int>> matchDescriptors(const cv::Mat& query, cv::flann::Index& target, int target_rows,
                                                  const SiftBaselineOptions& options) {
  std::vector<std::pair<int, int>> matches;
  if (query.rows == 0) return matches;
  cv::Mat indices, distances;
  target.knnSearch(query, indices, distances, 2, cv::flann::SearchParams(options.flann_checks));
  const float max_squared_ratio = options.ratio * options.ratio;  // FLANN reports squared distances
  std::vector<int> best_query(target_rows, -1);
  std::vector<float> best_distance(target_rows, std::numeric_limits<float>::infinity());
  for (int q = 0; q < indices.rows; ++q) {
    const int nearest = indices.at<int>(q, 0);
    const float d1 = distances.at<float>(q, 0), d2 = distances.at<float>(q, 1);
    if (nearest < 0 || nearest >= target_rows || !(d1 < max_squared_ratio * d2)) continue;
    if (d1 < best_distance[nearest]) {
      best_distance[nearest] = d1;
      best_query[nearest] = q;
    }
  }
  for (int t = 0; t < target_rows; ++t)
    if (best_query[t] >= 0) matches.emplace_back(best_query[t], t);
  return matches;
}

}  // namespace

SiftFeatures extractSiftFeatures(const Frame& frame, const SiftBaselineOptions& options) {
  const cv::Mat rgb = readImageRgb(frame.image_path);
  if (rgb.cols != frame.intrinsics.width || rgb.rows != frame.intrinsics.height)
    throw InputError(frame.image_path.string() + ": image is " + std::to_string(rgb.cols) + "x" +
                     std::to_string(rgb.rows) + " but frame '" + frame.name + "' has intrinsics for " +
                     std::to_string(frame.intrinsics.width) + "x" + std::to_string(frame.intrinsics.height));
  cv::Mat gray;
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);

  SiftFeatures features;
  const int long_side = std::max(gray.cols, gray.rows);
  if (options.max_image_size > 0 && long_side > options.max_image_size) {
    features.working_scale = static_cast<double>(options.max_image_size) / long_side;
    cv::Mat small;
    cv::resize(gray, small, cv::Size(), features.working_scale, features.working_scale, cv::INTER_AREA);
    gray = small;
  }

  // Detection runs on the (possibly distorted) image; only keypoint positions are undistorted,
  // which avoids resampling the image and keeps SIFT's sub-pixel localisation intact.
  const cv::Ptr<cv::SIFT> sift = cv::SIFT::create(std::max(0, options.max_features), 3, options.contrast_threshold);
  std::vector<cv::KeyPoint> keypoints;
  sift->detectAndCompute(gray, cv::noArray(), keypoints, features.descriptors);
  if (features.descriptors.type() != CV_32F) features.descriptors.convertTo(features.descriptors, CV_32F);
  toRootSift(features.descriptors);

  // Working pixel -> original pixel, keeping pixel edges aligned (centres at integers).
  const double sx = static_cast<double>(gray.cols) / rgb.cols, sy = static_cast<double>(gray.rows) / rgb.rows;
  std::vector<Eigen::Vector2d> original(keypoints.size());
  for (size_t i = 0; i < keypoints.size(); ++i)
    original[i] = {(keypoints[i].pt.x + 0.5) / sx - 0.5, (keypoints[i].pt.y + 0.5) / sy - 0.5};
  features.pixels = undistortPixels(frame.intrinsics, original);
  return features;
}

struct SiftBaselineSource::MappingFrame {
  size_t frame_index = 0;
  Intrinsics camera;  // undistorted, original resolution
  SiftFeatures features;
  std::unique_ptr<cv::flann::Index> index;
  Eigen::VectorXf global;  // VLAD descriptor, empty when retrieval is not needed
  // links[k]: (mapping frame position, keypoint) pairs keypoint k matched in other mapping frames.
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> links;
};

// VLAD (Jegou et al. 2010) over a small k-means vocabulary of the mapping descriptors, with
// intra-normalisation and signed square roots: a global descriptor that needs no network and is
// cheap for the few hundred mapping frames these scenes have.
struct SiftBaselineSource::Vocabulary {
  RowMatrixXf centres;  // words x 128
  Eigen::VectorXf squared_norms;

  Eigen::VectorXf describe(const cv::Mat& descriptors) const {
    const long words = centres.rows(), dims = centres.cols();
    Eigen::MatrixXf residuals = Eigen::MatrixXf::Zero(dims, words);
    if (descriptors.rows > 0) {
      const auto D = asEigen(descriptors);
      // argmin |d - c|^2 = argmax 2 d.c - |c|^2
      const Eigen::MatrixXf scores = (2.0f * (D * centres.transpose())).rowwise() - squared_norms.transpose();
      for (long i = 0; i < D.rows(); ++i) {
        Eigen::Index word;
        scores.row(i).maxCoeff(&word);
        residuals.col(word) += (D.row(i) - centres.row(word)).transpose();
      }
    }
    for (long w = 0; w < words; ++w) {
      const float n = residuals.col(w).norm();
      if (n > 0) residuals.col(w) /= n;
    }
    Eigen::VectorXf v = Eigen::Map<Eigen::VectorXf>(residuals.data(), residuals.size());
    v = v.unaryExpr([](float x) { return std::copysign(std::sqrt(std::abs(x)), x); });
    const float n = v.norm();
    if (n > 0) v /= n;
    return v;
  }
};

SiftBaselineSource::SiftBaselineSource(SiftBaselineOptions options) : options_(options) {}
SiftBaselineSource::~SiftBaselineSource() = default;

void SiftBaselineSource::prepare(const Scene& scene) {
  prepared_scene_ = nullptr;
  mapping_.clear();
  vocabulary_.reset();
  const std::vector<size_t> mapping = scene.mappingIndices();
  if (mapping.empty()) throw InputError(scene.root.string() + ": sift-baseline needs mapping frames, and the scene has none");

  for (size_t index : mapping) {
    const Frame& frame = scene.frames[index];
    if (!frame.intrinsics.isValid())
      throw InputError(scene.root.string() + ": frame '" + frame.name + "': invalid intrinsics");
    MappingFrame m;
    m.frame_index = index;
    m.camera = frame.intrinsics.undistorted();
    m.features = extractSiftFeatures(frame, options_);
    // The ratio test needs two neighbours; a blank image cannot help any query.
    if (m.features.descriptors.rows < 2) continue;
    m.index = buildIndex(m.features.descriptors, options_);
    mapping_.push_back(std::move(m));
  }

  const size_t needs_ranking = static_cast<size_t>(
      std::max(0, std::min(options_.retrieval_top_k, options_.map_neighbours + 1)));
  if (mapping_.size() > needs_ranking) {
    // Training set: an equal random share of every mapping frame's descriptors.
    size_t total = 0;
    for (const MappingFrame& m : mapping_) total += m.features.descriptors.rows;
    const double keep = std::min(1.0, static_cast<double>(options_.vocabulary_training_descriptors) / total);
    std::mt19937_64 rng(options_.seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    cv::Mat training;
    for (const MappingFrame& m : mapping_)
      for (int r = 0; r < m.features.descriptors.rows; ++r)
        if (unit(rng) < keep) training.push_back(m.features.descriptors.row(r));
    const int words = std::max(1, std::min(options_.vocabulary_size, training.rows));
    cv::Mat labels, centres;
    // cv::kmeans draws from the thread's cv::RNG; seed it and put the caller's state back.
    const uint64_t saved_state = cv::theRNG().state;
    cv::theRNG().state = options_.seed + 0x9E3779B97F4A7C15ULL;
    cv::kmeans(training, words, labels, cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 1e-4), 1,
               cv::KMEANS_PP_CENTERS, centres);
    cv::theRNG().state = saved_state;
    vocabulary_ = std::make_unique<Vocabulary>();
    vocabulary_->centres = asEigen(centres);
    vocabulary_->squared_norms = vocabulary_->centres.rowwise().squaredNorm();
    for (MappingFrame& m : mapping_) m.global = vocabulary_->describe(m.features.descriptors);
  }
  linkMappingFrames();
  prepared_scene_ = &scene;
}

void SiftBaselineSource::linkMappingFrames() {
  for (MappingFrame& m : mapping_) m.links.assign(m.features.descriptors.rows, {});
  const size_t neighbours = static_cast<size_t>(std::max(0, options_.map_neighbours));
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t i = 0; i < mapping_.size(); ++i) {
    std::vector<size_t> order = rank(mapping_[i].global);
    order.erase(std::remove(order.begin(), order.end(), i), order.end());
    if (order.size() > neighbours) order.resize(neighbours);
    for (size_t j : order) pairs.emplace_back(std::min(i, j), std::max(i, j));
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  for (const auto& [i, j] : pairs) {
    MappingFrame& a = mapping_[i];
    MappingFrame& b = mapping_[j];
    for (const auto& [ka, kb] : matchDescriptors(a.features.descriptors, *b.index, b.features.descriptors.rows, options_)) {
      a.links[ka].emplace_back(static_cast<uint32_t>(j), static_cast<uint32_t>(kb));
      b.links[kb].emplace_back(static_cast<uint32_t>(i), static_cast<uint32_t>(ka));
    }
  }
}

void SiftBaselineSource::ensurePrepared(const Scene& scene) {
  if (prepared_scene_ != &scene) prepare(scene);
}

Eigen::VectorXf SiftBaselineSource::describe(const SiftFeatures& features) const {
  return vocabulary_ ? vocabulary_->describe(features.descriptors) : Eigen::VectorXf();
}

std::vector<size_t> SiftBaselineSource::rank(const Eigen::VectorXf& global) const {
  std::vector<size_t> order(mapping_.size());
  std::iota(order.begin(), order.end(), 0);
  if (!vocabulary_) return order;
  std::vector<float> similarity(mapping_.size());
  for (size_t i = 0; i < mapping_.size(); ++i) similarity[i] = mapping_[i].global.dot(global);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return similarity[a] > similarity[b]; });
  return order;
}

std::vector<size_t> SiftBaselineSource::rankMappingFrames(const Scene& scene, size_t query_index) {
  ensurePrepared(scene);
  const std::vector<size_t> order = rank(describe(extractSiftFeatures(scene.frames.at(query_index), options_)));
  std::vector<size_t> frames(order.size());
  for (size_t i = 0; i < order.size(); ++i) frames[i] = mapping_[order[i]].frame_index;
  return frames;
}

Correspondences SiftBaselineSource::correspondences(const Scene& scene, size_t query_index) {
  ensurePrepared(scene);
  const SiftFeatures query = extractSiftFeatures(scene.frames.at(query_index), options_);
  Correspondences out;
  if (query.descriptors.rows == 0) return out;

  std::vector<size_t> selected = rank(describe(query));
  if (options_.retrieval_top_k > 0 && selected.size() > static_cast<size_t>(options_.retrieval_top_k))
    selected.resize(options_.retrieval_top_k);

  // direct[q]: the (mapping frame, keypoint) pairs query keypoint q matched.
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> direct(query.descriptors.rows);
  for (size_t m : selected) {
    MappingFrame& map = mapping_[m];
    for (const auto& [q, k] : matchDescriptors(query.descriptors, *map.index, map.features.descriptors.rows, options_))
      direct[q].emplace_back(static_cast<uint32_t>(m), static_cast<uint32_t>(k));
  }

  TriangulationOptions triangulation;
  triangulation.min_angle_deg = options_.min_triangulation_angle_deg;
  std::vector<std::pair<uint32_t, uint32_t>> track;
  std::vector<Observation> observations;
  std::vector<bool> inliers;
  for (size_t q = 0; q < direct.size(); ++q) {
    if (direct[q].empty()) continue;
    // The track: the query's direct matches first, then what those keypoints matched in the map.
    track = direct[q];
    for (const auto& [m, k] : direct[q])
      track.insert(track.end(), mapping_[m].links[k].begin(), mapping_[m].links[k].end());
    // One keypoint per mapping frame: a second one in the same frame is a SIFT duplicate or a
    // contradiction, and either way would only make the robust triangulation slower.
    std::vector<std::pair<uint32_t, uint32_t>> unique;
    for (const auto& view : track)
      if (std::none_of(unique.begin(), unique.end(), [&](const auto& kept) { return kept.first == view.first; }))
        unique.push_back(view);
    if (unique.size() > options_.max_track_views) unique.resize(options_.max_track_views);
    if (unique.size() < 2) continue;

    observations.clear();
    double finest_scale = 0;
    for (const auto& [m, k] : unique) {
      const MappingFrame& map = mapping_[m];
      observations.emplace_back(map.camera, scene.frames[map.frame_index].camera_to_world, map.features.pixels[k]);
      finest_scale = std::max(finest_scale, map.features.working_scale);
    }
    triangulation.max_reprojection_error_px = options_.max_reprojection_error_px / finest_scale;
    const std::optional<Eigen::Vector3d> point = triangulateRobust(observations, triangulation, &inliers);
    if (!point) continue;
    // The point must explain at least one of the query's own matches, or it belongs to a
    // different keypoint than the one the query saw.
    bool explains_query_match = false;
    for (size_t v = 0; v < direct[q].size() && v < inliers.size(); ++v) explains_query_match = explains_query_match || inliers[v];
    if (!explains_query_match) continue;
    const auto views = std::count(inliers.begin(), inliers.end(), true);
    out.add(query.pixels[q], *point, static_cast<float>(1 + views));
  }
  return out;
}

}  // namespace ffloc
