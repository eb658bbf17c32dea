#include "ffloc/classical/descriptor_matching.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/core/utility.hpp>
#include <opencv2/flann.hpp>

#include <cblas.h>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

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

constexpr int kDims = 128;

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define FFLOC_HAS_VNNI_KERNEL 1

constexpr int kChunks = kDims / 4;  // VNNI multiplies and sums 4 bytes at a time
constexpr int kBlockTargets = 16;  // one 4-byte chunk of 16 targets fills a 512-bit vector
constexpr int kKernelRows = 8;     // query rows per kernel pass: 8 x 2 blocks = 16 accumulators
constexpr int kKernelBlocks = 2;

// The targets as the VNNI kernel reads them: blocks of 16 rows, and in a block chunk c of every
// row side by side, so one load brings the same 4 dimensions of 16 targets. The kernel takes the
// query as signed bytes (q - 128), so each dot product is short of 128 times its target's sum:
// its offset.
struct PackedTargets {
  int blocks = 0;  // a multiple of kKernelBlocks; rows past the last target are zero
  std::vector<uint8_t> bytes;
  std::vector<int32_t> offsets;
};

PackedTargets packTargets(const cv::Mat& targets) {
  PackedTargets packed;
  const int blocks = (targets.rows + kBlockTargets - 1) / kBlockTargets;
  packed.blocks = (blocks + kKernelBlocks - 1) / kKernelBlocks * kKernelBlocks;
  packed.bytes.assign(static_cast<size_t>(packed.blocks) * kChunks * 64, 0);
  packed.offsets.assign(static_cast<size_t>(packed.blocks) * kBlockTargets, 0);
  for (int t = 0; t < targets.rows; ++t) {
    const uint8_t* row = targets.ptr<uint8_t>(t);
    uint8_t* block = packed.bytes.data() + static_cast<size_t>(t / kBlockTargets) * kChunks * 64;
    for (int c = 0; c < kChunks; ++c) std::memcpy(block + c * 64 + (t % kBlockTargets) * 4, row + c * 4, 4);
    int32_t sum = 0;
    for (int d = 0; d < kDims; ++d) sum += row[d];
    packed.offsets[t] = 128 * sum;
  }
  return packed;
}

// Dot products of kKernelRows signed query rows with every packed target, as floats (exact:
// at most 128 x 255^2 < 2^24), row r at out + r * stride.
__attribute__((target("avx512f,avx512bw,avx512vnni"))) void vnniProducts(const int8_t* query, const PackedTargets& packed,
                                                                          float* out, size_t stride) {
  for (int b = 0; b < packed.blocks; b += kKernelBlocks) {
    __m512i offsets[kKernelBlocks], accumulators[kKernelRows][kKernelBlocks];
    const uint8_t* blocks[kKernelBlocks];
    for (int k = 0; k < kKernelBlocks; ++k) {
      blocks[k] = packed.bytes.data() + static_cast<size_t>(b + k) * kChunks * 64;
      offsets[k] = _mm512_loadu_si512(packed.offsets.data() + (b + k) * kBlockTargets);
      for (int r = 0; r < kKernelRows; ++r) accumulators[r][k] = _mm512_setzero_si512();
    }
    for (int c = 0; c < kChunks; ++c) {
      __m512i targets[kKernelBlocks];
      for (int k = 0; k < kKernelBlocks; ++k) targets[k] = _mm512_loadu_si512(blocks[k] + c * 64);
      for (int r = 0; r < kKernelRows; ++r) {
        int32_t chunk;
        std::memcpy(&chunk, query + r * kDims + c * 4, 4);
        const __m512i repeated = _mm512_set1_epi32(chunk);
        for (int k = 0; k < kKernelBlocks; ++k)
          accumulators[r][k] = _mm512_dpbusd_epi32(accumulators[r][k], targets[k], repeated);
      }
    }
    for (int r = 0; r < kKernelRows; ++r)
      for (int k = 0; k < kKernelBlocks; ++k)
        _mm512_storeu_ps(out + r * stride + (b + k) * kBlockTargets,
                         // maskz: the plain conversion trips GCC 12's false "may be used uninitialized"
                         _mm512_maskz_cvtepi32_ps(0xFFFF, _mm512_add_epi32(accumulators[r][k], offsets[k])));
  }
}
#endif

float squaredNorm(const uint8_t* row) {
  int32_t sum = 0;
  for (int d = 0; d < kDims; ++d) sum += row[d] * row[d];
  return static_cast<float>(sum);
}

}  // namespace

bool hasVnniProducts() {
#ifdef FFLOC_HAS_VNNI_KERNEL
  static const bool has = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                          __builtin_cpu_supports("avx512vnni");
  return has;
#else
  return false;
#endif
}

