#include <vkjr2/kernels/ref/norm_ref.hpp>

#include <cmath>

namespace vkjr2::ref {
namespace {

struct PixelStats {
  double mu, rstd;
};

// Mean and 1/sqrt(variance + eps) of one pixel's channels (two passes).
PixelStats pixel_stats(std::span<const float> x, std::int64_t c, std::int64_t hw, std::int64_t base,
                       double eps) {
  double sum = 0;
  for (std::int64_t k = 0; k < c; ++k) sum += x[std::size_t(base + k * hw)];
  const double mu = sum / double(c);
  double sq = 0;
  for (std::int64_t k = 0; k < c; ++k) {
    const double d = x[std::size_t(base + k * hw)] - mu;
    sq += d * d;
  }
  return {mu, 1.0 / std::sqrt(sq / double(c) + eps)};
}

}  // namespace

std::vector<float> layer_norm_channels(std::span<const float> x, std::int64_t n, std::int64_t c,
                                       std::int64_t hw, std::span<const float> gamma,
                                       std::span<const float> beta, double eps) {
  std::vector<float> y(x.size());
  for (std::int64_t i = 0; i < n; ++i) {
    for (std::int64_t p = 0; p < hw; ++p) {
      const std::int64_t base = i * c * hw + p;
      const auto [mu, rstd] = pixel_stats(x, c, hw, base, eps);
      for (std::int64_t k = 0; k < c; ++k) {
        const std::size_t j = std::size_t(base + k * hw);
        y[j] = float(gamma[std::size_t(k)] * (x[j] - mu) * rstd + beta[std::size_t(k)]);
      }
    }
  }
  return y;
}

void layer_norm_channels_backward(std::span<const float> x, std::int64_t n, std::int64_t c,
                                  std::int64_t hw, std::span<const float> gamma,
                                  std::span<const float> dy, double eps, std::vector<float>& dx,
                                  std::vector<float>& dgamma, std::vector<float>& dbeta) {
  dx.assign(x.size(), 0.f);
  std::vector<double> dg(static_cast<std::size_t>(c), 0.0), db(dg), xhat(dg);
  for (std::int64_t i = 0; i < n; ++i) {
    for (std::int64_t p = 0; p < hw; ++p) {
      const std::int64_t base = i * c * hw + p;
      const auto [mu, rstd] = pixel_stats(x, c, hw, base, eps);
      double mean_g = 0, mean_gx = 0;
      for (std::int64_t k = 0; k < c; ++k) {
        const std::size_t j = std::size_t(base + k * hw);
        xhat[std::size_t(k)] = (x[j] - mu) * rstd;
        const double g = double(dy[j]) * gamma[std::size_t(k)];
        mean_g += g;
        mean_gx += g * xhat[std::size_t(k)];
        dg[std::size_t(k)] += double(dy[j]) * xhat[std::size_t(k)];
        db[std::size_t(k)] += dy[j];
      }
      mean_g /= double(c);
      mean_gx /= double(c);
      for (std::int64_t k = 0; k < c; ++k) {
        const std::size_t j = std::size_t(base + k * hw);
        const double g = double(dy[j]) * gamma[std::size_t(k)];
        dx[j] = float((g - mean_g - xhat[std::size_t(k)] * mean_gx) * rstd);
      }
    }
  }
  dgamma.assign(dg.begin(), dg.end());
  dbeta.assign(db.begin(), db.end());
}

}  // namespace vkjr2::ref
