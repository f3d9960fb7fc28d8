// Elementwise ops on f32 tensors and their backwards.
//
// Equal-shape ops need a, b and out of one shape (any rank). Channel ops
// broadcast a vector v[C] over x
// laid out as [N, C, spatial...] (rank 2 [N, C], rank 3 [N, C, L], rank 4
// NCHW; rank 1 is [C]). out may alias neither input. NaN propagates.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

// out = a + b, a - b, a * b (same shape).
void add(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& out);
void sub(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& out);
void mul(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& out);
// Backwards given dy = dL/dout; null outputs are skipped.
// add: da = dy, db = dy. sub: da = dy, db = -dy. mul: da = dy·b, db = dy·a.
void add_backward(Stream& stream, const Tensor& dy, const Tensor* da, const Tensor* db);
void sub_backward(Stream& stream, const Tensor& dy, const Tensor* da, const Tensor* db);
void mul_backward(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& dy,
                  const Tensor* da, const Tensor* db);

// out[n, c, s] = x[n, c, s] + v[c] (bias) or x[n, c, s] · v[c] (scale).
void add_channel(Stream& stream, const Tensor& x, const Tensor& v, const Tensor& out);
void mul_channel(Stream& stream, const Tensor& x, const Tensor& v, const Tensor& out);
// add_channel: dx = dy (use dy itself), dv[c] = Σ_{n,s} dy.
void add_channel_backward(Stream& stream, const Tensor& dy, const Tensor& dv);
// mul_channel: dx = dy · v[c], dv[c] = Σ_{n,s} dy · x. Null outputs are skipped.
void mul_channel_backward(Stream& stream, const Tensor& x, const Tensor& v, const Tensor& dy,
                          const Tensor* dx, const Tensor* dv);

// y = scale · x + shift (scalars).
void scale_shift(Stream& stream, const Tensor& x, float scale, float shift, const Tensor& y);
// dx = scale · dy.
void scale_shift_backward(Stream& stream, const Tensor& dy, float scale, const Tensor& dx);

// y = exp(x); backward from the saved output: dx = dy · y.
void exponential(Stream& stream, const Tensor& x, const Tensor& y);
void exponential_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx);
// y = log(x) (natural; x ≤ 0 gives -inf / NaN); backward from the saved input: dx = dy / x.
void logarithm(Stream& stream, const Tensor& x, const Tensor& y);
void logarithm_backward(Stream& stream, const Tensor& x, const Tensor& dy, const Tensor& dx);

namespace detail {

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

}  // namespace detail
}  // namespace vkjr2::kernels
