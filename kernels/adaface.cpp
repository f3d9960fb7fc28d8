#include <vkjr2/kernels/adaface.hpp>
#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/fast_div.hpp>

#include <cmath>
#include <string>

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kPerGroup = 1024;  // adaface_margin: 256 invocations × 4

struct ScalerPush {
  std::uint32_t rows;
  std::uint32_t update;
  float h;
  float eps;
  float alpha;
};
struct MarginPush {
  std::uint32_t n;
  std::uint32_t classes;
  std::uint32_t row_magic[2];
  float s;
  float m;
  float eps;
};
static_assert(sizeof(ScalerPush) <= 128 && sizeof(MarginPush) <= 128);

bool finite(float v) { return std::isfinite(v); }

void require_labels(const Tensor& labels, std::int64_t rows, const char* op) {
  if (!labels.defined() || labels.dtype() != DType::i32) {
    throw InvalidArgument(op, "labels must be a defined i32 tensor",
                          "pass one i32 class index per row of cos");
  }
  require_shape(labels, Shape{rows}, op, "labels (one class index per row of cos)");
}

// Checks shared by the margin forward and backward; returns C.
std::uint32_t check_margin(const Tensor& cos, const Tensor& labels, const Tensor& scaler,
                           const Tensor& out, const AdaFaceParams& p, const char* op,
                           const char* out_name) {
  check_adaface_params(p, op);
  const std::uint32_t n = require_f32_rank(cos, 2, op, "cos");
  if (n > 0x7fffffffu) {
    throw InvalidArgument(op, "cos " + cos.shape().str() + " has 2^31 or more elements",
                          "split the batch into chunks");
  }
  const std::int64_t rows = cos.shape()[0];
  require_labels(labels, rows, op);
  require_f32(scaler, op, "scaler");
  require_shape(scaler, Shape{rows}, op, "scaler (one ẑ per row of cos, from adaface_scaler)");
  require_f32(out, op, out_name);
  require_same_shape(cos, out, op, "cos", out_name);
  return std::uint32_t(cos.shape()[1]);
}

void dispatch_margin(Stream& stream, const Tensor& cos, const Tensor& labels, const Tensor& scaler,
                     const Tensor& dy, const AdaFaceParams& p, std::uint32_t classes,
                     const Tensor& out, bool backward) {
  static const KernelDef k{"adaface_margin",
                           {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                            BindingKind::texel, BindingKind::storage},
                           sizeof(MarginPush)};
  const auto n = std::uint32_t(cos.numel());
  const Magic magic_c = magic(classes);
  stream.dispatch(
      k, {texel(cos), texel(labels, VK_FORMAT_R32_SINT), texel(scaler), texel(dy), vkjr2::out(out)},
      MarginPush{n, classes, {magic_c.m, magic_c.l}, p.s, p.m, p.eps},
      groups_1d(div_up(n, kPerGroup), stream.device().info()), {backward ? 1u : 0u});
}

}  // namespace

void check_adaface_params(const AdaFaceParams& p, const char* op) {
  const bool ok = finite(p.m) && finite(p.h) && finite(p.s) && finite(p.eps) && finite(p.alpha) &&
                  p.m >= 0.f && p.m <= 1.f && p.h > 0.f && p.s > 0.f && p.eps > 0.f &&
                  p.eps <= 0.1f && p.alpha > 0.f && p.alpha <= 1.f;
  if (!ok) {
    throw InvalidArgument(op,
                          "AdaFace parameters m = " + std::to_string(p.m) +
                              ", h = " + std::to_string(p.h) + ", s = " + std::to_string(p.s) +
                              ", eps = " + std::to_string(p.eps) +
                              ", alpha = " + std::to_string(p.alpha) + " are out of range",
                          "use m in [0, 1], h > 0, s > 0, eps in (0, 0.1], alpha in (0, 1] (the "
                          "paper's m = 0.4, h = 0.333, s = 64, eps = 1e-3, alpha = 0.01)");
  }
}

void adaface_scaler(Stream& stream, const Tensor& norms, const Tensor& running_mean,
                    const Tensor& running_std, bool update, const AdaFaceParams& p,
                    const Tensor& scaler) {
  static const KernelDef k{
      "adaface_scaler",
      {BindingKind::texel, BindingKind::storage, BindingKind::storage, BindingKind::storage},
      sizeof(ScalerPush)};
  const char* op = "adaface_scaler";
  check_adaface_params(p, op);
  const std::uint32_t rows = require_f32_rank(norms, 1, op, "norms");
  require_f32(running_mean, op, "running_mean");
  require_shape(running_mean, Shape{1}, op, "running_mean");
  require_f32(running_std, op, "running_std");
  require_shape(running_std, Shape{1}, op, "running_std");
  require_f32(scaler, op, "scaler");
  require_same_shape(norms, scaler, op, "norms", "scaler");
  if (update && rows < 2) {
    throw InvalidArgument(op, "updating the running statistics needs a batch of at least 2 norms",
                          "use a batch of ≥ 2 samples in training, or update = false (eval)");
  }
  const Arg mean_arg = update ? inout(running_mean) : in(running_mean);
  const Arg std_arg = update ? inout(running_std) : in(running_std);
  stream.dispatch(k, {texel(norms), mean_arg, std_arg, out(scaler)},
                  ScalerPush{rows, update ? 1u : 0u, p.h, p.eps, p.alpha}, Groups{1, 1, 1});
}

void adaface_margin(Stream& stream, const Tensor& cos, const Tensor& labels, const Tensor& scaler,
                    const AdaFaceParams& p, const Tensor& logits) {
  const std::uint32_t classes =
      check_margin(cos, labels, scaler, logits, p, "adaface_margin", "logits");
  // dy is not read in the forward; cos fills its binding.
  dispatch_margin(stream, cos, labels, scaler, cos, p, classes, logits, false);
}

void adaface_margin_backward(Stream& stream, const Tensor& cos, const Tensor& labels,
                             const Tensor& scaler, const Tensor& d_logits, const AdaFaceParams& p,
                             const Tensor& d_cos) {
  const char* op = "adaface_margin_backward";
  const std::uint32_t classes = check_margin(cos, labels, scaler, d_cos, p, op, "d_cos");
  require_f32(d_logits, op, "d_logits");
  require_same_shape(cos, d_logits, op, "cos", "d_logits");
  dispatch_margin(stream, cos, labels, scaler, d_logits, p, classes, d_cos, true);
}

}  // namespace vkjr2::kernels
