// Plain C++ references of kernels/layout (tests and benchmarks only).
#pragma once

#include <vkjr2/kernels/layout.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

struct Nchw {
  std::int64_t n, c, h, w;
  std::int64_t numel() const { return n * c * h * w; }
};

std::vector<float> pad(std::span<const float> x, Nchw s, const kernels::Pad2d& p, float value);
// x[:, c0 : c0 + out.c, row : row + out.h, col : col + out.w].
std::vector<float> slice(std::span<const float> x, Nchw s, const kernels::SliceStart& at, Nchw out);
std::vector<float> concat_channels(std::span<const std::vector<float>> xs,
                                   std::span<const Nchw> shapes);
std::vector<float> channel_affine(std::span<const float> x, Nchw s, std::span<const float> scale,
                                  std::span<const float> bias);
// Sums in double.
void channel_affine_backward(std::span<const float> x, Nchw s, std::span<const float> scale,
                             std::span<const float> dy, std::vector<float>& dx,
                             std::vector<float>& dscale, std::vector<float>& dbias);

// x: [n, c·r², h, w] → [n, c, h·r, w·r] (PyTorch's PixelShuffle), and back.
std::vector<float> pixel_shuffle(std::span<const float> x, Nchw small, int r);
std::vector<float> pixel_unshuffle(std::span<const float> big, Nchw small, int r);

// y[n, c, i, j] = x[n, c, h − 1 − i, w − 1 − j].
std::vector<float> flip_spatial(std::span<const float> x, Nchw s);

}  // namespace vkjr2::ref
