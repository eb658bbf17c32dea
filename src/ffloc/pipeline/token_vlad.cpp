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

TokenVlad::TokenVlad(const MapFile& map, const VladOptions& options) {
  if (map.images.empty()) throw InputError("map: holds no images to learn a token vocabulary from");
  // One image's tokens in float32 at a time: the map's fp16 tokens (memory-mapped, for a large
  // map) are never copied whole.
  const auto tokensOf = [&map](size_t i) { return storedTokenRows(map.images[i], map.token_dim); };
  std::vector<int> rows;
  for (const MapImage& image : map.images) rows.push_back(static_cast<int>(image.tokenCount()));
  vocabulary_ = VladVocabulary::train(rows, tokensOf, options);
  images_.reserve(map.images.size());
  for (size_t i = 0; i < map.images.size(); ++i) images_.push_back(vocabulary_.describe(tokensOf(i)));
}

Eigen::VectorXf TokenVlad::describe(const at::Tensor& tokens) const {
  const at::Tensor rows = tokens.reshape({-1, tokens.size(-1)}).to(at::kFloat).contiguous();
  const cv::Mat view(static_cast<int>(rows.size(0)), static_cast<int>(rows.size(1)), CV_32F, rows.data_ptr<float>());
  return vocabulary_.describe(view);
}

}  // namespace ffloc
