#include <vkjr2/kernels/ref/basic_ref.hpp>

#include <cmath>
#include <cstddef>

namespace vkjr2::ref {

void axpy(float alpha, std::span<const float> x, std::span<float> y) {
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = std::fma(alpha, x[i], y[i]);
}

double sum(std::span<const float> x) {
  double s = 0;
  for (float v : x) s += v;
  return s;
}

}  // namespace vkjr2::ref
