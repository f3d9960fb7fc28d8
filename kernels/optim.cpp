#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/optim.hpp>

#include <cmath>
#include <string>

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kPerGroup = 1024;  // 256 invocations × 4

struct SgdPush {
  std::uint32_t n;
  float lr, momentum, weight_decay;
};
struct AdamPush {
  std::uint32_t n, step, decoupled;
  float lr, beta1, beta2, eps, weight_decay, step_size, bc2_sqrt;
};
static_assert(sizeof(SgdPush) <= 128 && sizeof(AdamPush) <= 128);

std::uint32_t check_state(const Tensor& param, const Tensor& grad,
                          std::initializer_list<const Tensor*> state, const char* op) {
  const std::uint32_t n = require_f32(param, op, "param");
  require_f32(grad, op, "grad");
  require_same_shape(param, grad, op, "param", "grad");
  for (const Tensor* s : state) {
    require_f32(*s, op, "optimizer state");
    require_same_shape(param, *s, op, "param", "optimizer state");
  }
  return n;
}

}  // namespace

void sgd_step(Stream& stream, const Tensor& param, const Tensor& grad, const Tensor& velocity,
              const SgdOptions& o) {
  static const KernelDef k{"optim_sgd",
                           {BindingKind::texel, BindingKind::storage, BindingKind::storage},
                           sizeof(SgdPush)};
  const std::uint32_t n = check_state(param, grad, {&velocity}, "sgd_step");
  stream.dispatch(k, {texel(grad), inout(param), inout(velocity)},
                  SgdPush{n, o.lr, o.momentum, o.weight_decay},
                  groups_1d(div_up(n, kPerGroup), stream.device().info()));
}

void adam_step(Stream& stream, const Tensor& param, const Tensor& grad, const Tensor& m,
               const Tensor& v, std::uint32_t step, const AdamOptions& o) {
  static const KernelDef k{
      "optim_adam",
      {BindingKind::texel, BindingKind::storage, BindingKind::storage, BindingKind::storage},
      sizeof(AdamPush)};
  const std::uint32_t n = check_state(param, grad, {&m, &v}, "adam_step");
  if (step == 0) {
    throw InvalidArgument("adam_step",
                          "step must count from 1 (the bias corrections divide by "
                          "1 - beta^step)");
  }
  const double bc1 = 1.0 - std::pow(double(o.beta1), double(step));
  const double bc2 = 1.0 - std::pow(double(o.beta2), double(step));
  const AdamPush push{n,
                      step,
                      o.decoupled ? 1u : 0u,
                      o.lr,
                      o.beta1,
                      o.beta2,
                      o.eps,
                      o.weight_decay,
                      float(double(o.lr) / bc1),
                      float(std::sqrt(bc2))};
  stream.dispatch(k, {texel(grad), inout(param), inout(m), inout(v)}, push,
                  groups_1d(div_up(n, kPerGroup), stream.device().info()));
}

}  // namespace vkjr2::kernels
