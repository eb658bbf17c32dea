#include "ffloc/classical/descriptor_matching.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core/utility.hpp>
#include <opencv2/flann.hpp>

#include <cblas.h>

#include "ffloc/core/error.h"

namespace ffloc {

void MatchingOptions::check() const {
  if (!(ratio > 0 && ratio <= 1)) throw InputError("ratio: must be in (0, 1], got " + std::to_string(ratio));
  if (flann_trees < 1) throw InputError("flann_trees: must be at least 1, got " + std::to_string(flann_trees));
  if (flann_checks < 1) throw InputError("flann_checks: must be at least 1, got " + std::to_string(flann_checks));
}

struct DescriptorIndex::Impl {
  cv::Mat descriptors;  // the index keeps pointers into it
  std::unique_ptr<cv::flann::Index> index;
};

DescriptorIndex::DescriptorIndex(const cv::Mat& descriptors, const MatchingOptions& options)
    : impl_(std::make_unique<Impl>()), rows_(descriptors.rows) {
  options.check();
  if (rows_ < 2) return;  // the ratio test needs two neighbours
  impl_->descriptors = descriptors.isContinuous() ? descriptors : descriptors.clone();
  // cvflann draws its random split dimensions from std::rand: seeded right before the build,
  // runs are repeatable.
  cvflann::seed_random(static_cast<unsigned>(options.seed));
  impl_->index = std::make_unique<cv::flann::Index>(impl_->descriptors, cv::flann::KDTreeIndexParams(options.flann_trees),
                                                    cvflann::FLANN_DIST_L2);
}

DescriptorIndex::~DescriptorIndex() = default;
DescriptorIndex::DescriptorIndex(DescriptorIndex&&) noexcept = default;
DescriptorIndex& DescriptorIndex::operator=(DescriptorIndex&&) noexcept = default;

std::vector<std::pair<int, int>> DescriptorIndex::match(const cv::Mat& query, const MatchingOptions& options) const {
  std::vector<std::pair<int, int>> matches;
  if (query.rows == 0 || !impl_->index) return matches;
  cv::Mat indices, distances;
  impl_->index->knnSearch(query, indices, distances, 2, cv::flann::SearchParams(options.flann_checks));
  const float max_squared_ratio = options.ratio * options.ratio;  // FLANN reports squared distances
  std::vector<int> best_query(rows_, -1);
  std::vector<float> best_distance(rows_, std::numeric_limits<float>::infinity());
  for (int q = 0; q < indices.rows; ++q) {
    const int nearest = indices.at<int>(q, 0);
    const float d1 = distances.at<float>(q, 0), d2 = distances.at<float>(q, 1);
    if (nearest < 0 || nearest >= rows_ || !(d1 < max_squared_ratio * d2)) continue;
    if (d1 < best_distance[nearest]) {
      best_distance[nearest] = d1;
      best_query[nearest] = q;
    }
  }
  for (int t = 0; t < rows_; ++t)
    if (best_query[t] >= 0) matches.emplace_back(best_query[t], t);
  return matches;
}

namespace {

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// Compiled twice, for AVX2 and for the baseline, and picked at load time by the CPU: with AVX2's
// blends the lanes below vectorise, and the scan of a redkitchen query's products takes less than
// half the time (docs/classical.md). Not "fma": both versions must round alike.
#define FFLOC_ALSO_FOR_AVX2 __attribute__((target_clones("avx2", "default")))
#else
#define FFLOC_ALSO_FOR_AVX2
#endif

// The two smallest squared distances of one query row to `count` targets, and the first target
// at the smallest.
struct NearestTwo {
  int index = -1;
  float nearest = std::numeric_limits<float>::infinity();
  float second = std::numeric_limits<float>::infinity();
};

// Squared distance to target t: query_norm + target_norms[t] - 2 products[t]. The targets are
// dealt to kLanes independent running minima, which a compiler can keep in vector registers, then
// merged: the result is exactly that of one scan in order (the first target wins a tie, and a
// distance that occurs twice is also the second smallest).
FFLOC_ALSO_FOR_AVX2 NearestTwo nearestTwo(const float* products, const float* target_norms, float query_norm,
                                          int count) {
  constexpr int kLanes = 16;
  float lane_nearest[kLanes], lane_second[kLanes];
  int lane_index[kLanes];
  for (int l = 0; l < kLanes; ++l) {
    lane_nearest[l] = lane_second[l] = std::numeric_limits<float>::infinity();
    lane_index[l] = -1;
  }
  int t = 0;
  for (; t + kLanes <= count; t += kLanes) {
    for (int l = 0; l < kLanes; ++l) {
      const float d = query_norm + target_norms[t + l] - 2.0f * products[t + l];
      const bool closer = d < lane_nearest[l];
      lane_second[l] = closer ? lane_nearest[l] : std::min(lane_second[l], d);
      lane_index[l] = closer ? t + l : lane_index[l];
      lane_nearest[l] = closer ? d : lane_nearest[l];
    }
  }
  NearestTwo found;
  int winner = -1;  // the lane holding found.index
  for (int l = 0; l < kLanes; ++l) {
    if (lane_index[l] < 0) continue;
    if (lane_nearest[l] < found.nearest || (lane_nearest[l] == found.nearest && lane_index[l] < found.index)) {
      found.nearest = lane_nearest[l];
      found.index = lane_index[l];
      winner = l;
    }
  }
  for (int l = 0; l < kLanes; ++l)
    found.second = std::min(found.second, l == winner ? lane_second[l] : lane_nearest[l]);
  for (; t < count; ++t) {
    const float d = query_norm + target_norms[t] - 2.0f * products[t];
    if (d < found.nearest) {
      found.second = found.nearest;
      found.nearest = d;
      found.index = t;
    } else if (d < found.second) {
      found.second = d;
    }
  }
  return found;
}

}  // namespace

std::vector<std::vector<std::pair<int, int>>> matchExactly(const cv::Mat& query, const std::vector<const cv::Mat*>& images,
                                                           float ratio) {
  std::vector<std::vector<std::pair<int, int>>> matches(images.size());
  const int dims = query.cols;
  int total = 0;
  std::vector<int> first_row(images.size() + 1, 0);
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i]->rows > 0 && (images[i]->cols != dims || images[i]->type() != CV_32F))
      throw InputError("descriptors: images to match must be CV_32F with the query's width");
    first_row[i] = total;
    total += images[i]->rows;
    first_row[i + 1] = total;
  }
  if (query.rows == 0 || total == 0) return matches;
  if (query.type() != CV_32F) throw InputError("descriptors: the query must be CV_32F");
  cv::Mat targets(total, dims, CV_32F);
  for (size_t i = 0; i < images.size(); ++i)
    if (images[i]->rows > 0) images[i]->copyTo(targets.rowRange(first_row[i], first_row[i + 1]));
  const cv::Mat contiguous_query = query.isContinuous() ? query : query.clone();
  std::vector<float> target_norms(total), query_norms(query.rows);
  for (int t = 0; t < total; ++t) target_norms[t] = static_cast<float>(cv::norm(targets.row(t), cv::NORM_L2SQR));
  for (int q = 0; q < query.rows; ++q) query_norms[q] = static_cast<float>(cv::norm(contiguous_query.row(q), cv::NORM_L2SQR));

  const float max_squared_ratio = ratio * ratio;
  // best[i][t]: the query row that matched target row t of image i, closest first.
  std::vector<std::vector<int>> best_query(images.size());
  std::vector<std::vector<float>> best_distance(images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    best_query[i].assign(images[i]->rows, -1);
    best_distance[i].assign(images[i]->rows, std::numeric_limits<float>::infinity());
  }
  // Per query row and image: the nearest target row (-1: the ratio test failed) and its distance.
  const size_t image_count = images.size();
  std::vector<int> nearest(static_cast<size_t>(query.rows) * image_count, -1);
  std::vector<float> nearest_distance(nearest.size(), 0.0f);
  constexpr int kBlock = 256;  // query rows per product: 256 x (all targets) floats stay small
  std::vector<float> products(static_cast<size_t>(kBlock) * total);
  for (int begin = 0; begin < query.rows; begin += kBlock) {
    const int rows = std::min(kBlock, query.rows - begin);
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, rows, total, dims, 1.0f, contiguous_query.ptr<float>(begin), dims,
                targets.ptr<float>(), dims, 0.0f, products.data(), total);
    // The scan is as long as the product is cheap: spread it over the cores too.
    cv::parallel_for_(cv::Range(0, rows), [&](const cv::Range& range) {
      for (int r = range.start; r < range.end; ++r) {
        const int q = begin + r;
        const float* row = products.data() + static_cast<size_t>(r) * total;
        for (size_t i = 0; i < image_count; ++i) {
          if (images[i]->rows < 2) continue;  // the ratio test needs two neighbours
          const NearestTwo found = nearestTwo(row + first_row[i], target_norms.data() + first_row[i], query_norms[q],
                                              images[i]->rows);
          if (found.index < 0 || !(found.nearest < max_squared_ratio * found.second)) continue;
          nearest[static_cast<size_t>(q) * image_count + i] = found.index;
          nearest_distance[static_cast<size_t>(q) * image_count + i] = found.nearest;
        }
      }
    });
  }
  for (int q = 0; q < query.rows; ++q)
    for (size_t i = 0; i < image_count; ++i) {
      const int t = nearest[static_cast<size_t>(q) * image_count + i];
      const float d = nearest_distance[static_cast<size_t>(q) * image_count + i];
      if (t >= 0 && d < best_distance[i][t]) {
        best_distance[i][t] = d;
        best_query[i][t] = q;
      }
    }
  for (size_t i = 0; i < images.size(); ++i)
    for (int t = 0; t < images[i]->rows; ++t)
      if (best_query[i][t] >= 0) matches[i].emplace_back(best_query[i][t], t);
  return matches;
}

}  // namespace ffloc
