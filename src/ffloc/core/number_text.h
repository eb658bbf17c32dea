#pragma once

#include <string>

namespace ffloc {

// The shortest decimal text that parses back to exactly `value`, so write -> read is lossless and a
// message shows the value read (100.0000001, not the "100" of six significant digits).
std::string formatNumber(double value);

}  // namespace ffloc
