// Basic kernels that prove the runtime path: fill, copy, axpy, sum.
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

// dst[i] = value (f32).
void fill(Stream& stream, const Tensor& dst, float value);
// dst[i] = src[i] (f32, same element count).
void copy(Stream& stream, const Tensor& src, const Tensor& dst);
// y[i] += alpha * x[i] (f32, same element count).
void axpy(Stream& stream, float alpha, const Tensor& x, const Tensor& y);
// out[0] = Σ x[i] (f32; out has one element). Multi-pass tree reduction.
void sum(Stream& stream, const Tensor& x, const Tensor& out);

}  // namespace vkjr2::kernels
