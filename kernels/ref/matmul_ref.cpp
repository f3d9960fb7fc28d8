#include <vkjr2/kernels/ref/matmul_ref.hpp>

#include <cmath>

namespace vkjr2::ref {

std::vector<float> matmul(std::span<const float> x, std::span<const float> w,
                          std::span<const float> bias, std::size_t m, std::size_t k,
                          std::size_t n) {
  std::vector<double> acc(m * n, 0.0);
  for (std::size_t i = 0; i < m; ++i) {
    for (std::size_t r = 0; r < k; ++r) {
      const double a = x[i * k + r];
      for (std::size_t j = 0; j < n; ++j) acc[i * n + j] += a * w[r * n + j];
    }
  }
  std::vector<float> y(m * n);
  for (std::size_t i = 0; i < m * n; ++i) y[i] = float(acc[i] + (bias.empty() ? 0.0 : bias[i % n]));
  return y;
}

std::vector<float> matmul_abs(std::span<const float> x, std::span<const float> w, std::size_t m,
                              std::size_t k, std::size_t n) {
  std::vector<float> ax(x.size()), aw(w.size());
  for (std::size_t i = 0; i < x.size(); ++i) ax[i] = std::fabs(x[i]);
  for (std::size_t i = 0; i < w.size(); ++i) aw[i] = std::fabs(w[i]);
  return matmul(ax, aw, {}, m, k, n);
}

std::vector<float> transpose(std::span<const float> a, std::size_t rows, std::size_t cols) {
  std::vector<float> t(a.size());
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t j = 0; j < cols; ++j) t[j * rows + i] = a[i * cols + j];
  }
  return t;
}

}  // namespace vkjr2::ref
