// Plain C++ reference of kernels/warp (tests and benchmarks only).
#pragma once

#include <vkjr2/kernels/warp.hpp>

#include <span>
#include <vector>

namespace vkjr2::ref {

// img: N×C×H×W, flow: N×2×H×W (dx, dy in pixels) → out N×C×H×W.
std::vector<float> warp(std::span<const float> img, std::span<const float> flow, int n, int c,
                        int h, int w, kernels::SamplePadding padding);
// Gradients of warp for d_out: d_img (N×C×H×W) and d_flow (N×2×H×W).
void warp_backward(std::span<const float> img, std::span<const float> flow,
                   std::span<const float> d_out, int n, int c, int h, int w,
                   kernels::SamplePadding padding, std::vector<float>& d_img,
                   std::vector<float>& d_flow);

}  // namespace vkjr2::ref
