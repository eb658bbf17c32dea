#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <utility>
#include <vector>

namespace ffloc {

struct MatchingOptions {
  float ratio = 0.8f;  // Lowe's ratio test on RootSIFT distances
  int flann_trees = 4;
  int flann_checks = 64;
  uint64_t seed = 0;  // the kd-forest's random split dimensions

  // InputError naming the field for a value out of range (or NaN).
  void check() const;
};

// A kd-forest over one image's descriptors, queried with Lowe's ratio test.
class DescriptorIndex {
 public:
  DescriptorIndex(const cv::Mat& descriptors, const MatchingOptions& options);
  ~DescriptorIndex();
  DescriptorIndex(DescriptorIndex&&) noexcept;
  DescriptorIndex& operator=(DescriptorIndex&&) noexcept;

  int size() const { return rows_; }

  // Ratio-test matches (query row, indexed row). One query row per indexed row: the closest
  // wins, so one keypoint cannot pin several others to its point.
  std::vector<std::pair<int, int>> match(const cv::Mat& query, const MatchingOptions& options) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int rows_ = 0;
};

// How matchExactly computes its dot products. Both give the same exact integers, so the same
// matches on every CPU.
enum class ProductKernel {
  kFastest,  // AVX-512 VNNI where the CPU has it (one instruction: 64 byte products), else BLAS
  kBlas,     // single-precision BLAS on the bytes as floats (exact: every sum stays below 2^24)
};

// Exact ratio-test matching of `query` against several images' descriptors at once, all
// quantized RootSIFT (CV_8U rows of 128, quantizeDescriptors): the squared distances are exact
// integers, then, per image, the two nearest of every query row and the same one-to-one rule as
// DescriptorIndex::match. Exact search finds the true second neighbour, which the kd-forest
// misses often enough to let ambiguous matches through (docs/classical.md). `distance_ratios`,
// when given, receives each match's distance to the nearest over that to the second nearest, in
// the order of the matches.
std::vector<std::vector<std::pair<int, int>>> matchExactly(const cv::Mat& query, const std::vector<const cv::Mat*>& images,
                                                           float ratio, ProductKernel kernel = ProductKernel::kFastest,
                                                           std::vector<std::vector<float>>* distance_ratios = nullptr);

// Whether ProductKernel::kFastest runs the VNNI kernel on this CPU.
bool hasVnniProducts();

}  // namespace ffloc
