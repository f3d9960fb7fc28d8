// Internal to the nets layer (not installed): IEEE 754 binary16 → float, for
// the weight readers (safetensors F16, TF.js float16). Exact for every value,
// subnormals, infinities and NaN included.
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

namespace vkjr2::nets::detail {

inline float half_to_float(std::uint16_t h) {
  const std::uint32_t sign = std::uint32_t(h >> 15) << 31;
  const std::uint32_t exp = (h >> 10) & 0x1f;
  const std::uint32_t mant = h & 0x3ff;
  if (exp == 0) {  // zero or subnormal: mant · 2^−24
    const float v = std::ldexp(float(mant), -24);
    return sign ? -v : v;
  }
  const std::uint32_t bits =
      exp == 31 ? (sign | 0x7f800000u | (mant << 13)) : (sign | ((exp + 112) << 23) | (mant << 13));
  return std::bit_cast<float>(bits);
}

}  // namespace vkjr2::nets::detail
