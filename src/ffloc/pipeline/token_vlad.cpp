#include "ffloc/pipeline/token_vlad.h"

#include <opencv2/core.hpp>

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

cv::Mat storedTokenRows(const MapImage& image, int token_dim) {
  const cv::Mat half(static_cast<int>(image.tokenCount()), token_dim, CV_16F, const_cast<uint16_t*>(image.tokens.data()));
  cv::Mat rows;
  half.convertTo(rows, CV_32F);
  return rows;
}

}  // namespace

std::vector<float> TokenVlad::learnVocabulary(const MapFile& map) {
  if (map.images.empty()) throw InputError("map: holds no images to learn a token vocabulary from");
  // One image's tokens in float32 at a time: the map's fp16 tokens (memory-mapped, for a large
  // map) are never copied whole.
  std::vector<int> rows;
  for (const MapImage& image : map.images) rows.push_back(static_cast<int>(image.tokenCount()));
  const VladVocabulary vocabulary = VladVocabulary::train(
      rows, [&map](size_t i) { return storedTokenRows(map.images[i], map.token_dim); }, VladOptions{kWords});
  return std::vector<float>(vocabulary.centres().data(), vocabulary.centres().data() + vocabulary.centres().size());
}

TokenVlad::TokenVlad(const MapFile& map) {
  if (map.images.empty()) throw InputError("map: holds no images to rank");
  const std::vector<float> words = map.token_vocabulary.empty() ? learnVocabulary(map) : map.token_vocabulary;
  vocabulary_ = VladVocabulary(Eigen::Map<const VladVocabulary::RowMatrixXf>(
      words.data(), static_cast<Eigen::Index>(words.size() / map.token_dim), map.token_dim));
  images_.reserve(map.images.size());
  for (const MapImage& image : map.images) images_.push_back(vocabulary_.describe(storedTokenRows(image, map.token_dim)));
}

Eigen::VectorXf TokenVlad::describe(const at::Tensor& tokens) const {
  const at::Tensor rows = tokens.reshape({-1, tokens.size(-1)}).to(at::kFloat).contiguous();
  const cv::Mat view(static_cast<int>(rows.size(0)), static_cast<int>(rows.size(1)), CV_32F, rows.data_ptr<float>());
  return vocabulary_.describe(view);
}

}  // namespace ffloc
