#include "ffloc/model/model_options.h"

#include "ffloc/core/error.h"

namespace ffloc {

at::ScalarType parseNetworkDtype(const std::string& name, const std::string& field) {
  if (name == "f32" || name == "fp32" || name == "float32") return at::kFloat;
  if (name == "bf16" || name == "bfloat16") return at::kBFloat16;
  throwInputError(field, 0, "unknown dtype '" + name + "' (expected f32 or bf16, also spelt fp32, float32 and bfloat16)");
}

}  // namespace ffloc
