// Matrix products on row-major f32 matrices: linear layers and their backwards.
// Register-blocked shader (4 × 8 outputs per invocation, operands through
// uniform texel buffers; shaders/matmul.comp).
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

// Y[M, N] = X[M, K] · W[K, N] (+ bias[N] when given).
void matmul(Stream& stream, const Tensor& x, const Tensor& w, const Tensor& y,
            const Tensor* bias = nullptr);
// Backward of matmul given dY[M, N]; null outputs are skipped:
// dX[M, K] = dY · Wᵀ, dW[K, N] = Xᵀ · dY, dbias[N] = Σ_m dY[m, :].
void matmul_backward(Stream& stream, const Tensor& x, const Tensor& w, const Tensor& dy,
                     const Tensor* dx, const Tensor* dw, const Tensor* dbias = nullptr);

}  // namespace vkjr2::kernels
