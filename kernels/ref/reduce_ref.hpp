// Plain C++ references of kernels/reduce (tests only); rows of k elements.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// op: 0 sum, 1 mean, 2 L2 norm, per row (accumulated in double).
std::vector<float> reduce_rows(int op, std::span<const float> x, std::size_t k);
// Max value and index per row: ties to the smallest index, the first NaN wins.
void max_rows(std::span<const float> x, std::size_t k, std::vector<float>& value,
              std::vector<std::int32_t>& index);

}  // namespace vkjr2::ref
