// Internal to the kernels layer (not installed): the bilinear sampler that
// warp and grid_sample share. Included as "internal/sample.hpp" from
// kernels/*.cpp only.
#pragma once

#include <vkjr2/kernels/warp.hpp>

#include <cstdint>

namespace vkjr2::kernels::detail {

// The bilinear sampler behind warp and grid_sample (shaders/warp_sample*.comp).
struct SampleGeometry {
  std::uint32_t n_batch = 0, channels = 0, in_h = 0, in_w = 0, out_h = 0, out_w = 0;
  bool grid_mode = false;  // coords: false = flow N×2×H×W, true = grid N×Hout×Wout×2
  SamplePadding padding = SamplePadding::zeros;
  bool align_corners = false;  // grid mode only
};
void sample_forward(Stream& stream, const SampleGeometry& g, const Tensor& img,
                    const Tensor& coords, const Tensor& out);
void sample_backward(Stream& stream, const SampleGeometry& g, const Tensor& img,
                     const Tensor& coords, const Tensor& d_out, const Tensor* d_img,
                     const Tensor* d_coords);

}  // namespace vkjr2::kernels::detail
