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

// NAFNet's SimpleGate over [N, 2C, spatial...] (rank 2..4, the channel
// count even): y[n, c, s] = x[n, c, s] · x[n, c + C, s], y: [N, C, spatial...].
void simple_gate(Stream& stream, const Tensor& x, const Tensor& y);
// dx[n, c, s] = dy[n, c, s] · x[n, c + C, s], dx[n, c + C, s] = dy[n, c, s] · x[n, c, s].
void simple_gate_backward(Stream& stream, const Tensor& x, const Tensor& dy, const Tensor& dx);

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

}  // namespace vkjr2::kernels
