#include "ffloc/train/trainable_parameters.h"

namespace ffloc {

bool isEncoderParameter(const std::string& name) {
  return name.rfind("patch_embed.", 0) == 0 || name.rfind("enc_", 0) == 0;
}

std::vector<std::pair<std::string, at::Tensor>> trainableParameters(FastForwardModel& model, bool include_encoder) {
  std::vector<std::pair<std::string, at::Tensor>> out;
  const ParameterTable table = model.parameterTable();
  for (const auto& entry : table.entries()) {
    if (entry.name == "mask_token") continue;
    if (!include_encoder && isEncoderParameter(entry.name)) continue;
    out.emplace_back(entry.name, *entry.tensor);
  }
  return out;
}

}  // namespace ffloc
