#pragma once

#include <string>

namespace ffloc {

// The shortest decimal text that parses back to exactly `value`, so write -> read is lossless and a
// message shows the value read (100.0000001, not the "100" of six significant digits).
std::string formatNumber(double value);

// `value` to `digits` significant digits (printf's %g) for messages about measured values, where
// "0.100000" and "9.99999974737875e-05" read as machine output.
std::string formatSignificant(double value, int digits = 3);

}  // namespace ffloc
