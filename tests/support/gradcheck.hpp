// Finite-difference gradient checks for backward kernels.
//
// Usage: write the loss L(x) = Σ w ⊙ f(x) with fixed random weights w, run
// the forward on the device, and compare the analytic gradient dL/dx from
// the backward kernel (fed w as the output gradient) with central
// differences (L(x + h e_i) − L(x − h e_i)) / 2h on sampled coordinates.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <span>
#include <string>
#include <vector>

namespace vkjr2::test {

struct GradCheckOptions {
  double step = 1e-2;        // h, in units of the input (fp32 forward: keep ≥ 1e-3)
  double rtol = 2e-2;        // relative tolerance on each checked coordinate
  double atol = 2e-3;        // absolute tolerance (gradients near 0)
  std::size_t samples = 48;  // coordinates checked (all when the input is smaller)
  std::uint32_t seed = 1;
};

// loss(x) evaluates the device forward at x and returns Σ w ⊙ f(x) (in
// double on the host). `analytic` is dL/dx from the backward kernel.
inline void expect_gradient_matches(const std::function<double(std::span<const float>)>& loss,
                                    std::vector<float> x, std::span<const float> analytic,
                                    const std::string& what, GradCheckOptions o = {}) {
  ASSERT_EQ(x.size(), analytic.size()) << what;
  std::vector<std::size_t> idx(x.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  if (idx.size() > o.samples) {
    std::mt19937 rng(o.seed);
    std::shuffle(idx.begin(), idx.end(), rng);
    idx.resize(o.samples);
  }
  for (std::size_t i : idx) {
    const float saved = x[i];
    x[i] = static_cast<float>(saved + o.step);
    const double plus = loss(x);
    x[i] = static_cast<float>(saved - o.step);
    const double minus = loss(x);
    x[i] = saved;
    const double numeric = (plus - minus) / (2 * o.step);
    const double tol =
        o.atol + o.rtol * std::max(std::fabs(numeric), std::fabs(double(analytic[i])));
    EXPECT_NEAR(analytic[i], numeric, tol)
        << what << ": d/dx[" << i << "] analytic " << analytic[i] << " vs numeric " << numeric
        << " (seed " << o.seed << ", step " << o.step << ")";
  }
}

// Σ w ⊙ y in double.
inline double weighted_sum(std::span<const float> y, std::span<const float> w) {
  double s = 0;
  for (std::size_t i = 0; i < y.size(); ++i) s += double(y[i]) * double(w[i]);
  return s;
}

}  // namespace vkjr2::test
