#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

namespace ffloc {

struct VladOptions {
  int words = 64;  // k-means visual words
  int training_descriptors = 40000;  // sampled evenly from every image
  uint64_t seed = 0;
};

// VLAD (Jegou et al. 2010) over a small k-means vocabulary of local descriptors, with
// intra-normalisation and signed square roots: a global descriptor that needs no network and is
// cheap for the few hundred images a scene map has. Cosine similarity ranks images.
class VladVocabulary {
 public:
  using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  VladVocabulary() = default;
  explicit VladVocabulary(RowMatrixXf centres);

  // k-means on an even random share of every image's descriptors (CV_32F rows).
  static VladVocabulary train(const std::vector<const cv::Mat*>& descriptors, const VladOptions& options = {});
  // The same, with image i's `rows_per_image[i]` descriptors made by `descriptors_of(i)` when
  // they are sampled: only one image's descriptors exist at a time beside the sample.
  static VladVocabulary train(const std::vector<int>& rows_per_image,
                              const std::function<cv::Mat(size_t)>& descriptors_of, const VladOptions& options = {});

  bool empty() const { return centres_.rows() == 0; }
  const RowMatrixXf& centres() const { return centres_; }
  size_t descriptorSize() const { return static_cast<size_t>(centres_.size()); }

  // Unit-norm VLAD vector of one image's descriptors (zero for an image without any).
  Eigen::VectorXf describe(const cv::Mat& descriptors) const;

 private:
  RowMatrixXf centres_;  // words x descriptor width
  Eigen::VectorXf squared_norms_;
};

// Indices of `database` by decreasing dot product with `query` (ties keep database order).
std::vector<size_t> rankBySimilarity(const std::vector<Eigen::VectorXf>& database, const Eigen::VectorXf& query);

}  // namespace ffloc
