#include <vkjr2/sim/quadrature.hpp>

#include <cmath>
#include <numbers>

namespace vkjr2::sim {

GaussLegendre::GaussLegendre(int n) : x(std::size_t(n)), w(std::size_t(n)) {
  for (int i = 0; i < n; ++i) {
    double t = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double dp = 1;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = t;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (t * p1 - p0) / (t * t - 1);
      const double step = p1 / dp;
      t -= step;
      if (std::fabs(step) < 1e-16) break;
    }
    x[std::size_t(i)] = t;
    w[std::size_t(i)] = 2 / ((1 - t * t) * dp * dp);
  }
}

}  // namespace vkjr2::sim
