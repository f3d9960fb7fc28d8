// Plain C++ reference of kernels/resize (tests and benchmarks only).
#pragma once

#include <vkjr2/kernels/resize.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// x: planes × [h, w] → planes × [oh, ow].
std::vector<float> resize(std::span<const float> x, std::int64_t planes, std::int64_t h,
                          std::int64_t w, std::int64_t oh, std::int64_t ow,
                          kernels::ResizeMode mode);
// Adjoint by scattering each output gradient onto its taps (in double).
std::vector<float> resize_backward(std::span<const float> dy, std::int64_t planes, std::int64_t h,
                                   std::int64_t w, std::int64_t oh, std::int64_t ow,
                                   kernels::ResizeMode mode);

}  // namespace vkjr2::ref
