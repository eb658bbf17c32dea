#pragma once

#include <ATen/core/Tensor.h>

#include <string>
#include <utility>
#include <vector>

#include "ffloc/model/fastforward_model.h"

namespace ffloc {

// The model's parameters that training updates, by state_dict name, as the model's own tensors
// (an optimiser step on them is a step on the model): the decoder with its embedding and norm,
// the query DPT head, the ray MLP and the map head; the patch embedding and encoder too when
// `include_encoder`. mask_token is never used, so it is left out. A non-empty `only_prefixes`
// keeps just the parameters whose names start with one of them; a prefix that names none is a
// TrainingConfigError of `origin`'s field 'trained_parameters'.
std::vector<std::pair<std::string, at::Tensor>> trainableParameters(FastForwardModel& model, bool include_encoder,
                                                                    const std::vector<std::string>& only_prefixes = {},
                                                                    const std::string& origin = "training config");

// Encoder parameters: what the paper freezes.
bool isEncoderParameter(const std::string& name);

}  // namespace ffloc
