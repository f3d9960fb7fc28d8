#include <vkjr2/kernels/ref/adaface_ref.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace vkjr2::ref {
namespace {

double safe_norm(float x) { return std::clamp(double(x), 0.001, 100.0); }

bool valid_label(std::int32_t c, std::size_t classes) { return c >= 0 && std::size_t(c) < classes; }

}  // namespace

std::vector<float> adaface_scaler(std::span<const float> norms, float& running_mean,
                                  float& running_std, bool update,
                                  const kernels::AdaFaceParams& p) {
  const std::size_t b = norms.size();
  double mu = running_mean, sigma = running_std;
  if (update) {
    double sum = 0;
    for (float x : norms) sum += safe_norm(x);
    const double mean = sum / double(b);
    double ss = 0;
    for (float x : norms) ss += (safe_norm(x) - mean) * (safe_norm(x) - mean);
    const double std_dev = std::sqrt(ss / double(b - 1));
    mu = p.alpha * mean + (1.0 - p.alpha) * mu;
    sigma = p.alpha * std_dev + (1.0 - p.alpha) * sigma;
    running_mean = float(mu);
    running_std = float(sigma);
  }
  std::vector<float> out(b);
  for (std::size_t i = 0; i < b; ++i) {
    out[i] = float(std::clamp(p.h * (safe_norm(norms[i]) - mu) / (sigma + p.eps), -1.0, 1.0));
  }
  return out;
}

std::vector<float> adaface_margin(std::span<const float> cos, std::span<const std::int32_t> labels,
                                  std::span<const float> scaler, std::size_t classes,
                                  const kernels::AdaFaceParams& p) {
  const double eps = p.eps, m = p.m, pi = std::numbers::pi;
  std::vector<float> out(cos.size());
  for (std::size_t r = 0; r < labels.size(); ++r) {
    for (std::size_t j = 0; j < classes; ++j) {
      const std::size_t i = r * classes + j;
      if (!valid_label(labels[r], classes)) {
        out[i] = std::numeric_limits<float>::quiet_NaN();
        continue;
      }
      const double c = std::clamp(double(cos[i]), -1.0 + eps, 1.0 - eps);
      if (j != std::size_t(labels[r])) {
        out[i] = float(p.s * c);
        continue;
      }
      const double z = scaler[r];
      const double theta = std::clamp(std::acos(c) - m * z, eps, pi - eps);
      out[i] = float(p.s * (std::cos(theta) - (m + m * z)));
    }
  }
  return out;
}

std::vector<float> adaface_margin_backward(std::span<const float> cos,
                                           std::span<const std::int32_t> labels,
                                           std::span<const float> scaler, std::span<const float> dy,
                                           std::size_t classes, const kernels::AdaFaceParams& p) {
  const double eps = p.eps, m = p.m, pi = std::numbers::pi;
  std::vector<float> out(cos.size());
  for (std::size_t r = 0; r < labels.size(); ++r) {
    for (std::size_t j = 0; j < classes; ++j) {
      const std::size_t i = r * classes + j;
      if (!valid_label(labels[r], classes)) {
        out[i] = std::numeric_limits<float>::quiet_NaN();
        continue;
      }
      const double x = cos[i];
      const bool inside = x >= -1.0 + eps && x <= 1.0 - eps;
      const double g = double(dy[i]) * p.s;
      if (j != std::size_t(labels[r])) {
        out[i] = inside ? float(g) : 0.f;
        continue;
      }
      const double c = std::clamp(x, -1.0 + eps, 1.0 - eps);
      const double theta = std::acos(c) - m * double(scaler[r]);
      const bool open = theta >= eps && theta <= pi - eps;
      // d/dc cos(acos(c) − m ẑ) = sin θ′ / sqrt(1 − c²).
      out[i] = inside && open ? float(g * std::sin(theta) / std::sqrt(1.0 - c * c)) : 0.f;
    }
  }
  return out;
}

}  // namespace vkjr2::ref
