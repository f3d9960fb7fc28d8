#include <vkjr2/kernels/ref/optim_ref.hpp>

#include <cmath>
#include <cstddef>

namespace vkjr2::ref {

void sgd_step(std::span<float> p, std::span<const float> g, std::span<float> v,
              const kernels::SgdOptions& o) {
  for (std::size_t i = 0; i < p.size(); ++i) {
    const float gi = g[i] + o.weight_decay * p[i];
    v[i] = o.momentum * v[i] + gi;
    p[i] = p[i] - o.lr * v[i];
  }
}

void adam_step(std::span<float> p, std::span<const float> g, std::span<float> m, std::span<float> v,
               std::uint32_t step, const kernels::AdamOptions& o) {
  const double bc1 = 1.0 - std::pow(double(o.beta1), double(step));
  const double bc2 = 1.0 - std::pow(double(o.beta2), double(step));
  const auto step_size = float(double(o.lr) / bc1);
  const auto bc2_sqrt = float(std::sqrt(bc2));
  for (std::size_t i = 0; i < p.size(); ++i) {
    float w = p[i], gi = g[i];
    if (o.decoupled) {
      w *= 1.f - o.lr * o.weight_decay;
    } else {
      gi += o.weight_decay * w;
    }
    m[i] = o.beta1 * m[i] + (1.f - o.beta1) * gi;
    v[i] = o.beta2 * v[i] + (1.f - o.beta2) * gi * gi;
    p[i] = w - step_size * (m[i] / (std::sqrt(v[i]) / bc2_sqrt + o.eps));
  }
}

}  // namespace vkjr2::ref
