// Losses on f32 tensors. Unless noted each writes the mean over elements to
// a one-element tensor, and its backward takes the upstream scalar gradient
// g (one element, on the device) and writes d pred (same shape as pred).
// The gradient with respect to target is -d pred for L1, MSE and Charbonnier.
// Deterministic (fixed summation order per device); NaN propagates.
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

// mean |pred - target|; d pred = g/n · sign(pred - target) (0 where equal).
void l1_loss(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& loss);
void l1_loss_backward(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& g,
                      const Tensor& d_pred);
// mean (pred - target)²; d pred = g/n · 2 (pred - target).
void mse_loss(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& loss);
void mse_loss_backward(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& g,
                       const Tensor& d_pred);
// mean sqrt(d² + eps²), d = pred - target (Charbonnier 1994); d pred = g/n · d / sqrt(d² + eps²).
void charbonnier_loss(Stream& stream, const Tensor& pred, const Tensor& target, float eps,
                      const Tensor& loss);
void charbonnier_loss_backward(Stream& stream, const Tensor& pred, const Tensor& target, float eps,
                               const Tensor& g, const Tensor& d_pred);

// Per row of a, b [..., K] (not a mean): y[r] = a·b / (max(|a|, eps) max(|b|, eps));
// y has one element per row. Backward takes dy (one per row) and writes da and db.
void cosine_similarity(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& y,
                       float eps = 1e-8f);
void cosine_similarity_backward(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& dy,
                                const Tensor& da, const Tensor& db, float eps = 1e-8f);

// Cross-entropy of logits [rows, K] (rank 2) against i32 labels [rows] in
// [0, K): mean over rows of logsumexp(x[r]) - x[r, label[r]] (an
// out-of-range label gives NaN). Backward: d logits = g/rows · (softmax - onehot).
void cross_entropy(Stream& stream, const Tensor& logits, const Tensor& labels, const Tensor& loss);
void cross_entropy_backward(Stream& stream, const Tensor& logits, const Tensor& labels,
                            const Tensor& g, const Tensor& d_logits);

}  // namespace vkjr2::kernels
