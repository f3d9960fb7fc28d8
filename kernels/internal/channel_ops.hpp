// Internal to the kernels layer (not installed): the primitives behind the
// elementwise ops, the activations and the per-channel reductions. Included
// as "internal/channel_ops.hpp" from kernels/*.cpp only.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels::detail {

// Op codes of shaders/ew_unary.comp (shared with kernels/activation.cpp).
enum class UnaryOp : std::uint32_t {
  scale_shift = 0,
  exp = 1,
  log = 2,
  relu = 3,
  leaky_relu = 4,
  prelu = 5,
  sigmoid = 6,
  tanh = 7,
};

// Forward (dy null): out = f(a). Backward: out = dy · f'(a), a the saved
// tensor. slope: PReLU's per-channel slope (else null). Checks shapes.
void unary(Stream& stream, const char* op_name, UnaryOp op, const Tensor& a, const Tensor* dy,
           const Tensor* slope, const Tensor& out, float p0 = 0.f, float p1 = 0.f);

// Geometry of x as [batch, channels, hw] for channel broadcasts.
struct ChannelGeometry {
  std::uint32_t batch = 1, channels = 1, hw = 1;
};
ChannelGeometry channel_geometry(const Tensor& x);

// out[c] = Σ_{n,s} term, term = a (mode 0), a·b (mode 1), a·min(b, 0) (mode 2),
// over [batch, channels, hw] (shaders/reduce_channels.comp). b may be null for mode 0.
void reduce_channels(Stream& stream, const Tensor& a, const Tensor* b, std::uint32_t mode,
                     std::uint32_t batch, std::uint32_t channels, std::uint32_t hw,
                     const Tensor& out);

}  // namespace vkjr2::kernels::detail
