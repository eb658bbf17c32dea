// Image header sniffing: the size a PNG or JPEG declares, as decoded and as stored, read before
// any decoding (the server refuses oversized images by it).
#include "../support/fuzz_support.h"
#include "ffloc/io/image_size.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const std::optional<cv::Size> declared = encodedImageSize(bytes);
  const std::optional<cv::Size> frame = encodedFrameSize(bytes);
  if (declared && (declared->width <= 0 || declared->height <= 0)) std::abort();
  // The size as decoded is known only where the frame's is, and then they agree.
  if (declared && declared != frame) std::abort();
  return 0;
}
