#include "ffloc/eval/sift_baseline_source.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "ffloc/core/error.h"

namespace ffloc {

struct SiftBaselineSource::MappingFrame {
  size_t frame_index = 0;
  Intrinsics camera;  // undistorted, original resolution
  SiftFeatures features;
  std::unique_ptr<DescriptorIndex> index;
  Eigen::VectorXf global;  // VLAD descriptor, empty when retrieval is not needed
  // links[k]: (mapping frame position, keypoint) pairs keypoint k matched in other mapping frames.
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> links;
};

SiftBaselineSource::SiftBaselineSource(SiftBaselineOptions options) : options_(options) {}

MatchingOptions SiftBaselineSource::matchingOptions() const {
  MatchingOptions matching = options_.matching;
  matching.seed = options_.seed;
  return matching;
}
SiftBaselineSource::~SiftBaselineSource() = default;

void SiftBaselineSource::prepare(const Scene& scene) {
  prepared_scene_ = nullptr;
  mapping_.clear();
  vocabulary_ = VladVocabulary();
  const std::vector<size_t> mapping = scene.mappingIndices();
  if (mapping.empty()) throw InputError(scene.root.string() + ": sift-baseline needs mapping frames, and the scene has none");

  for (size_t index : mapping) {
    const Frame& frame = scene.frames[index];
    if (!frame.intrinsics.isValid())
      throw InputError(scene.root.string() + ": frame '" + frame.name + "': invalid intrinsics");
    MappingFrame m;
    m.frame_index = index;
    m.camera = frame.intrinsics.undistorted();
    m.features = extractSiftFeatures(frame, options_.sift);
    // The ratio test needs two neighbours; a blank image cannot help any query.
    if (m.features.descriptors.rows < 2) continue;
    m.index = std::make_unique<DescriptorIndex>(m.features.descriptors, matchingOptions());
    mapping_.push_back(std::move(m));
  }

  const size_t needs_ranking = static_cast<size_t>(
      std::max(0, std::min(options_.retrieval_top_k, options_.map_neighbours + 1)));
  if (mapping_.size() > needs_ranking) {
    std::vector<const cv::Mat*> descriptors;
    for (const MappingFrame& m : mapping_) descriptors.push_back(&m.features.descriptors);
    VladOptions vocabulary = options_.vocabulary;
    vocabulary.seed = options_.seed;
    vocabulary_ = VladVocabulary::train(descriptors, vocabulary);
    for (MappingFrame& m : mapping_) m.global = vocabulary_.describe(m.features.descriptors);
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
    for (const auto& [ka, kb] : b.index->match(a.features.descriptors, matchingOptions())) {
      a.links[ka].emplace_back(static_cast<uint32_t>(j), static_cast<uint32_t>(kb));
      b.links[kb].emplace_back(static_cast<uint32_t>(i), static_cast<uint32_t>(ka));
    }
  }
}

void SiftBaselineSource::ensurePrepared(const Scene& scene) {
  if (prepared_scene_ != &scene) prepare(scene);
}

Eigen::VectorXf SiftBaselineSource::describe(const SiftFeatures& features) const {
  return vocabulary_.empty() ? Eigen::VectorXf() : vocabulary_.describe(features.descriptors);
}

std::vector<size_t> SiftBaselineSource::rank(const Eigen::VectorXf& global) const {
  if (vocabulary_.empty()) {
    std::vector<size_t> order(mapping_.size());
    std::iota(order.begin(), order.end(), 0);
    return order;
  }
  std::vector<Eigen::VectorXf> database;
  for (const MappingFrame& m : mapping_) database.push_back(m.global);
  return rankBySimilarity(database, global);
}

std::vector<size_t> SiftBaselineSource::rankMappingFrames(const Scene& scene, size_t query_index) {
  ensurePrepared(scene);
  const std::vector<size_t> order = rank(describe(extractSiftFeatures(scene.frames.at(query_index), options_.sift)));
  std::vector<size_t> frames(order.size());
  for (size_t i = 0; i < order.size(); ++i) frames[i] = mapping_[order[i]].frame_index;
  return frames;
}

Correspondences SiftBaselineSource::correspondences(const Scene& scene, size_t query_index) {
  ensurePrepared(scene);
  const SiftFeatures query = extractSiftFeatures(scene.frames.at(query_index), options_.sift);
  Correspondences out;
  if (query.descriptors.rows == 0) return out;

  std::vector<size_t> selected = rank(describe(query));
  if (options_.retrieval_top_k > 0 && selected.size() > static_cast<size_t>(options_.retrieval_top_k))
    selected.resize(options_.retrieval_top_k);

  // direct[q]: the (mapping frame, keypoint) pairs query keypoint q matched.
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> direct(query.descriptors.rows);
  for (size_t m : selected) {
    MappingFrame& map = mapping_[m];
    for (const auto& [q, k] : map.index->match(query.descriptors, matchingOptions()))
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
