#include "ffloc/io/half.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

TEST(Half, KnownValues) {
  EXPECT_EQ(floatToHalf(1.0f), 0x3c00);
  EXPECT_EQ(floatToHalf(-2.0f), 0xc000);
  EXPECT_EQ(floatToHalf(65504.0f), 0x7bff);
  EXPECT_EQ(floatToHalf(65520.0f), 0x7c00);  // the tie above the largest half rounds to inf
  EXPECT_EQ(floatToHalf(65519.0f), 0x7bff);
  EXPECT_EQ(floatToHalf(1e10f), 0x7c00);
  EXPECT_EQ(floatToHalf(std::ldexp(1.0f, -24)), 0x0001);  // smallest subnormal
  EXPECT_EQ(floatToHalf(std::ldexp(1.0f, -25)), 0x0000);  // tie to even (zero)
  EXPECT_EQ(floatToHalf(std::ldexp(3.0f, -25)), 0x0002);  // tie to even (two)
  EXPECT_EQ(floatToHalf(-0.0f), 0x8000);
  EXPECT_EQ(floatToHalf(1.0f + std::ldexp(1.0f, -11)), 0x3c00);  // tie to even, down
  EXPECT_EQ(floatToHalf(1.0f + 3 * std::ldexp(1.0f, -11)), 0x3c02);  // tie to even, up
  EXPECT_EQ(floatToHalf(std::numeric_limits<float>::infinity()), 0x7c00);
  EXPECT_TRUE(std::isnan(halfToFloat(floatToHalf(std::numeric_limits<float>::quiet_NaN()))));
  EXPECT_EQ(halfToFloat(0x3555), 0.333251953125f);
  EXPECT_EQ(halfToFloat(0x0001), std::ldexp(1.0f, -24));
  EXPECT_EQ(halfToFloat(0xfc00), -std::numeric_limits<float>::infinity());

  EXPECT_EQ(floatToBfloat16(1.0f), 0x3f80);
  EXPECT_EQ(bfloat16ToFloat(0xc040), -3.0f);
  EXPECT_EQ(floatToBfloat16(1.0f + std::ldexp(1.0f, -8)), 0x3f80);  // tie to even, down
  EXPECT_EQ(floatToBfloat16(1.0f + 3 * std::ldexp(1.0f, -8)), 0x3f82);  // tie to even, up
  EXPECT_EQ(floatToBfloat16(std::numeric_limits<float>::max()), 0x7f80);
  EXPECT_TRUE(std::isnan(bfloat16ToFloat(floatToBfloat16(std::numeric_limits<float>::quiet_NaN()))));
}

TEST(Half, EveryFiniteValueRoundTrips) {
  for (uint32_t bits = 0; bits <= 0xffff; ++bits) {
    const uint16_t h = static_cast<uint16_t>(bits);
    const bool half_nan = (h & 0x7c00) == 0x7c00 && (h & 0x3ff) != 0;
    if (!half_nan) ASSERT_EQ(floatToHalf(halfToFloat(h)), h) << std::hex << bits;
    const bool bf16_nan = (h & 0x7f80) == 0x7f80 && (h & 0x7f) != 0;
    if (!bf16_nan) ASSERT_EQ(floatToBfloat16(bfloat16ToFloat(h)), h) << std::hex << bits;
  }
}

TEST(Half, NarrowingPicksTheNearestHalf) {
  // Compare with the exhaustive nearest neighbour over positive finite halves.
  for (float value : {0.1f, 0.7f, 3.14159f, 1234.567f, 6.1e-5f, 3e-6f, 60000.0f, 2.0009765f}) {
    const float rounded = halfToFloat(floatToHalf(value));
    for (uint32_t h = 0; h < 0x7c00; ++h) {
      EXPECT_LE(std::fabs(rounded - value), std::fabs(halfToFloat(static_cast<uint16_t>(h)) - value))
          << value;
    }
  }
}

// A one-dimensional view of `values`, read as `dtype`.
template <typename T>
TensorView viewOf(const std::vector<T>& values, DType dtype, const std::string& name) {
  TensorView view;
  view.name = name;
  view.dtype = dtype;
  view.shape = {static_cast<int64_t>(values.size())};
  view.data = reinterpret_cast<const uint8_t*>(values.data());
  view.nbytes = values.size() * sizeof(T);
  return view;
}

TEST(Half, ConvertsTensors) {
  const std::vector<uint16_t> halves = {floatToHalf(0.5f), floatToHalf(-4.0f)};
  const TensorView view = viewOf(halves, DType::kF16, "h");
  EXPECT_EQ(toFloat32(view), (std::vector<float>{0.5f, -4.0f}));

  const std::vector<uint8_t> bf16 = castFloatTensor(view, DType::kBF16);
  TensorView bf16_view = view;
  bf16_view.dtype = DType::kBF16;
  bf16_view.data = bf16.data();
  EXPECT_EQ(toFloat32(bf16_view), (std::vector<float>{0.5f, -4.0f}));

  const std::vector<uint8_t> f64 = castFloatTensor(view, DType::kF64);
  EXPECT_EQ(f64.size(), 16u);
  TensorView f64_view = view;
  f64_view.dtype = DType::kF64;
  f64_view.data = f64.data();
  f64_view.nbytes = 16;
  EXPECT_EQ(toFloat32(f64_view), (std::vector<float>{0.5f, -4.0f}));

  TensorView integers = view;
  integers.dtype = DType::kI16;
  EXPECT_THROW(toFloat32(integers), InputError);
  TensorView wrong_size = view;
  wrong_size.nbytes = 2;
  EXPECT_THROW(toFloat32(wrong_size), InputError);
  EXPECT_THROW(castFloatTensor(view, DType::kI32), InputError);

  const std::vector<float> large = {1e5f};
  const TensorView too_large = viewOf(large, DType::kF32, "big");
  EXPECT_THROW(castFloatTensor(too_large, DType::kF16), InputError);
  EXPECT_EQ(castFloatTensor(too_large, DType::kBF16).size(), 2u);

  // A double beyond float's range was written as inf by every narrower cast.
  const std::vector<double> huge = {1.0, 1e300};
  const TensorView too_large_double = viewOf(huge, DType::kF64, "huge");
  for (const DType target : {DType::kF32, DType::kF16, DType::kBF16}) {
    try {
      castFloatTensor(too_large_double, target);
      ADD_FAILURE() << toString(target) << ": 1e300 accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("tensor 'huge': value 1e+300 at element 1 is beyond the F32 range"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace ffloc
