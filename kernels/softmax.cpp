#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/softmax.hpp>

#include <algorithm>

namespace vkjr2::kernels {
namespace {

struct SoftmaxPush {
  std::uint32_t rows, k;
};
static_assert(sizeof(SoftmaxPush) <= 128);

void forward(Stream& stream, bool log, const char* op, const Tensor& x, const Tensor& y) {
  static const KernelDef k{
      "softmax", {BindingKind::texel, BindingKind::storage}, sizeof(SoftmaxPush)};
  const std::uint32_t n = require_f32(x, op, "x");
  require_f32(y, op, "y");
  require_same_shape(x, y, op, "x", "y");
  const auto len = std::uint32_t(x.shape()[-1]);
  stream.dispatch(k, {texel(x), out(y)}, SoftmaxPush{n / len, len},
                  subgroup_row_groups(stream, n / len, op), {log ? 1u : 0u});
}

void backward(Stream& stream, bool log, const char* op, const Tensor& y, const Tensor& dy,
              const Tensor& dx) {
  static const KernelDef k{"softmax_grad",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(SoftmaxPush)};
  const std::uint32_t n = require_f32(y, op, "y");
  require_f32(dy, op, "dy");
  require_f32(dx, op, "dx");
  require_same_shape(y, dy, op, "y", "dy");
  require_same_shape(y, dx, op, "y", "dx");
  const auto len = std::uint32_t(y.shape()[-1]);
  stream.dispatch(k, {texel(y), texel(dy), out(dx)}, SoftmaxPush{n / len, len},
                  subgroup_row_groups(stream, n / len, op), {log ? 1u : 0u});
}

}  // namespace

void softmax(Stream& stream, const Tensor& x, const Tensor& y) {
  forward(stream, false, "softmax", x, y);
}
void softmax_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx) {
  backward(stream, false, "softmax_backward", y, dy, dx);
}
void log_softmax(Stream& stream, const Tensor& x, const Tensor& y) {
  forward(stream, true, "log_softmax", x, y);
}
void log_softmax_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx) {
  backward(stream, true, "log_softmax_backward", y, dy, dx);
}

}  // namespace vkjr2::kernels
