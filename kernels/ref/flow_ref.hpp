// Plain C++ reference of kernels/flow (tests and benchmarks only).
#pragma once

#include <vkjr2/kernels/flow.hpp>

#include <span>
#include <vector>

namespace vkjr2::ref {

struct LucasKanadeResult {
  std::vector<double> flow;     // N×2×H×W
  std::vector<double> min_eig;  // N×1×H×W
};

// kernels::lucas_kanade_step in double precision. ref: R×H×W (R = 1 or n),
// img: n×H×W, flow: n×2×H×W.
LucasKanadeResult lucas_kanade_step(std::span<const float> ref, int ref_images,
                                    std::span<const float> img, std::span<const float> flow, int n,
                                    int h, int w, const kernels::LucasKanade& p);

}  // namespace vkjr2::ref
