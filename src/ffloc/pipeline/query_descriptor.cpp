#include "ffloc/pipeline/query_descriptor.h"

#include <ATen/core/Tensor.h>
#include <c10/core/InferenceMode.h>

#include "ffloc/pipeline/prepared_image.h"

namespace ffloc {

std::vector<float> encodingDescriptor(const Dust3rEncoding& encoding, const GlobalDescriptorOptions& options) {
  const at::Tensor tokens = encoding.tokens[0].to(at::kFloat).contiguous();  // (T, D)
  return globalDescriptor(tokens.data_ptr<float>(), tokens.size(0), tokens.size(1), options);
}

Dust3rEncoding queryEncoding(const FastForwardModel& model, const cv::Mat& rgb, const Intrinsics& intrinsics,
                             const std::string& name, int long_side) {
  c10::InferenceMode inference;
  const PreparedImage query = prepareImage(rgb, intrinsics, name, preprocessOptionsFor(model, long_side));
  return encodeImage(model, query);
}

std::vector<float> queryDescriptor(const FastForwardModel& model, const cv::Mat& rgb, const Intrinsics& intrinsics,
                                   const std::string& name, int long_side, const GlobalDescriptorOptions& options) {
  return encodingDescriptor(queryEncoding(model, rgb, intrinsics, name, long_side), options);
}

}  // namespace ffloc
