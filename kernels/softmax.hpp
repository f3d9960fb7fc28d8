// Softmax and log-softmax over the last axis of f32 x [..., K] (rows of K),
// numerically stable (the row maximum is subtracted). Backwards from the
// saved output y. A row of all -inf gives NaN; NaN propagates within its row.
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

// y = exp(x - max) / Σ exp(x - max); dx = y ⊙ (dy - Σ_row dy ⊙ y).
void softmax(Stream& stream, const Tensor& x, const Tensor& y);
void softmax_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx);
// y = x - max - log Σ exp(x - max); dx = dy - exp(y) Σ_row dy.
void log_softmax(Stream& stream, const Tensor& x, const Tensor& y);
void log_softmax_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx);

}  // namespace vkjr2::kernels
