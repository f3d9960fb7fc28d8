// Warp: bilinear resampling of a multi-channel image by a per-pixel
// displacement field (the turbulence tilt), forward and backward.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

// What a bilinear tap outside the image reads.
enum class SamplePadding : std::uint8_t {
  zeros,   // 0
  border,  // the sampling position is clamped to the image first (PyTorch "border")
};

// out[n, c, y, x] = bilinear sample of img[n, c] at (x + flow[n, 0, y, x],
// y + flow[n, 1, y, x]), in pixels (pixel centres at integers).
// img, out: N×C×H×W; flow: N×2×H×W (channel 0 = dx, 1 = dy); f32.
// A NaN or infinite displacement gives NaN in every channel of that pixel;
// NaN in img propagates through the in-range taps that read it, zero-weight taps
// included (as in PyTorch).
void warp(Stream& stream, const Tensor& img, const Tensor& flow, const Tensor& out,
          SamplePadding padding = SamplePadding::border);

// Gradients of warp given d_out (N×C×H×W). d_img (N×C×H×W) and d_flow
// (N×2×H×W) are overwritten; pass nullptr for one that is not needed (not
// both). d_img is summed exactly in 64-bit fixed point, so it is
// deterministic (same bits on every run); a non-finite d_out makes all of
// d_img NaN. d_flow is 0 where the border padding clamped the position.
void warp_backward(Stream& stream, const Tensor& img, const Tensor& flow, const Tensor& d_out,
                   const Tensor* d_img, const Tensor* d_flow,
                   SamplePadding padding = SamplePadding::border);

}  // namespace vkjr2::kernels
