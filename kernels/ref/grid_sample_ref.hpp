// Plain C++ references of kernels/grid_sample and the bilinear sampler behind
// kernels/warp (tests and benchmarks only). Written after PyTorch's
// grid_sampler_2d CPU kernel (bilinear; zeros/border padding), in double.
#pragma once

#include <vkjr2/kernels/grid_sample.hpp>

#include <span>
#include <vector>

namespace vkjr2::ref {

struct SampleDims {
  int n = 0, c = 0, in_h = 0, in_w = 0, out_h = 0, out_w = 0;
};

// out (N×C×Hout×Wout) = bilinear sample of img (N×C×Hin×Win) at pos
// (N×Hout×Wout×2: x, y in input pixels).
std::vector<float> sample_pixels(std::span<const float> img, std::span<const double> pos,
                                 const SampleDims& d, kernels::SamplePadding padding);
// Gradients of sample_pixels: d_img (N×C×Hin×Win) and d_pos (N×Hout×Wout×2),
// including the border clip gradient (0 where the position was clamped).
void sample_pixels_backward(std::span<const float> img, std::span<const double> pos,
                            std::span<const float> d_out, const SampleDims& d,
                            kernels::SamplePadding padding, std::vector<float>& d_img,
                            std::vector<double>& d_pos);

// grid: N×Hout×Wout×2.
std::vector<float> grid_sample(std::span<const float> input, std::span<const float> grid,
                               const SampleDims& d, kernels::GridSampleOptions options);
void grid_sample_backward(std::span<const float> input, std::span<const float> grid,
                          std::span<const float> d_out, const SampleDims& d,
                          kernels::GridSampleOptions options, std::vector<float>& d_input,
                          std::vector<float>& d_grid);

// theta: N×2×3 → grid N×H×W×2, and its backward.
std::vector<float> affine_grid(std::span<const float> theta, int n, int h, int w,
                               bool align_corners);
std::vector<float> affine_grid_backward(std::span<const float> d_grid, int n, int h, int w,
                                        bool align_corners);

}  // namespace vkjr2::ref
