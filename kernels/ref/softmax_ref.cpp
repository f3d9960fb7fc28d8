#include <vkjr2/kernels/ref/softmax_ref.hpp>

#include <algorithm>
#include <cmath>

namespace vkjr2::ref {

std::vector<float> softmax(std::span<const float> x, std::size_t k, bool log) {
  std::vector<float> y(x.size());
  for (std::size_t base = 0; base < x.size(); base += k) {
    double m = -INFINITY, s = 0;
    for (std::size_t j = 0; j < k; ++j) m = std::max(m, double(x[base + j]));
    for (std::size_t j = 0; j < k; ++j) s += std::exp(x[base + j] - m);
    for (std::size_t j = 0; j < k; ++j) {
      const double d = x[base + j] - m;
      y[base + j] = float(log ? d - std::log(s) : std::exp(d) / s);
    }
  }
  return y;
}

std::vector<float> softmax_backward(std::span<const float> y, std::span<const float> dy,
                                    std::size_t k, bool log) {
  std::vector<float> dx(y.size());
  for (std::size_t base = 0; base < y.size(); base += k) {
    double t = 0;
    for (std::size_t j = 0; j < k; ++j)
      t += log ? dy[base + j] : double(dy[base + j]) * y[base + j];
    for (std::size_t j = 0; j < k; ++j) {
      const double g = dy[base + j], v = y[base + j];
      dx[base + j] = float(log ? g - std::exp(v) * t : v * (g - t));
    }
  }
  return dx;
}

}  // namespace vkjr2::ref
