#include "ffloc/data/scene.h"

namespace ffloc {

const char* toString(Split split) {
  switch (split) {
    case Split::kMapping: return "mapping";
    case Split::kQuery: return "query";
    case Split::kUnassigned: return "unassigned";
  }
  return "unassigned";
}

std::vector<size_t> Scene::indices(Split split) const {
  std::vector<size_t> out;
  for (size_t i = 0; i < frames.size(); ++i)
    if (frames[i].split == split) out.push_back(i);
  return out;
}

}  // namespace ffloc
