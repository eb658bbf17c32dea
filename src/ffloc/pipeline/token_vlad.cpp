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
  std::vector<cv::Mat> tokens;
  tokens.reserve(map.images.size());
  for (const MapImage& image : map.images) tokens.push_back(storedTokenRows(image, map.token_dim));
  std::vector<const cv::Mat*> views;
  for (const cv::Mat& rows : tokens) views.push_back(&rows);
  vocabulary_ = VladVocabulary::train(views, options);
  images_.reserve(tokens.size());
  for (const cv::Mat& rows : tokens) images_.push_back(vocabulary_.describe(rows));
}

Eigen::VectorXf TokenVlad::describe(const at::Tensor& tokens) const {
  const at::Tensor rows = tokens.reshape({-1, tokens.size(-1)}).to(at::kFloat).contiguous();
  const cv::Mat view(static_cast<int>(rows.size(0)), static_cast<int>(rows.size(1)), CV_32F, rows.data_ptr<float>());
  return vocabulary_.describe(view);
}

}  // namespace ffloc
