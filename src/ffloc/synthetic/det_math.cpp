#include "ffloc/synthetic/det_math.h"

#include <cmath>

namespace ffloc::synthetic {
namespace {

// Taylor series on [-pi/4, pi/4]; the first omitted terms are below 1e-17 there.
double sinKernel(double r) {
  const double r2 = r * r;
  double p = 1.0 / 355687428096000.0;      // 1/17!
  p = p * r2 - 1.0 / 1307674368000.0;      // 1/15!
  p = p * r2 + 1.0 / 6227020800.0;         // 1/13!
  p = p * r2 - 1.0 / 39916800.0;           // 1/11!
  p = p * r2 + 1.0 / 362880.0;             // 1/9!
  p = p * r2 - 1.0 / 5040.0;               // 1/7!
  p = p * r2 + 1.0 / 120.0;                // 1/5!
  p = p * r2 - 1.0 / 6.0;                  // 1/3!
  return r + r * r2 * p;
}

double cosKernel(double r) {
  const double r2 = r * r;
  double p = -1.0 / 20922789888000.0;      // 1/16!
  p = p * r2 + 1.0 / 87178291200.0;        // 1/14!
  p = p * r2 - 1.0 / 479001600.0;          // 1/12!
  p = p * r2 + 1.0 / 3628800.0;            // 1/10!
  p = p * r2 - 1.0 / 40320.0;              // 1/8!
  p = p * r2 + 1.0 / 720.0;                // 1/6!
  p = p * r2 - 1.0 / 24.0;                 // 1/4!
  p = p * r2 + 0.5;                        // 1/2!
  return 1.0 - r2 * p;
}

// x = k * pi/2 + r with |r| <= pi/4; pi/2 split in two (Cody-Waite) so r keeps its precision
// for the angles a scene uses (|x| up to a few hundred radians).
double reduce(double x, long long& quadrant) {
  constexpr double kTwoOverPi = 0.63661977236758134308;
  constexpr double kPiOver2Hi = 1.57079632673412561417;
  constexpr double kPiOver2Lo = 6.07710050650619224932e-11;
  const double k = std::floor(x * kTwoOverPi + 0.5);
  quadrant = static_cast<long long>(k);
  return (x - k * kPiOver2Hi) - k * kPiOver2Lo;
}

}  // namespace

double detSin(double x) {
  long long q = 0;
  const double r = reduce(x, q);
  switch (((q % 4) + 4) % 4) {
    case 0: return sinKernel(r);
    case 1: return cosKernel(r);
    case 2: return -sinKernel(r);
    default: return -cosKernel(r);
  }
}

double detCos(double x) {
  long long q = 0;
  const double r = reduce(x, q);
  switch (((q % 4) + 4) % 4) {
    case 0: return cosKernel(r);
    case 1: return -sinKernel(r);
    case 2: return -cosKernel(r);
    default: return sinKernel(r);
  }
}

}  // namespace ffloc::synthetic
