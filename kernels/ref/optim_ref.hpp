// Plain C++ references of kernels/optim (tests only): the same float
// arithmetic in the same order as the shaders, for bit-close comparisons.
#pragma once

#include <vkjr2/kernels/optim.hpp>

#include <cstdint>
#include <span>

namespace vkjr2::ref {

void sgd_step(std::span<float> p, std::span<const float> g, std::span<float> v,
              const kernels::SgdOptions& o);
void adam_step(std::span<float> p, std::span<const float> g, std::span<float> m, std::span<float> v,
               std::uint32_t step, const kernels::AdamOptions& o);

}  // namespace vkjr2::ref
