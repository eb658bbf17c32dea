#pragma once

#include <cstdint>
#include <vector>

#include "ffloc/io/tensor_archive.h"

namespace ffloc {

// IEEE 754 binary16 and bfloat16 <-> float32. Narrowing rounds to nearest, ties to even;
// overflow gives infinity, NaN stays NaN (quiet), subnormals are kept.
float halfToFloat(uint16_t bits);
uint16_t floatToHalf(float value);
float bfloat16ToFloat(uint16_t bits);
uint16_t floatToBfloat16(float value);

// The elements of a floating-point tensor (F32, F16, BF16, F64) as float32, C order. Reads
// with memcpy, so `view.data` may be unaligned. InputError naming the tensor for other dtypes
// or a view whose nbytes does not match its shape.
std::vector<float> toFloat32(const TensorView& view);

// The bytes of a floating-point tensor stored as `target` (F32, F16, BF16 or F64), C order,
// little-endian. Same errors as toFloat32(), and InputError for a finite value beyond the F16
// range (it would silently become infinity).
std::vector<uint8_t> castFloatTensor(const TensorView& view, DType target);

}  // namespace ffloc
