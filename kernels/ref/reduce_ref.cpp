#include <vkjr2/kernels/ref/reduce_ref.hpp>

#include <cmath>
#include <cstddef>

namespace vkjr2::ref {

std::vector<float> reduce_rows(int op, std::span<const float> x, std::size_t k) {
  const std::size_t rows = x.size() / k;
  std::vector<float> out(rows);
  for (std::size_t r = 0; r < rows; ++r) {
    double s = 0;
    for (std::size_t j = 0; j < k; ++j) {
      const double v = x[r * k + j];
      s += op == 2 ? v * v : v;
    }
    out[r] = float(op == 1 ? s / double(k) : (op == 2 ? std::sqrt(s) : s));
  }
  return out;
}

void max_rows(std::span<const float> x, std::size_t k, std::vector<float>& value,
              std::vector<std::int32_t>& index) {
  const std::size_t rows = x.size() / k;
  value.assign(rows, 0.f);
  index.assign(rows, 0);
  for (std::size_t r = 0; r < rows; ++r) {
    std::size_t best = 0;
    for (std::size_t j = 0; j < k; ++j) {
      const float v = x[r * k + j];
      if (std::isnan(v)) {
        best = j;
        break;
      }
      if (v > x[r * k + best]) best = j;
    }
    value[r] = x[r * k + best];
    index[r] = std::int32_t(best);
  }
}

}  // namespace vkjr2::ref
