// Image header sniffing: the size a PNG or JPEG declares, read before any decoding (the
// server refuses oversized images by it).
#include "../support/fuzz_support.h"
#include "ffloc/io/image_size.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::optional<cv::Size> declared = encodedImageSize(std::string(reinterpret_cast<const char*>(data), size));
  if (declared && (declared->width <= 0 || declared->height <= 0)) std::abort();
  return 0;
}
