#include "ffloc/classical/vlad.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "ffloc/core/random.h"

namespace ffloc {
namespace {

Eigen::Map<const VladVocabulary::RowMatrixXf> asEigen(const cv::Mat& m) {
  return Eigen::Map<const VladVocabulary::RowMatrixXf>(m.ptr<float>(), m.rows, m.cols);
}

}  // namespace

VladVocabulary::VladVocabulary(RowMatrixXf centres)
    : centres_(std::move(centres)), squared_norms_(centres_.rowwise().squaredNorm()) {}

VladVocabulary VladVocabulary::train(const std::vector<const cv::Mat*>& descriptors, const VladOptions& options) {
  std::vector<int> rows;
  for (const cv::Mat* d : descriptors) rows.push_back(d->rows);
  return train(rows, [&descriptors](size_t i) { return *descriptors[i]; }, options);
}

VladVocabulary VladVocabulary::train(const std::vector<int>& rows_per_image,
                                     const std::function<cv::Mat(size_t)>& descriptors_of, const VladOptions& options) {
  size_t total = 0;
  for (int rows : rows_per_image) total += static_cast<size_t>(rows);
  if (total == 0) return {};
  const double keep = std::min(1.0, static_cast<double>(options.training_descriptors) / static_cast<double>(total));
  Rng rng(options.seed);
  cv::Mat training;
  cv::Mat first_row;
  for (size_t i = 0; i < rows_per_image.size(); ++i) {
    if (rows_per_image[i] == 0) continue;
    const cv::Mat d = descriptors_of(i);
    if (first_row.empty()) first_row = d.row(0).clone();
    for (int r = 0; r < d.rows; ++r)
      if (rng.uniform() < keep) training.push_back(d.row(r));
  }
  if (training.rows == 0) training.push_back(first_row);
  const int words = std::max(1, std::min(options.words, training.rows));
  cv::Mat labels, centres;
  // cv::kmeans draws from the thread's cv::RNG; seed it and put the caller's state back.
  const uint64_t saved_state = cv::theRNG().state;
  cv::theRNG().state = options.seed + 0x9E3779B97F4A7C15ULL;
  cv::kmeans(training, words, labels, cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 1e-4), 1,
             cv::KMEANS_PP_CENTERS, centres);
  cv::theRNG().state = saved_state;
  return VladVocabulary(asEigen(centres));
}

Eigen::VectorXf VladVocabulary::describe(const cv::Mat& descriptors) const {
  const long words = centres_.rows(), dims = centres_.cols();
  Eigen::MatrixXf residuals = Eigen::MatrixXf::Zero(dims, words);
  if (descriptors.rows > 0) {
    const auto D = asEigen(descriptors);
    // argmin |d - c|^2 = argmax 2 d.c - |c|^2
    const Eigen::MatrixXf scores = (2.0f * (D * centres_.transpose())).rowwise() - squared_norms_.transpose();
    for (long i = 0; i < D.rows(); ++i) {
      Eigen::Index word;
      scores.row(i).maxCoeff(&word);
      residuals.col(word) += (D.row(i) - centres_.row(word)).transpose();
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

std::vector<size_t> rankBySimilarity(const std::vector<Eigen::VectorXf>& database, const Eigen::VectorXf& query) {
  std::vector<size_t> order(database.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<float> similarity(database.size(), 0.0f);
  for (size_t i = 0; i < database.size(); ++i)
    if (database[i].size() == query.size()) similarity[i] = database[i].dot(query);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return similarity[a] > similarity[b]; });
  return order;
}

}  // namespace ffloc
