#include <vkjr2/kernels/ref/metrics_ref.hpp>

#include <cmath>
#include <limits>

namespace vkjr2::ref {

std::vector<double> psnr(std::span<const float> a, std::span<const float> b, std::int64_t n,
                         std::int64_t c, std::int64_t h, std::int64_t w, double data_range) {
  std::vector<double> out(static_cast<std::size_t>(n));
  const std::int64_t per = c * h * w;
  for (std::int64_t i = 0; i < n; ++i) {
    double se = 0;
    for (std::int64_t k = i * per; k < (i + 1) * per; ++k) {
      const double d = double(a[std::size_t(k)]) - double(b[std::size_t(k)]);
      se += d * d;
    }
    const double mse = se / double(per);
    out[std::size_t(i)] = mse == 0 ? std::numeric_limits<double>::infinity()
                                   : 10 * std::log10(data_range * data_range / mse);
  }
  return out;
}

std::vector<double> ssim(std::span<const float> x, std::span<const float> y, std::int64_t n,
                         std::int64_t c, std::int64_t h, std::int64_t w, double data_range) {
  // The 11×11 window: exp(−(u² + v²) / 2σ²), normalized to sum 1.
  double win[11][11];
  double total = 0;
  for (int u = 0; u < 11; ++u) {
    for (int v = 0; v < 11; ++v) {
      win[u][v] = std::exp(-double((u - 5) * (u - 5) + (v - 5) * (v - 5)) / (2 * 1.5 * 1.5));
      total += win[u][v];
    }
  }
  for (auto& row : win) {
    for (double& v : row) v /= total;
  }
  const double c1 = (0.01 * data_range) * (0.01 * data_range);
  const double c2 = (0.03 * data_range) * (0.03 * data_range);
  std::vector<double> out(static_cast<std::size_t>(n));
  for (std::int64_t img = 0; img < n; ++img) {
    double sum = 0;
    for (std::int64_t ch = 0; ch < c; ++ch) {
      const std::int64_t base = (img * c + ch) * h * w;
      for (std::int64_t i = 0; i + 11 <= h; ++i) {
        for (std::int64_t j = 0; j + 11 <= w; ++j) {
          double mx = 0, my = 0, xx = 0, yy = 0, xy = 0;
          for (int u = 0; u < 11; ++u) {
            for (int v = 0; v < 11; ++v) {
              const auto k = static_cast<std::size_t>(base + (i + u) * w + j + v);
              const double a = x[k], b = y[k], g = win[u][v];
              mx += g * a;
              my += g * b;
              xx += g * a * a;
              yy += g * b * b;
              xy += g * a * b;
            }
          }
          const double sxx = xx - mx * mx, syy = yy - my * my, sxy = xy - mx * my;
          sum +=
              ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2));
        }
      }
    }
    out[std::size_t(img)] = sum / double(c * (h - 10) * (w - 10));
  }
  return out;
}

}  // namespace vkjr2::ref
