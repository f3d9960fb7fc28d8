// Normalization layers on NCHW f32 tensors.
//
// layer_norm_channels is NAFNet's LayerNorm2d: every pixel's C values are
// normalized by their own mean and variance (biased, over the channels),
// then scaled and shifted per channel:
//   y[n, c, h, w] = gamma[c] · (x − μ[n, h, w]) / sqrt(σ²[n, h, w] + eps) + beta[c].
// Unlike batch norm it has no running statistics, so training and inference
// compute the same thing. A NaN in a pixel makes that pixel's outputs NaN.
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

// x, y: [N, C, H, W]; gamma, beta: [C]; eps > 0. y may not alias x.
void layer_norm_channels(Stream& stream, const Tensor& x, const Tensor& gamma, const Tensor& beta,
                         float eps, const Tensor& y);

// Gradients from dy = dL/dy (the statistics are recomputed from x):
//   dx = (g − mean_c g − x̂ · mean_c(g · x̂)) / sqrt(σ² + eps), g = dy · gamma[c];
//   dgamma[c] = Σ_{n,h,w} dy · x̂, dbeta[c] = Σ_{n,h,w} dy.
// Null outputs are skipped (at least one must be given).
void layer_norm_channels_backward(Stream& stream, const Tensor& x, const Tensor& gamma,
                                  const Tensor& dy, float eps, const Tensor* dx,
                                  const Tensor* dgamma, const Tensor* dbeta);

}  // namespace vkjr2::kernels
