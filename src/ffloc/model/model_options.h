#pragma once

#include <c10/core/ScalarType.h>

#include <string>

namespace ffloc {

// "f32" / "float32" -> kFloat, "bf16" / "bfloat16" -> kBFloat16; InputError naming `field`
// otherwise.
at::ScalarType parseNetworkDtype(const std::string& name, const std::string& field = "dtype");

}  // namespace ffloc
