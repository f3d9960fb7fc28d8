// grid_sample and affine_grid with PyTorch semantics (bilinear; zeros or
// border padding; align_corners true or false), forward and backward.
#pragma once

#include <vkjr2/kernels/warp.hpp>
#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

struct GridSampleOptions {
  SamplePadding padding = SamplePadding::zeros;
  // true: -1 and 1 are the centres of the corner pixels; false: their outer
  // edges (PyTorch's default).
  bool align_corners = false;
};

// out[n, c, h, w] = bilinear sample of input[n, c] at grid[n, h, w] = (x, y)
// in normalized coordinates ([-1, 1] spans the image; values outside sample
// the padding). input: N×C×Hin×Win; grid: N×Hout×Wout×2; out: N×C×Hout×Wout.
// A NaN or infinite grid value gives NaN in every channel of that pixel.
void grid_sample(Stream& stream, const Tensor& input, const Tensor& grid, const Tensor& out,
                 GridSampleOptions options = {});

// Gradients of grid_sample given d_out (N×C×Hout×Wout). d_input
// (N×C×Hin×Win) and d_grid (N×Hout×Wout×2) are overwritten; nullptr skips
// one (not both). d_input is summed deterministically in 64-bit fixed point
// (see warp_backward).
void grid_sample_backward(Stream& stream, const Tensor& input, const Tensor& grid,
                          const Tensor& d_out, const Tensor* d_input, const Tensor* d_grid,
                          GridSampleOptions options = {});

// grid[n, h, w] = theta[n] · (x_w, y_h, 1) with x_w, y_h the normalized pixel
// centres (PyTorch affine_grid, 2-D). theta: N×2×3; grid: N×H×W×2 (its
// shape sets the output size).
void affine_grid(Stream& stream, const Tensor& theta, const Tensor& grid, bool align_corners);

// d_theta (N×2×3, overwritten) = Σ_{h,w} d_grid[n, h, w] ⊗ (x_w, y_h, 1).
void affine_grid_backward(Stream& stream, const Tensor& d_grid, const Tensor& d_theta,
                          bool align_corners);

}  // namespace vkjr2::kernels
