#include "ffloc/pipeline/prepared_image.h"

#include <c10/core/InferenceMode.h>

#include "ffloc/core/error.h"
#include "ffloc/model/image_tensor.h"

namespace ffloc {

PreparedImage prepareImage(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                           const PreprocessOptions& options) {
  if (rgb.empty()) throwInputError(name, 0, "image is empty");
  if ((intrinsics.width > 0 && intrinsics.width != rgb.cols) ||
      (intrinsics.height > 0 && intrinsics.height != rgb.rows)) {
    throwInputError(name, 0,
                    "image is " + std::to_string(rgb.cols) + "x" + std::to_string(rgb.rows) + " but its intrinsics are for " +
                        std::to_string(intrinsics.width) + "x" + std::to_string(intrinsics.height));
  }
  Intrinsics sized = intrinsics;
  sized.width = rgb.cols;
  sized.height = rgb.rows;
  if (!sized.isValid())
    throwInputError(name, 0, "intrinsics: invalid (need fx, fy > 0 and finite cx, cy)");
  PreparedImage out;
  out.camera = sized.undistorted();
  const cv::Mat undistorted = sized.hasDistortion() ? undistortImage(rgb, sized) : rgb;
  try {
    out.preprocessed = preprocessImage(undistorted, out.camera, options);
  } catch (const InputError& error) {
    throwInputError(name, 0, error.what());
  }
  return out;
}

Dust3rEncoding encodeImage(const FastForwardModel& model, const PreparedImage& image) {
  c10::InferenceMode inference;
  return model.encode(normalizedImageTensor(image.preprocessed.rgb));
}

PreprocessOptions preprocessOptionsFor(const FastForwardModel& model, int long_side) {
  PreprocessOptions options;
  options.long_side = long_side > 0 ? long_side : static_cast<int>(model.config().input_long_side);
  options.patch_size = static_cast<int>(model.config().dust3r.patch_size);
  return options;
}

}  // namespace ffloc
