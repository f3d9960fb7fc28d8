// Plain C++ reference of kernels/softmax (tests only); rows of k, in double.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace vkjr2::ref {

std::vector<float> softmax(std::span<const float> x, std::size_t k, bool log);
std::vector<float> softmax_backward(std::span<const float> y, std::span<const float> dy,
                                    std::size_t k, bool log);

}  // namespace vkjr2::ref
