#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/norm.hpp>
#include <vkjr2/runtime/error.hpp>

#include <cmath>
#include <string>

namespace vkjr2::kernels {
namespace {

// Mirrors the push block of shaders/layer_norm.comp.
struct LayerNormPush {
  std::uint32_t hw, channels;
  float eps;
};
static_assert(sizeof(LayerNormPush) <= 128);

void check_args(const char* op, const Tensor& x, const Tensor& gamma, float eps) {
  require_f32_rank(x, 4, op, "x");
  const std::int64_t c = x.shape()[1];
  require_f32(gamma, op, "gamma");
  require_shape(gamma, Shape{c}, op, "gamma (one value per channel)");
  if (!(eps > 0.f) || !std::isfinite(eps)) {
    throw InvalidArgument(op, "eps is " + std::to_string(eps), "pass a small positive eps (1e-6)");
  }
}

void dispatch(Stream& stream, bool grad, const Tensor& x, const Tensor& gamma,
              const Tensor& beta_or_dy, float eps, const Tensor& y, const Tensor& xhat) {
  static const KernelDef k{"layer_norm",
                           {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                            BindingKind::storage, BindingKind::storage},
                           sizeof(LayerNormPush)};
  const Shape& s = x.shape();
  const auto hw = static_cast<std::uint32_t>(s[2] * s[3]);
  stream.dispatch(k, {texel(x), texel(gamma), texel(beta_or_dy), out(y), out(xhat)},
                  LayerNormPush{hw, static_cast<std::uint32_t>(s[1]), eps},
                  Groups{div_up(hw, 256), static_cast<std::uint32_t>(s[0]), 1}, {grad ? 1u : 0u});
}

}  // namespace

void layer_norm_channels(Stream& stream, const Tensor& x, const Tensor& gamma, const Tensor& beta,
                         float eps, const Tensor& y) {
  const char* op = "layer_norm_channels";
  check_args(op, x, gamma, eps);
  require_f32(beta, op, "beta");
  require_shape(beta, gamma.shape(), op, "beta (one value per channel)");
  require_f32(y, op, "y");
  require_same_shape(x, y, op, "x", "y");
  // The forward never writes binding 4; y stands in for it.
  dispatch(stream, false, x, gamma, beta, eps, y, y);
}

void layer_norm_channels_backward(Stream& stream, const Tensor& x, const Tensor& gamma,
                                  const Tensor& dy, float eps, const Tensor* dx,
                                  const Tensor* dgamma, const Tensor* dbeta) {
  const char* op = "layer_norm_channels_backward";
  check_args(op, x, gamma, eps);
  require_f32(dy, op, "dy");
  require_same_shape(x, dy, op, "x", "dy");
  if (dx == nullptr && dgamma == nullptr && dbeta == nullptr) {
    throw InvalidArgument(op, "dx, dgamma and dbeta are all null", "pass at least one output");
  }
  if (dx != nullptr) {
    require_f32(*dx, op, "dx");
    require_same_shape(x, *dx, op, "x", "dx");
  }
  if (dgamma != nullptr) {
    require_f32(*dgamma, op, "dgamma");
    require_shape(*dgamma, gamma.shape(), op, "dgamma");
  }
  if (dbeta != nullptr) {
    require_f32(*dbeta, op, "dbeta");
    require_shape(*dbeta, gamma.shape(), op, "dbeta");
  }
  if (dbeta != nullptr) add_channel_backward(stream, dy, *dbeta);
  if (dx == nullptr && dgamma == nullptr) return;
  // x̂ is a temporary: kept alive by the stream until it has run.
  const Tensor xhat = Tensor::empty(stream.device(), x.shape());
  const Tensor dx_out = dx != nullptr ? *dx : Tensor::empty(stream.device(), x.shape());
  dispatch(stream, true, x, gamma, dy, eps, dx_out, xhat);
  if (dgamma != nullptr) mul_channel_backward(stream, xhat, gamma, dy, nullptr, dgamma);
}

}  // namespace vkjr2::kernels