std::vector<std::vector<std::pair<int, int>>> matchExactly(const cv::Mat& query, const std::vector<const cv::Mat*>& images,
                                                           float ratio, ProductKernel kernel,
                                                           std::vector<std::vector<float>>* distance_ratios) {
  std::vector<std::vector<std::pair<int, int>>> matches(images.size());
  if (distance_ratios) distance_ratios->assign(images.size(), {});
  int total = 0;
  std::vector<int> first_row(images.size() + 1, 0);
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i]->rows > 0 && (images[i]->cols != kDims || images[i]->type() != CV_8U))
      throw InputError("descriptors: images to match must be quantized (CV_8U) rows of 128");
    first_row[i] = total;
    total += images[i]->rows;
    first_row[i + 1] = total;
  }
  if (query.rows == 0 || total == 0) return matches;
  if (query.cols != kDims || query.type() != CV_8U)
    throw InputError("descriptors: the query must be quantized (CV_8U) rows of 128");
  cv::Mat targets(total, kDims, CV_8U);
  for (size_t i = 0; i < images.size(); ++i)
    if (images[i]->rows > 0) images[i]->copyTo(targets.rowRange(first_row[i], first_row[i + 1]));
  const cv::Mat contiguous_query = query.isContinuous() ? query : query.clone();
  std::vector<float> target_norms(total), query_norms(query.rows);
  for (int t = 0; t < total; ++t) target_norms[t] = squaredNorm(targets.ptr<uint8_t>(t));
  for (int q = 0; q < query.rows; ++q) query_norms[q] = squaredNorm(contiguous_query.ptr<uint8_t>(q));

  // Per query row and image: the nearest target row (-1: the ratio test failed) and its distance.
  const float max_squared_ratio = ratio * ratio;
  const size_t image_count = images.size();
  std::vector<int> nearest(static_cast<size_t>(query.rows) * image_count, -1);
  std::vector<float> nearest_distance(nearest.size(), 0.0f);
  std::vector<float> nearest_ratio(distance_ratios ? nearest.size() : 0, 0.0f);
  const auto scan = [&](int q, const float* products) {
    for (size_t i = 0; i < image_count; ++i) {
      if (images[i]->rows < 2) continue;  // the ratio test needs two neighbours
      const NearestTwo found =
          nearestTwo(products + first_row[i], target_norms.data() + first_row[i], query_norms[q], images[i]->rows);
      if (found.index < 0 || !(found.nearest < max_squared_ratio * found.second)) continue;
      nearest[static_cast<size_t>(q) * image_count + i] = found.index;
      nearest_distance[static_cast<size_t>(q) * image_count + i] = found.nearest;
      if (distance_ratios)
        nearest_ratio[static_cast<size_t>(q) * image_count + i] =
            found.second > 0 ? std::sqrt(found.nearest / found.second) : 0.0f;
    }
  };

#ifdef FFLOC_HAS_VNNI_KERNEL
  if (kernel == ProductKernel::kFastest && hasVnniProducts()) {
    const PackedTargets packed = packTargets(targets);
    const size_t stride = static_cast<size_t>(packed.blocks) * kBlockTargets;
    const int groups = (query.rows + kKernelRows - 1) / kKernelRows;
    // A group's products (8 rows of all targets: 448 KB on redkitchen) stay in the core's L2
    // until the scan has read them. One stripe a thread: one buffer each.
    cv::parallel_for_(cv::Range(0, groups), [&](const cv::Range& range) {
      std::vector<int8_t> signed_rows(kKernelRows * kDims);
      std::vector<float> products(kKernelRows * stride);
      for (int g = range.start; g < range.end; ++g) {
        const int begin = g * kKernelRows, rows = std::min(kKernelRows, query.rows - begin);
        std::fill(signed_rows.begin(), signed_rows.end(), int8_t{0});
        for (int r = 0; r < rows; ++r) {
          const uint8_t* row = contiguous_query.ptr<uint8_t>(begin + r);
          for (int d = 0; d < kDims; ++d) signed_rows[r * kDims + d] = static_cast<int8_t>(row[d] - 128);
        }
        vnniProducts(signed_rows.data(), packed, products.data(), stride);
        for (int r = 0; r < rows; ++r) scan(begin + r, products.data() + r * stride);
      }
    }, cv::getNumThreads());
  } else
#else
  (void)kernel;  // one kernel only
#endif
  {
    cv::Mat float_query, float_targets;
    contiguous_query.convertTo(float_query, CV_32F);
    targets.convertTo(float_targets, CV_32F);
    constexpr int kBlock = 256;  // query rows per product: 256 x (all targets) floats stay small
    std::vector<float> products(static_cast<size_t>(kBlock) * total);
    for (int begin = 0; begin < query.rows; begin += kBlock) {
      const int rows = std::min(kBlock, query.rows - begin);
      cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, rows, total, kDims, 1.0f, float_query.ptr<float>(begin), kDims,
                  float_targets.ptr<float>(), kDims, 0.0f, products.data(), total);
      // The scan is as long as the product is cheap: spread it over the cores too.
      cv::parallel_for_(cv::Range(0, rows), [&](const cv::Range& range) {
        for (int r = range.start; r < range.end; ++r) scan(begin + r, products.data() + static_cast<size_t>(r) * total);
      });
    }
  }

  // best[i][t]: the query row that matched target row t of image i, closest first.
  std::vector<std::vector<int>> best_query(images.size());
  std::vector<std::vector<float>> best_distance(images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    best_query[i].assign(images[i]->rows, -1);
    best_distance[i].assign(images[i]->rows, std::numeric_limits<float>::infinity());
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
    for (int t = 0; t < images[i]->rows; ++t) {
      const int q = best_query[i][t];
      if (q < 0) continue;
      matches[i].emplace_back(q, t);
      if (distance_ratios) (*distance_ratios)[i].push_back(nearest_ratio[static_cast<size_t>(q) * image_count + i]);
    }
  return matches;
}

}  // namespace ffloc
