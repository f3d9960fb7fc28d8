#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/elementwise.hpp>

#include <string>
#include <vector>

#include "internal/channel_ops.hpp"

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kPerGroup = 1024;      // 256 invocations × 4 elements
constexpr std::uint32_t kVec4PerGroup = 1024;  // ew_binary4: 256 invocations × 4 vec4

struct BinaryPush {
  std::uint32_t n, hw, channels;
};
struct Binary4Push {
  std::uint32_t n4;
};
static_assert(sizeof(BinaryPush) <= 128 && sizeof(Binary4Push) <= 128);

enum class BinaryOp : std::uint32_t { add = 0, sub = 1, mul = 2 };

void binary(Stream& stream, const char* op_name, BinaryOp op, const Tensor& a, const Tensor& b,
            const Tensor& out) {
  static const KernelDef k{"ew_binary",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(BinaryPush)};
  const std::uint32_t n = require_f32(a, op_name, "a");
  require_f32(b, op_name, "b");
  require_f32(out, op_name, "out");
  require_same_shape(a, b, op_name, "a", "b");
  require_same_shape(a, out, op_name, "a", "out");
  // The one selection point: vec4 texels when the count and every offset allow
  // them (LAVAPIPE.md: vector gathers from texel buffers, more work per invocation).
  const bool vec4_ok = stream.device().traits().vec4_elementwise && n % 4 == 0 &&
                       a.vk_offset() % 16 == 0 && b.vk_offset() % 16 == 0 &&
                       out.vk_offset() % 16 == 0;
  if (vec4_ok) {
    static const KernelDef k4{"ew_binary4",
                              {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                              sizeof(Binary4Push)};
    const VkFormat rgba = VK_FORMAT_R32G32B32A32_SFLOAT;
    stream.dispatch(k4, {texel(a, rgba), texel(b, rgba), vkjr2::out(out)}, Binary4Push{n / 4},
                    groups_1d(div_up(n / 4, kVec4PerGroup), stream.device().info()),
                    {std::uint32_t(op)});
    return;
  }
  stream.dispatch(k, {texel(a), texel(b), vkjr2::out(out)}, BinaryPush{n, 1, 1},
                  groups_1d(div_up(n, kPerGroup), stream.device().info()), {std::uint32_t(op), 0u});
}

void binary_channel(Stream& stream, const char* op_name, BinaryOp op, const Tensor& x,
                    const Tensor& v, const Tensor& out) {
  static const KernelDef k{"ew_binary",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(BinaryPush)};
  const std::uint32_t n = require_f32(x, op_name, "x");
  require_f32(out, op_name, "out");
  require_same_shape(x, out, op_name, "x", "out");
  const detail::ChannelGeometry g = detail::channel_geometry(x);
  require_f32(v, op_name, "v");
  require_shape(v, Shape{std::int64_t(g.channels)}, op_name, "v (one value per channel)");
  stream.dispatch(k, {texel(x), texel(v), vkjr2::out(out)}, BinaryPush{n, g.hw, g.channels},
                  groups_1d(div_up(n, kPerGroup), stream.device().info()), {std::uint32_t(op), 1u});
}

// Checks a simple_gate's x [N, 2C, spatial...] against its half-size
// partner (y, or dy) and returns the geometry of the half: [N, C, S].
detail::ChannelGeometry gate_geometry(const char* op, const Tensor& x, const Tensor& half,
                                      const char* half_name) {
  require_f32(x, op, "x");
  require_f32(half, op, half_name);
  if (x.shape().rank() < 2) {
    throw InvalidArgument(op, "x has shape " + x.shape().str(),
                          "pass [N, 2C, ...] (rank 2 to 4, the gate's two halves on axis 1)");
  }
  const detail::ChannelGeometry g = detail::channel_geometry(x);
  if (g.channels % 2 != 0) {
    throw InvalidArgument(
        op, "x has " + std::to_string(g.channels) + " channels (shape " + x.shape().str() + ")",
        "pass an even channel count: the gate multiplies the two halves");
  }
  std::vector<std::int64_t> dims(x.shape().dims().begin(), x.shape().dims().end());
  dims[1] /= 2;
  require_shape(half, Shape(dims), op, half_name);
  return {g.batch, g.channels / 2, g.hw};
}

void gate_dispatch(Stream& stream, bool backward, const Tensor& x, const Tensor& dy,
                   const detail::ChannelGeometry& g, const Tensor& out) {
  static const KernelDef k{"simple_gate",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(std::uint32_t)};
  const std::uint32_t half = g.channels * g.hw;
  if (half == 0 || g.batch == 0) return;
  Groups groups = groups_1d(div_up(half, 256), stream.device().info());
  groups.z = g.batch;
  stream.dispatch(k, {texel(x), texel(dy), vkjr2::out(out)}, half, groups, {backward ? 1u : 0u});
}

}  // namespace

void simple_gate(Stream& stream, const Tensor& x, const Tensor& y) {
  const detail::ChannelGeometry g = gate_geometry("simple_gate", x, y, "y");
  // The forward never reads binding 1; x stands in for it.
  gate_dispatch(stream, false, x, x, g, y);
}

