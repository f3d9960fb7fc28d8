// Activations on f32 tensors (any shape; PReLU: [N, C, spatial...] as in
// elementwise.hpp) and their backwards. Each backward states which saved
// tensor it needs: the input x (ReLU, LeakyReLU, PReLU) or the output y
// (sigmoid, tanh). dx may not alias dy. NaN propagates (ReLU(NaN) = NaN).
// At x = 0 the (sub)gradient used is the one of the x < 0 side.
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

// y = max(x, 0); dx = dy · [x > 0].
void relu(Stream& stream, const Tensor& x, const Tensor& y);
void relu_backward(Stream& stream, const Tensor& x, const Tensor& dy, const Tensor& dx);

// y = x for x ≥ 0, slope · x below; dx = dy · (x > 0 ? 1 : slope).
void leaky_relu(Stream& stream, const Tensor& x, float slope, const Tensor& y);
void leaky_relu_backward(Stream& stream, const Tensor& x, float slope, const Tensor& dy,
                         const Tensor& dx);

// y = x for x ≥ 0, slope[c] · x below (slope has one value per channel).
// Backward: dx = dy · (x > 0 ? 1 : slope[c]), dslope[c] = Σ_{n,s} dy · min(x, 0).
// Null outputs are skipped.
void prelu(Stream& stream, const Tensor& x, const Tensor& slope, const Tensor& y);
void prelu_backward(Stream& stream, const Tensor& x, const Tensor& slope, const Tensor& dy,
                    const Tensor* dx, const Tensor* dslope);

// y = 1 / (1 + exp(-x)); backward from the output: dx = dy · y (1 - y).
void sigmoid(Stream& stream, const Tensor& x, const Tensor& y);
void sigmoid_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx);

// y = tanh(x); backward from the output: dx = dy · (1 - y²).
void tanh_activation(Stream& stream, const Tensor& x, const Tensor& y);
void tanh_activation_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx);

}  // namespace vkjr2::kernels
