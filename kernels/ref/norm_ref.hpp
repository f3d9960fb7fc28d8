// Plain C++ references of kernels/norm (tests and benchmarks only). Statistics
// and sums in double.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// x: [n, c, hw] flattened NCHW.
std::vector<float> layer_norm_channels(std::span<const float> x, std::int64_t n, std::int64_t c,
                                       std::int64_t hw, std::span<const float> gamma,
                                       std::span<const float> beta, double eps);
void layer_norm_channels_backward(std::span<const float> x, std::int64_t n, std::int64_t c,
                                  std::int64_t hw, std::span<const float> gamma,
                                  std::span<const float> dy, double eps, std::vector<float>& dx,
                                  std::vector<float>& dgamma, std::vector<float>& dbeta);

}  // namespace vkjr2::ref