void simple_gate_backward(Stream& stream, const Tensor& x, const Tensor& dy, const Tensor& dx) {
  const char* op = "simple_gate_backward";
  const detail::ChannelGeometry g = gate_geometry(op, x, dy, "dy");
  require_f32(dx, op, "dx");
  require_same_shape(x, dx, op, "x", "dx");
  gate_dispatch(stream, true, x, dy, g, dx);
}

void add(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& out) {
  binary(stream, "add", BinaryOp::add, a, b, out);
}
void sub(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& out) {
  binary(stream, "sub", BinaryOp::sub, a, b, out);
}
void mul(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& out) {
  binary(stream, "mul", BinaryOp::mul, a, b, out);
}

void add_backward(Stream& stream, const Tensor& dy, const Tensor* da, const Tensor* db) {
  require_f32(dy, "add_backward", "dy");
  for (const Tensor* d : {da, db}) {
    if (d == nullptr) continue;
    require_f32(*d, "add_backward", "gradient");
    require_same_shape(dy, *d, "add_backward", "dy", "gradient");
    stream.copy(dy, *d);
  }
}

void sub_backward(Stream& stream, const Tensor& dy, const Tensor* da, const Tensor* db) {
  require_f32(dy, "sub_backward", "dy");
  if (da != nullptr) {
    require_f32(*da, "sub_backward", "da");
    require_same_shape(dy, *da, "sub_backward", "dy", "da");
    stream.copy(dy, *da);
  }
  if (db != nullptr) {
    detail::unary(stream, "sub_backward", detail::UnaryOp::scale_shift, dy, nullptr, nullptr, *db,
                  -1.f, 0.f);
  }
}

void mul_backward(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& dy,
                  const Tensor* da, const Tensor* db) {
  require_f32(a, "mul_backward", "a");
  require_same_shape(a, b, "mul_backward", "a", "b");
  if (da != nullptr) binary(stream, "mul_backward", BinaryOp::mul, dy, b, *da);
  if (db != nullptr) binary(stream, "mul_backward", BinaryOp::mul, dy, a, *db);
}

void add_channel(Stream& stream, const Tensor& x, const Tensor& v, const Tensor& out) {
  binary_channel(stream, "add_channel", BinaryOp::add, x, v, out);
}
void mul_channel(Stream& stream, const Tensor& x, const Tensor& v, const Tensor& out) {
  binary_channel(stream, "mul_channel", BinaryOp::mul, x, v, out);
}

void add_channel_backward(Stream& stream, const Tensor& dy, const Tensor& dv) {
  require_f32(dy, "add_channel_backward", "dy");
  const detail::ChannelGeometry g = detail::channel_geometry(dy);
  require_f32(dv, "add_channel_backward", "dv");
  require_shape(dv, Shape{std::int64_t(g.channels)}, "add_channel_backward", "dv");
  detail::reduce_channels(stream, dy, nullptr, 0, g.batch, g.channels, g.hw, dv);
}

void mul_channel_backward(Stream& stream, const Tensor& x, const Tensor& v, const Tensor& dy,
                          const Tensor* dx, const Tensor* dv) {
  require_f32(x, "mul_channel_backward", "x");
  require_f32(dy, "mul_channel_backward", "dy");
  require_same_shape(x, dy, "mul_channel_backward", "x", "dy");
  if (dx != nullptr) binary_channel(stream, "mul_channel_backward", BinaryOp::mul, dy, v, *dx);
  if (dv != nullptr) {
    const detail::ChannelGeometry g = detail::channel_geometry(x);
    require_f32(*dv, "mul_channel_backward", "dv");
    require_shape(*dv, Shape{std::int64_t(g.channels)}, "mul_channel_backward", "dv");
    detail::reduce_channels(stream, dy, &x, 1, g.batch, g.channels, g.hw, *dv);
  }
}

void scale_shift(Stream& stream, const Tensor& x, float scale, float shift, const Tensor& y) {
  detail::unary(stream, "scale_shift", detail::UnaryOp::scale_shift, x, nullptr, nullptr, y, scale,
                shift);
}
void scale_shift_backward(Stream& stream, const Tensor& dy, float scale, const Tensor& dx) {
  // dx = scale·dy + 0: the forward op applied to dy.
  detail::unary(stream, "scale_shift_backward", detail::UnaryOp::scale_shift, dy, nullptr, nullptr,
                dx, scale, 0.f);
}

void exponential(Stream& stream, const Tensor& x, const Tensor& y) {
  detail::unary(stream, "exponential", detail::UnaryOp::exp, x, nullptr, nullptr, y);
}
void exponential_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx) {
  detail::unary(stream, "exponential_backward", detail::UnaryOp::exp, y, &dy, nullptr, dx);
}
void logarithm(Stream& stream, const Tensor& x, const Tensor& y) {
  detail::unary(stream, "logarithm", detail::UnaryOp::log, x, nullptr, nullptr, y);
}
void logarithm_backward(Stream& stream, const Tensor& x, const Tensor& dy, const Tensor& dx) {
  detail::unary(stream, "logarithm_backward", detail::UnaryOp::log, x, &dy, nullptr, dx);
}

}  // namespace vkjr2::kernels
