// Plain C++ reference of kernels/mix (tests only).
#pragma once

#include <vkjr2/kernels/mix.hpp>

#include <span>
#include <vector>

namespace vkjr2::ref {

// planes [K·B, H, W, 2], mix [K, K] → out [B, K, out_h, out_w] and first2 [B, 2, out_h, out_w].
void mix_planes(std::span<const float> planes, std::int64_t plane_h, std::int64_t plane_w,
                std::span<const float> mix, std::int64_t k, const kernels::MixPlanesParams& p,
                std::vector<float>& out, std::vector<float>& first2);

}  // namespace vkjr2::ref
