// Plain C++ references of kernels/adaface (tests only), in double.
#pragma once

#include <vkjr2/kernels/adaface.hpp>

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// ẑ per row; when `update`, running_mean / running_std are updated in place
// (batch mean and unbiased std of the clipped norms) before ẑ is formed.
std::vector<float> adaface_scaler(std::span<const float> norms, float& running_mean,
                                  float& running_std, bool update, const kernels::AdaFaceParams& p);

// Margin logits [rows, classes] and d cos for the upstream gradient dy.
// A label outside [0, classes) gives a NaN row.
std::vector<float> adaface_margin(std::span<const float> cos, std::span<const std::int32_t> labels,
                                  std::span<const float> scaler, std::size_t classes,
                                  const kernels::AdaFaceParams& p);
std::vector<float> adaface_margin_backward(std::span<const float> cos,
                                           std::span<const std::int32_t> labels,
                                           std::span<const float> scaler, std::span<const float> dy,
                                           std::size_t classes, const kernels::AdaFaceParams& p);

}  // namespace vkjr2::ref
