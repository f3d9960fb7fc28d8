// Host side of fast_div() in shaders/common.glsl: multiply-high constants
// for n / d in shaders, m = ceil(2^(31 + l) / d), l = ceil(log2 d); exact for
// n < 2^31 (Granlund & Montgomery 1994). Integer division is scalarized and
// slow on llvmpipe.
#pragma once

#include <cstdint>

namespace vkjr2::kernels {

struct Magic {
  std::uint32_t m = 0, l = 0;
};

inline Magic magic(std::uint64_t d) {
  std::uint32_t l = 0;
  while ((std::uint64_t(1) << l) < d) ++l;
  return {static_cast<std::uint32_t>(((std::uint64_t(1) << (31 + l)) + d - 1) / d), l};
}

}  // namespace vkjr2::kernels
