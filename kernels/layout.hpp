// Layout ops on NCHW tensors: constant padding, concatenation along
// channels, channel/spatial slicing, and the per-channel affine map
// y = x·scale[c] + bias[c] (frozen batch norm); forward and backward.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>
#include <span>

namespace vkjr2::kernels {

// Pixels added on each side (all ≥ 0).
struct Pad2d {
  std::int32_t top = 0, bottom = 0, left = 0, right = 0;
};

// y[n, c, i, j] = x[n, c, i − top, j − left] inside, `value` outside.
// x: [N, C, H, W], y: [N, C, H + top + bottom, W + left + right].
void pad(Stream& stream, const Tensor& x, const Pad2d& p, float value, const Tensor& y);
// dx = the interior of dy (the padding's gradient is dropped).
void pad_backward(Stream& stream, const Tensor& dy, const Pad2d& p, const Tensor& dx);

// y = [x_0, x_1, ...] along C. Every x_k: [N, C_k, H, W]; y: [N, Σ C_k, H, W].
void concat_channels(Stream& stream, std::span<const Tensor> xs, const Tensor& y);
// dx_k = dy[:, offset_k : offset_k + C_k].
void concat_channels_backward(Stream& stream, const Tensor& dy, std::span<const Tensor> dxs);

// Start of a slice; its extent is the output's shape.
struct SliceStart {
  std::int64_t channel = 0, row = 0, col = 0;
};
// y[n, c, i, j] = x[n, c + s.channel, i + s.row, j + s.col]. x: [N, C, H, W];
// y: [N, C', H', W'] lying inside x (channel range and spatial crop).
void slice(Stream& stream, const Tensor& x, const SliceStart& s, const Tensor& y);
// dx = dy placed at s, zero elsewhere (dx fully overwritten).
void slice_backward(Stream& stream, const Tensor& dy, const SliceStart& s, const Tensor& dx);

// y[n, c, i, j] = x[n, c, i, j]·scale[c] + bias[c]. scale, bias: [C] (any
// shape with C elements). x, y: [N, C, H, W], distinct tensors.
void channel_affine(Stream& stream, const Tensor& x, const Tensor& scale, const Tensor& bias,
                    const Tensor& y);
// Gradients of channel_affine: dx = dy·scale[c]; dscale[c] = Σ_{n,i,j} dy·x;
// dbias[c] = Σ_{n,i,j} dy (fixed-order reductions, deterministic). Pass
// nullptr for a gradient that is not wanted.
void channel_affine_backward(Stream& stream, const Tensor& x, const Tensor& scale, const Tensor& dy,
                             const Tensor* dx, const Tensor* dscale, const Tensor* dbias);

// y[n, c, i, j] = x[n, c, H − 1 − i, W − 1 − j] (rotation by 180°; a
// convolution's weight flipped for its backward-data). x, y: [N, C, H, W],
// distinct; the op is its own inverse and backward.
void flip_spatial(Stream& stream, const Tensor& x, const Tensor& y);

// Pixel shuffle with factor r ≥ 1 (PyTorch's PixelShuffle):
//   y[n, c, h·r + i, w·r + j] = x[n, c·r² + i·r + j, h, w],
// x: [N, C·r², H, W] → y: [N, C, H·r, W·r]. pixel_unshuffle is its inverse
// (y: [N, C, H·r, W·r] → x) and each is the other's backward: a
// permutation, so dx = pixel_unshuffle(dy) and vice versa.
void pixel_shuffle(Stream& stream, const Tensor& x, int r, const Tensor& y);
void pixel_unshuffle(Stream& stream, const Tensor& x, int r, const Tensor& y);

}  // namespace vkjr2::kernels
