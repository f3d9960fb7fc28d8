// The per-element and per-channel primitives that elementwise, activation and
// reduce share (kernels/internal/channel_ops.hpp).
#include "internal/channel_ops.hpp"

#include <vkjr2/kernels/check.hpp>

namespace vkjr2::kernels::detail {
namespace {

constexpr std::uint32_t kPerGroup = 1024;  // 256 invocations × 4 elements

struct UnaryPush {
  std::uint32_t n;
  float p0, p1;
  std::uint32_t hw, channels;
};
struct ChannelsPush {
  std::uint32_t batch, channels, hw;
};
static_assert(sizeof(UnaryPush) <= 128 && sizeof(ChannelsPush) <= 128);

}  // namespace

ChannelGeometry channel_geometry(const Tensor& x) {
  const Shape& s = x.shape();
  ChannelGeometry g;
  if (s.rank() == 1) {
    g.channels = std::uint32_t(s[0]);
    return g;
  }
  g.batch = std::uint32_t(s[0]);
  g.channels = std::uint32_t(s[1]);
  for (int i = 2; i < s.rank(); ++i) g.hw *= std::uint32_t(s[i]);
  return g;
}

void unary(Stream& stream, const char* op_name, UnaryOp op, const Tensor& a, const Tensor* dy,
           const Tensor* slope, const Tensor& out, float p0, float p1) {
  static const KernelDef k{
      "ew_unary",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage},
      sizeof(UnaryPush)};
  const bool backward = dy != nullptr;
  const std::uint32_t n = require_f32(a, op_name, backward ? "saved tensor" : "x");
  require_f32(out, op_name, backward ? "dx" : "y");
  require_same_shape(a, out, op_name, backward ? "saved tensor" : "x", backward ? "dx" : "y");
  if (backward) {
    require_f32(*dy, op_name, "dy");
    require_same_shape(a, *dy, op_name, "saved tensor", "dy");
  }
  ChannelGeometry g;
  if (op == UnaryOp::prelu) {
    g = channel_geometry(a);
    require_f32(*slope, op_name, "slope");
    require_shape(*slope, Shape{std::int64_t(g.channels)}, op_name,
                  "slope (one value per channel)");
  }
  // Unused bindings are bound to `a` (never read).
  const Tensor& b = backward ? *dy : a;
  const Tensor& sl = op == UnaryOp::prelu ? *slope : a;
  stream.dispatch(k, {texel(a), texel(b), texel(sl), vkjr2::out(out)},
                  UnaryPush{n, p0, p1, g.hw, g.channels},
                  groups_1d(div_up(n, kPerGroup), stream.device().info()),
                  {std::uint32_t(op), backward ? 1u : 0u});
}

void reduce_channels(Stream& stream, const Tensor& a, const Tensor* b, std::uint32_t mode,
                     std::uint32_t batch, std::uint32_t channels, std::uint32_t hw,
                     const Tensor& out) {
  static const KernelDef k{"reduce_channels",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(ChannelsPush)};
  require_subgroup_arithmetic(stream, "reduce_channels");
  const Tensor& bs = b != nullptr ? *b : a;
  stream.dispatch(k, {texel(a), texel(bs), vkjr2::out(out)}, ChannelsPush{batch, channels, hw},
                  subgroup_row_groups(stream, channels, "reduce_channels"), {mode});
}

}  // namespace vkjr2::kernels::detail
