// Plain C++ reference of kernels/matmul (tests only), accumulated in double.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace vkjr2::ref {

// Y[M, N] = X[M, K] · W[K, N] (+ bias[N] when non-empty).
std::vector<float> matmul(std::span<const float> x, std::span<const float> w,
                          std::span<const float> bias, std::size_t m, std::size_t k, std::size_t n);
// Σ|x|·|w| per output: the scale of the rounding error of each Y element.
std::vector<float> matmul_abs(std::span<const float> x, std::span<const float> w, std::size_t m,
                              std::size_t k, std::size_t n);
// Aᵀ of a row-major [rows, cols] matrix.
std::vector<float> transpose(std::span<const float> a, std::size_t rows, std::size_t cols);

}  // namespace vkjr2::ref
