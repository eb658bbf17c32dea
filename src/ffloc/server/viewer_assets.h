#pragma once

#include <cstddef>
#include <vector>

namespace ffloc {

// A file of the map viewer (src/ffloc/server/viewer), compiled into the server by CMake so that
// the page needs neither the source tree nor the network.
struct ViewerAsset {
  const char* route;  // "/", "/viewer/viewer.js", ...
  const char* content_type;
  const unsigned char* bytes;
  size_t size;
};

const std::vector<ViewerAsset>& viewerAssets();

}  // namespace ffloc
