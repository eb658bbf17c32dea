#include "ffloc/data/readers.h"

namespace ffloc {

std::string frameName(const std::filesystem::path& image_path, const std::filesystem::path& root) {
  return image_path.lexically_normal().lexically_relative(root.lexically_normal()).generic_string();
}

Scene emptyScene(const std::filesystem::path& dir, const std::string& format, bool metric) {
  Scene scene;
  scene.root = dir;
  scene.format = format;
  scene.metric = metric;
  auto absolute = std::filesystem::absolute(dir).lexically_normal();
  if (absolute.filename().empty()) absolute = absolute.parent_path();  // "dir/" ends in an empty part
  scene.name = absolute.filename().string();
  return scene;
}

}  // namespace ffloc
