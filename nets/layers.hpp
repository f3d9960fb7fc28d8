// Layers: Modules with named parameters over the differentiable ops.
//
// Initialization follows PyTorch's defaults (uniform ±1/√fan_in for weights
// and biases) from a seed, on the host, so the same seed gives the same
// network on every device. Weight layouts: conv OIHW, linear [in, out]
// (y = x·W, as TF.js and our matmul).
#pragma once

#include <vkjr2/nets/ops.hpp>

#include <cstdint>

namespace vkjr2::nets {

class Conv2d : public Module {
 public:
  // kernels::Conv2dParams carries stride, dilation, padding, groups and the
  // fused activation. in_channels must be a multiple of params.groups.
  Conv2d(const Device& device, int in_channels, int out_channels, int kernel_h, int kernel_w,
         const kernels::Conv2dParams& params, bool bias, std::uint32_t seed);
  // The plan per input shape is made once; the weight's packed form is kept
  // between calls and rebuilt after it changed (Var::version()).
  Var forward(Tape& t, const Var& x) const { return conv2d(t, x, weight, bias, params, &plans_); }

  Var weight;  // [out, in/groups, kh, kw]
  Var bias;    // [out] or undefined
  kernels::Conv2dParams params;

 private:
  ConvPlans plans_;
};

class Linear : public Module {
 public:
  Linear(const Device& device, int in_features, int out_features, bool bias, std::uint32_t seed);
  Var forward(Tape& t, const Var& x) const { return linear(t, x, weight, bias); }

  Var weight;  // [in, out]
  Var bias;    // [out] or undefined
};

// Per-channel y = x·scale + bias (frozen batch norm; face-api's "scale" layers).
class ChannelScale : public Module {
 public:
  ChannelScale(const Device& device, int channels);
  Var forward(Tape& t, const Var& x) const { return channel_affine(t, x, scale, bias); }

  Var scale;  // [C], starts at 1
  Var bias;   // [C], starts at 0
};

// Batch normalization over N, H, W (Ioffe & Szegedy 2015). Training mode
// normalizes with the batch statistics (biased variance) and updates the
// running ones (unbiased variance, PyTorch's convention) by `momentum`;
// eval mode uses the running statistics. Differentiable in both modes.
class BatchNorm2d : public Module {
 public:
  BatchNorm2d(const Device& device, int channels, float momentum = 0.1f, float eps = 1e-5f);
  Var forward(Tape& t, const Var& x) const;

  Var gamma, beta;                // parameters [C]
  Var running_mean, running_var;  // buffers [C]
  float momentum, eps;
};

// Host-side seeded uniform values in [-bound, bound) (the layers' initializer).
std::vector<float> uniform_init(std::size_t n, float bound, std::uint32_t seed);

}  // namespace vkjr2::nets
