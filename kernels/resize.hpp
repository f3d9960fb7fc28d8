// Resizing NCHW images: bilinear in the half-pixel, legacy-TF and
// align-corners conventions, and nearest; forward and backward.
#pragma once

#include <vkjr2/kernels/planes.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

// Source coordinate of output pixel d on an axis of `in` input and `out`
// output pixels (computed in fp32, as PyTorch does):
enum class ResizeMode : std::uint32_t {
  // src = (d + 0.5)·in/out − 0.5, clamped to [0, in − 1]: PyTorch
  // align_corners=False, TF half_pixel_centers=True, OpenCV INTER_LINEAR.
  bilinear_half_pixel = 0,
  // src = d·in/out: TF resize_bilinear with align_corners=False,
  // half_pixel_centers=False (legacy TF 1.x, face-api).
  bilinear_legacy = 1,
  // src = d·(in − 1)/(out − 1) (0 when out = 1): align_corners=True.
  bilinear_align_corners = 2,
  // src = min(floor(d·in/out), in − 1): PyTorch "nearest", TF legacy nearest.
  nearest = 3,
};

// y[n, c, :, :] = x[n, c, :, :] resampled to y's H×W. x: [N, C, H, W],
// y: [N, C, OH, OW] (any positive OH, OW). Bilinear taps beyond the last
// pixel clamp to it.
void resize(Stream& stream, const Tensor& x, ResizeMode mode, const Tensor& y);
// A zero canvas of height × width holding x with its top-left pixel at (top, left).
struct ResizeCanvas {
  std::int64_t height = 0, width = 0;
  std::int64_t top = 0, left = 0;
};
// y = resize(x zero-padded to the canvas), in one pass that never builds the
// padded canvas (face-api's padToSquare + resizeBilinear): taps that fall in
// the padding read 0, so the result equals pad then resize exactly. The
// canvas must hold x. Forward only.
void resize_zero_padded(Stream& stream, const Tensor& x, const ResizeCanvas& canvas,
                        ResizeMode mode, const Tensor& y);
// A network's input in one pass: y = resize_zero_padded(x, canvas, mode)
// · scale[c] + shift[c] (per-channel normalization, fma as channel_affine
// computes it), written into the interior of a conv's zero-padded input
// (padded planes of y.shape = [N, C, OH, OW]: Planes::make with the first
// conv's Conv2dPlan::input_layout, or plain ones; a border is left as it is). nonfinite: nullptr,
// or a 1-element tensor set to 1 when any output is NaN or infinite and left as it is otherwise
// (fill it with 0 first). Forward only.
void resize_into_padded(Stream& stream, const Tensor& x, const ResizeCanvas& canvas,
                        ResizeMode mode, const Tensor& scale, const Tensor& shift, const Planes& y,
                        const Tensor* nonfinite = nullptr);
// dx = the adjoint of resize applied to dy, written as a gather over the
// output pixels each input pixel contributes to (deterministic, dx fully
// overwritten). dy: [N, C, OH, OW], dx: [N, C, H, W].
void resize_backward(Stream& stream, const Tensor& dy, ResizeMode mode, const Tensor& dx);

}  // namespace vkjr2::kernels
