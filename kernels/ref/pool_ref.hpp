// Plain C++ references of kernels/pool (tests and benchmarks only). Shapes
// are NCHW; outputs are sized by the function.
#pragma once

#include <vkjr2/kernels/pool.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

struct PoolResult {
  std::int64_t oh = 0, ow = 0;
  std::vector<float> y;
  std::vector<std::int32_t> indices;  // max pool only
};

PoolResult max_pool2d(std::span<const float> x, std::int64_t planes, std::int64_t h, std::int64_t w,
                      const kernels::Pool2d& p);
std::vector<float> max_pool2d_backward(std::span<const float> dy,
                                       std::span<const std::int32_t> indices, std::int64_t planes,
                                       std::int64_t h, std::int64_t w, const kernels::Pool2d& p);
PoolResult avg_pool2d(std::span<const float> x, std::int64_t planes, std::int64_t h, std::int64_t w,
                      const kernels::Pool2d& p, bool count_include_pad);
std::vector<float> avg_pool2d_backward(std::span<const float> dy, std::int64_t planes,
                                       std::int64_t h, std::int64_t w, const kernels::Pool2d& p,
                                       bool count_include_pad);
std::vector<float> global_avg_pool(std::span<const float> x, std::int64_t planes, std::int64_t hw);

}  // namespace vkjr2::ref
