#include "ffloc/io/half.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

uint32_t floatBits(float value) {
  uint32_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  return bits;
}

float bitsToFloat(uint32_t bits) {
  float value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

// Drops the low `shift` bits of `value`, rounding to nearest with ties to even.
uint32_t shiftRoundEven(uint32_t value, int shift) {
  const uint32_t kept = value >> shift;
  const uint32_t remainder = value & ((1u << shift) - 1);
  const uint32_t half = 1u << (shift - 1);
  return kept + ((remainder > half || (remainder == half && (kept & 1))) ? 1 : 0);
}

void checkFloatView(const TensorView& view) {
  if (!isFloatingPoint(view.dtype)) {
    throw InputError("tensor '" + view.name + "': dtype " + toString(view.dtype) +
                     " is not a floating-point type");
  }
  if (static_cast<uint64_t>(view.numel()) * elementSize(view.dtype) != view.nbytes) {
    throw InputError("tensor '" + view.name + "': " + std::to_string(view.nbytes) +
                     " bytes do not match shape " + view.shapeString());
  }
}

}  // namespace

float halfToFloat(uint16_t bits) {
  const uint32_t sign = static_cast<uint32_t>(bits & 0x8000) << 16;
  const uint32_t exponent = (bits >> 10) & 0x1f;
  const uint32_t mantissa = bits & 0x3ff;
  if (exponent == 0) {
    // Zero or subnormal: mantissa * 2^-24, exact in float32.
    const float magnitude = std::ldexp(static_cast<float>(mantissa), -24);
    return sign ? -magnitude : magnitude;
  }
  if (exponent == 0x1f) return bitsToFloat(sign | 0x7f800000u | (mantissa << 13));
  return bitsToFloat(sign | ((exponent + 112) << 23) | (mantissa << 13));
}

uint16_t floatToHalf(float value) {
  const uint32_t bits = floatBits(value);
  const uint16_t sign = static_cast<uint16_t>((bits >> 16) & 0x8000);
  const uint32_t magnitude = bits & 0x7fffffffu;
  if (magnitude >= 0x7f800000u) {
    if (magnitude == 0x7f800000u) return sign | 0x7c00;
    return sign | 0x7e00 | static_cast<uint16_t>((magnitude >> 13) & 0x3ff);
  }
  if (magnitude >= 0x47800000u) return sign | 0x7c00;  // >= 2^16: beyond rounding to 65504
  const uint32_t exponent = magnitude >> 23;
  if (exponent < 113) {
    // Below 2^-14: a half subnormal, in units of 2^-24.
    const uint32_t mantissa = (magnitude & 0x7fffffu) | 0x800000u;
    const int shift = 126 - static_cast<int>(exponent);
    if (shift > 24) return sign;
    return sign | static_cast<uint16_t>(shiftRoundEven(mantissa, shift));
  }
  // Rebias the exponent; a rounding carry correctly ripples into the exponent (up to infinity).
  const uint32_t rebiased = magnitude - (112u << 23);
  return sign | static_cast<uint16_t>(shiftRoundEven(rebiased, 13));
}

float bfloat16ToFloat(uint16_t bits) { return bitsToFloat(static_cast<uint32_t>(bits) << 16); }

uint16_t floatToBfloat16(float value) {
  const uint32_t bits = floatBits(value);
  if ((bits & 0x7fffffffu) > 0x7f800000u) return static_cast<uint16_t>((bits >> 16) | 0x40);
  return static_cast<uint16_t>(shiftRoundEven(bits, 16));
}

std::vector<float> toFloat32(const TensorView& view) {
  checkFloatView(view);
  const size_t count = static_cast<size_t>(view.numel());
  std::vector<float> values(count);
  switch (view.dtype) {
    case DType::kF32:
      if (count > 0) std::memcpy(values.data(), view.data, count * sizeof(float));
      break;
    case DType::kF16:
    case DType::kBF16:
      for (size_t i = 0; i < count; ++i) {
        uint16_t bits;
        std::memcpy(&bits, view.data + 2 * i, sizeof(bits));
        values[i] = view.dtype == DType::kF16 ? halfToFloat(bits) : bfloat16ToFloat(bits);
      }
      break;
    default:
      for (size_t i = 0; i < count; ++i) {
        double element;
        std::memcpy(&element, view.data + 8 * i, sizeof(element));
        values[i] = static_cast<float>(element);
      }
      break;
  }
  return values;
}

std::vector<uint8_t> castFloatTensor(const TensorView& view, DType target) {
  checkFloatView(view);
  if (!isFloatingPoint(target)) {
    throw InputError("tensor '" + view.name + "': cannot cast to non-floating-point dtype " +
                     toString(target));
  }
  if (target == view.dtype) return std::vector<uint8_t>(view.data, view.data + view.nbytes);
  const size_t count = static_cast<size_t>(view.numel());
  if (view.dtype == DType::kF64) {
    // Every narrower type goes through float: a finite double beyond float's range became inf
    // there, past the F16 test below, and was written as inf without a word.
    for (size_t i = 0; i < count; ++i) {
      double element;
      std::memcpy(&element, view.data + 8 * i, sizeof(element));
      if (std::isfinite(element) && std::abs(element) > std::numeric_limits<float>::max()) {
        std::ostringstream value;
        value << element;
        throw InputError("tensor '" + view.name + "': value " + value.str() + " at element " + std::to_string(i) +
                         " is beyond the F32 range (3.4e38)");
      }
    }
  }
  std::vector<uint8_t> bytes(count * elementSize(target));
  if (view.dtype == DType::kF64 && target == DType::kF32) {
    // Straight from double, avoiding a second rounding through an intermediate.
    for (size_t i = 0; i < count; ++i) {
      double element;
      std::memcpy(&element, view.data + 8 * i, sizeof(element));
      const float narrowed = static_cast<float>(element);
      std::memcpy(bytes.data() + 4 * i, &narrowed, sizeof(narrowed));
    }
    return bytes;
  }
  const std::vector<float> values = toFloat32(view);
  for (size_t i = 0; i < count; ++i) {
    uint8_t* out = bytes.data() + i * elementSize(target);
    switch (target) {
      case DType::kF32:
        std::memcpy(out, &values[i], 4);
        break;
      case DType::kF16: {
        const uint16_t bits = floatToHalf(values[i]);
        if ((bits & 0x7fff) == 0x7c00 && std::isfinite(values[i])) {
          throw InputError("tensor '" + view.name + "': value " + std::to_string(values[i]) +
                           " at element " + std::to_string(i) +
                           " is beyond the F16 range (65504); use BF16 or F32");
        }
        std::memcpy(out, &bits, 2);
        break;
      }
      case DType::kBF16: {
        const uint16_t bits = floatToBfloat16(values[i]);
        std::memcpy(out, &bits, 2);
        break;
      }
      default: {
        const double widened = values[i];
        std::memcpy(out, &widened, 8);
        break;
      }
    }
  }
  return bytes;
}

}  // namespace ffloc
