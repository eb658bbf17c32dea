#include "ffloc/train/trainable_parameters.h"

#include "ffloc/train/training_config.h"

namespace ffloc {

bool isEncoderParameter(const std::string& name) {
  return name.rfind("patch_embed.", 0) == 0 || name.rfind("enc_", 0) == 0;
}

std::vector<std::pair<std::string, at::Tensor>> trainableParameters(FastForwardModel& model, bool include_encoder,
                                                                    const std::vector<std::string>& only_prefixes,
                                                                    const std::string& origin) {
  std::vector<std::pair<std::string, at::Tensor>> out;
  std::vector<bool> prefix_used(only_prefixes.size(), false);
  const ParameterTable table = model.parameterTable();
  for (const auto& entry : table.entries()) {
    if (entry.name == "mask_token") continue;
    if (!include_encoder && isEncoderParameter(entry.name)) continue;
    if (!only_prefixes.empty()) {
      bool kept = false;
      for (size_t i = 0; i < only_prefixes.size(); ++i) {
        if (entry.name.rfind(only_prefixes[i], 0) == 0) prefix_used[i] = kept = true;
      }
      if (!kept) continue;
    }
    out.emplace_back(entry.name, *entry.tensor);
  }
  for (size_t i = 0; i < only_prefixes.size(); ++i) {
    if (!prefix_used[i]) {
      throw TrainingConfigError(origin, {"trained_parameters", "'" + only_prefixes[i] + "' names no " +
                                                                   (include_encoder ? "" : "decoder-side ") +
                                                                   "parameter of this model"});
    }
  }
  return out;
}

}  // namespace ffloc
