// Reductions on f32 tensors: sums, means, L2 norms and maxima over the last
// axis or over everything, and per-channel sums. All deterministic: a fixed
// summation order per device (subgroup adds in a fixed tree).
//
// "Rows" are the last axis: x with shape [..., K] has numel/K rows of K.
// Row outputs have numel == rows (any shape, e.g. [rows] or x's shape with
// the last axis dropped or set to 1). NaN propagates.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

// out[r] = Σ_k x[r, k];  mean: / K;  l2: sqrt(Σ_k x[r, k]²).
void sum_rows(Stream& stream, const Tensor& x, const Tensor& out);
void mean_rows(Stream& stream, const Tensor& x, const Tensor& out);
void l2norm_rows(Stream& stream, const Tensor& x, const Tensor& out);
// dx[r, k] = dy[r] (sum), dy[r] / K (mean), dy[r] · x[r, k] / y[r] (l2; 0 where y[r] = 0).
void sum_rows_backward(Stream& stream, const Tensor& dy, const Tensor& dx);
void mean_rows_backward(Stream& stream, const Tensor& dy, const Tensor& dx);
void l2norm_rows_backward(Stream& stream, const Tensor& x, const Tensor& y, const Tensor& dy,
                          const Tensor& dx);

// out[0] = Σ x or mean(x) over all elements (out has one element).
// Backward: dx = dy[0] (sum), dy[0] / numel (mean); dy has one element.
void sum_all(Stream& stream, const Tensor& x, const Tensor& out);
void mean_all(Stream& stream, const Tensor& x, const Tensor& out);
void sum_all_backward(Stream& stream, const Tensor& dy, const Tensor& dx);
void mean_all_backward(Stream& stream, const Tensor& dy, const Tensor& dx);

// Maximum and its index per row (index within the row) or over all (flat
// index); value/index have numel == rows, or one element. Ties: the smallest
// index; NaN counts as the maximum (the first NaN wins). index is i32.
void max_rows(Stream& stream, const Tensor& x, const Tensor& value, const Tensor& index);
void max_all(Stream& stream, const Tensor& x, const Tensor& value, const Tensor& index);

// Per-channel sums over x as [N, C, spatial...] (see elementwise.hpp):
// out[c] = Σ_{n,s} x[n, c, s]. For a matrix [M, N] this is the column sum.
void sum_channels(Stream& stream, const Tensor& x, const Tensor& out);

}  // namespace vkjr2::kernels
