#pragma once

namespace ffloc::synthetic {

// Sine and cosine from range reduction and a fixed polynomial, using only +, -, * and floor.
// libm's sin and cos may differ in the last bit between library versions; these do not, which
// keeps camera poses (and so every pixel) bit-identical across machines. Accurate to ~1e-15.
double detSin(double x);
double detCos(double x);

constexpr double kPi = 3.14159265358979323846;

inline double degrees(double deg) { return deg * (kPi / 180.0); }

}  // namespace ffloc::synthetic
