#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/nets/layers.hpp>
#include <vkjr2/runtime/error.hpp>

#include <cmath>
#include <random>
#include <string>

namespace vkjr2::nets {

std::vector<float> uniform_init(std::size_t n, float bound, std::uint32_t seed) {
  std::mt19937 rng(seed);
  // Drawn as integers and scaled by hand: std::uniform_real_distribution is
  // not specified bit-exactly across standard libraries.
  std::vector<float> out(n);
  for (float& v : out) {
    const double u = double(rng()) / 4294967296.0;  // [0, 1)
    v = float((2.0 * u - 1.0) * bound);
  }
  return out;
}

namespace {

void require_positive(const char* op, const char* what, int v) {
  if (v <= 0) {
    throw InvalidArgument(op, std::string(what) + " = " + std::to_string(v) + " must be > 0",
                          "pass a positive size");
  }
}

}  // namespace

Conv2d::Conv2d(const Device& device, int in_channels, int out_channels, int kernel_h, int kernel_w,
               const kernels::Conv2dParams& p, bool with_bias, std::uint32_t seed)
    : params(p) {
  require_positive("nets::Conv2d", "in_channels", in_channels);
  require_positive("nets::Conv2d", "out_channels", out_channels);
  require_positive("nets::Conv2d", "kernel_h", kernel_h);
  require_positive("nets::Conv2d", "kernel_w", kernel_w);
  require_positive("nets::Conv2d", "groups", p.groups);
  if (in_channels % p.groups != 0 || out_channels % p.groups != 0) {
    throw InvalidArgument("nets::Conv2d",
                          "channels " + std::to_string(in_channels) + " → " +
                              std::to_string(out_channels) + " do not divide into " +
                              std::to_string(p.groups) + " groups",
                          "use channel counts that are multiples of groups");
  }
  const int fan_in = in_channels / p.groups * kernel_h * kernel_w;
  const float bound = 1.f / std::sqrt(float(fan_in));
  const Shape ws{out_channels, in_channels / p.groups, kernel_h, kernel_w};
  weight =
      register_parameter("weight", Tensor::from(device, ws, uniform_init(ws.numel(), bound, seed)));
  if (with_bias) {
    bias = register_parameter(
        "bias", Tensor::from(device, Shape{out_channels},
                             uniform_init(std::size_t(out_channels), bound, seed ^ 0x9e3779b9u)));
  }
}

Linear::Linear(const Device& device, int in_features, int out_features, bool with_bias,
               std::uint32_t seed) {
  require_positive("nets::Linear", "in_features", in_features);
  require_positive("nets::Linear", "out_features", out_features);
  const float bound = 1.f / std::sqrt(float(in_features));
  const Shape ws{in_features, out_features};
  weight =
      register_parameter("weight", Tensor::from(device, ws, uniform_init(ws.numel(), bound, seed)));
  if (with_bias) {
    bias = register_parameter(
        "bias", Tensor::from(device, Shape{out_features},
                             uniform_init(std::size_t(out_features), bound, seed ^ 0x9e3779b9u)));
  }
}

ChannelScale::ChannelScale(const Device& device, int channels) {
  require_positive("nets::ChannelScale", "channels", channels);
  scale = register_parameter("scale", Tensor::from(device, Shape{channels},
                                                   std::vector<float>(std::size_t(channels), 1.f)));
  bias = register_parameter("bias", Tensor::from(device, Shape{channels},
                                                 std::vector<float>(std::size_t(channels), 0.f)));
}

BatchNorm2d::BatchNorm2d(const Device& device, int channels, float momentum_, float eps_)
    : momentum(momentum_), eps(eps_) {
  require_positive("nets::BatchNorm2d", "channels", channels);
  if (!(momentum > 0.f && momentum <= 1.f) || !(eps > 0.f)) {
    throw InvalidArgument("nets::BatchNorm2d", "momentum must be in (0, 1] and eps > 0",
                          "use e.g. momentum 0.1, eps 1e-5");
  }
  const auto c = std::size_t(channels);
  gamma = register_parameter("weight",
                             Tensor::from(device, Shape{channels}, std::vector<float>(c, 1.f)));
  beta =
      register_parameter("bias", Tensor::from(device, Shape{channels}, std::vector<float>(c, 0.f)));
  running_mean = register_buffer("running_mean",
                                 Tensor::from(device, Shape{channels}, std::vector<float>(c, 0.f)));
  running_var = register_buffer("running_var",
                                Tensor::from(device, Shape{channels}, std::vector<float>(c, 1.f)));
}

Var BatchNorm2d::forward(Tape& t, const Var& x) const {
  const Shape& s = x.shape();
  if (s.rank() != 4 || s[1] != gamma.numel()) {
    throw InvalidArgument(
        "nets::BatchNorm2d",
        "x has shape " + s.str() + "; expected [N, " + std::to_string(gamma.numel()) + ", H, W]",
        "pass NCHW input with the layer's channel count");
  }
  if (!training()) {
    // scale = γ / √(var + eps), shift = β − mean·scale; gradients still reach x, γ and β.
    const Var inv = exp(t, scale_shift(t, log(t, scale_shift(t, running_var, 1.f, eps)), -0.5f));
    const Var scale = mul(t, gamma, inv);
    const Var shift = sub(t, beta, mul(t, running_mean, scale));
    return channel_affine(t, x, scale, shift);
  }
  const std::int64_t m = s[0] * s[2] * s[3];
  if (m < 2) {
    throw InvalidArgument("nets::BatchNorm2d", "training needs more than one value per channel",
                          "use a larger batch or eval mode");
  }
  const float inv_m = 1.f / float(m);
  const Var mean = scale_shift(t, sum_channels(t, x), inv_m);
  const Var centred = add_channel(t, x, scale_shift(t, mean, -1.f));
  const Var var = scale_shift(t, sum_channels(t, mul(t, centred, centred)), inv_m);
  const Var inv = exp(t, scale_shift(t, log(t, scale_shift(t, var, 1.f, eps)), -0.5f));
  Var y = add_channel(t, mul_channel(t, mul_channel(t, centred, inv), gamma), beta);

  // Running statistics (no gradient): r = (1 − momentum)·r + momentum·batch,
  // the variance unbiased by m / (m − 1).
  Stream& st = t.stream();
  const auto update = [&](const Var& running, const Tensor& batch, float unbias) {
    Tensor next = Tensor::empty(running.value().device(), running.shape());
    kernels::scale_shift(st, running.value(), 1.f - momentum, 0.f, next);
    kernels::axpy(st, momentum * unbias, batch, next);
    kernels::copy(st, next, running.value());
  };
  update(running_mean, mean.value(), 1.f);
  update(running_var, var.value(), float(m) / float(m - 1));
  return y;
}

}  // namespace vkjr2::nets
