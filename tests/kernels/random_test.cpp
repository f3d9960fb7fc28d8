#include <vkjr2/kernels/random.hpp>
#include <vkjr2/kernels/ref/random_ref.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

constexpr std::uint64_t kSeed = 0x1234'5678'9abc'def0ull;

// Device vs reference: the hash is exact integer arithmetic; the normals
// differ only by float rounding (measured: ≤ 5e-7).
TEST(Random, RandnMatchesReference) {
  Device& dev = test::device();
  for (std::int64_t n : {1, 3, 4, 5, 1023, 1024, 1025, 77777}) {
    SCOPED_TRACE("n=" + std::to_string(n));
    Tensor t = Tensor::empty(dev, {n});
    Stream s(dev);
    kernels::randn(s, t, kSeed, 7, 0.5f, 2.f);
    s.run();
    std::vector<float> want(static_cast<std::size_t>(n));
    ref::randn(want, kSeed, 7, 0.5f, 2.f);
    test::expect_all_close("t", t.download(), want, {1e-5, 2e-6});
  }
}

TEST(Random, SameSeedSameNumbersOtherStreamIndependent) {
  Device& dev = test::device();
  const std::int64_t n = 1 << 16;
  Tensor a = Tensor::empty(dev, {n}), b = Tensor::empty(dev, {n}), c = Tensor::empty(dev, {n});
  Stream s(dev);
  kernels::randn(s, a, 42, 0);
  kernels::randn(s, b, 42, 0);
  kernels::randn(s, c, 42, 1);
  s.run();
  const auto va = a.download(), vb = b.download(), vc = c.download();
  EXPECT_EQ(va, vb);
  // Correlation of independent streams: σ = 1/√n = 0.004; 4σ bound.
  double sab = 0;
  for (std::size_t i = 0; i < va.size(); ++i) sab += double(va[i]) * vc[i];
  EXPECT_LT(std::fabs(sab / double(n)), 4.0 / std::sqrt(double(n)));
}

// Moments of 2^20 draws, each bound 4σ of its estimator: mean σ = 1/√n,
// variance σ = √(2/n), 4th moment (3) σ = √(96/n), lag-1 and lag-4
// correlations σ = 1/√n.
TEST(Random, MomentsAndIndependence) {
  Device& dev = test::device();
  const std::int64_t n = 1 << 20;
  Tensor t = Tensor::empty(dev, {n});
  Stream s(dev);
  kernels::randn(s, t, 2024, 3);
  s.run();
  const auto v = t.download();
  double m1 = 0, m2 = 0, m4 = 0, lag1 = 0, lag4 = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double x = v[i];
    m1 += x;
    m2 += x * x;
    m4 += x * x * x * x;
    if (i + 1 < v.size()) lag1 += x * v[i + 1];
    if (i + 4 < v.size()) lag4 += x * v[i + 4];
  }
  const double dn = double(n);
  EXPECT_NEAR(m1 / dn, 0.0, 4 / std::sqrt(dn));
  EXPECT_NEAR(m2 / dn, 1.0, 4 * std::sqrt(2 / dn));
  EXPECT_NEAR(m4 / dn, 3.0, 4 * std::sqrt(96 / dn));
  EXPECT_NEAR(lag1 / dn, 0.0, 4 / std::sqrt(dn));
  EXPECT_NEAR(lag4 / dn, 0.0, 4 / std::sqrt(dn));
  // Tail: P(|x| > 3) = 0.0027; binomial σ = √(p/n).
  std::size_t tail = 0;
  for (float x : v) tail += std::fabs(x) > 3.f;
  EXPECT_NEAR(double(tail) / dn, 0.0026998, 4 * std::sqrt(0.0027 / dn));
}

TEST(Random, Ar1MatchesReferenceAndKeepsUnitVariance) {
  Device& dev = test::device();
  const std::int64_t n = 1 << 18;
  Tensor x = Tensor::empty(dev, {n});
  Stream s(dev);
  kernels::randn(s, x, 5, 0);
  s.run();
  const auto x0 = x.download();
  const float rho = 0.8f;
  std::vector<float> want = x0;
  for (std::uint32_t t = 1; t <= 3; ++t) {
    kernels::randn_ar1(s, x, rho, 5, t);
    ref::randn_ar1(want, rho, 5, t);
  }
  s.run();
  const auto x3 = x.download();
  test::expect_all_close("x3", x3, want, {1e-5, 3e-6});
  // Lag-3 correlation ρ³ = 0.512 (σ ≈ (1 − ρ⁶)/√n ≈ 0.0014), variance 1.
  double c = 0, v = 0;
  for (std::size_t i = 0; i < x3.size(); ++i) {
    c += double(x0[i]) * x3[i];
    v += double(x3[i]) * x3[i];
  }
  EXPECT_NEAR(c / double(n), 0.512, 4 * 0.0014);
  EXPECT_NEAR(v / double(n), 1.0, 4 * std::sqrt(2.0 / double(n)));
}

TEST(Random, SensorNoiseMatchesReferenceInPlaceAndOut) {
  Device& dev = test::device();
  const std::int64_t n = 4099;
  auto xs = test::random_floats(std::size_t(n), 11, -0.1f, 1.f);
  Tensor x = Tensor::from(dev, {n}, xs);
  Tensor y = Tensor::empty(dev, {n});
  Stream s(dev);
  kernels::sensor_noise(s, x, y, 1.f / 500, 0.01f, 9, 2);
  kernels::sensor_noise(s, x, x, 1.f / 500, 0.01f, 9, 2);
  s.run();
  std::vector<float> want(xs.size());
  ref::sensor_noise(xs, want, 1.f / 500, 0.01f, 9, 2);
  test::expect_all_close("y", y.download(), want, {1e-5, 1e-6});
  test::expect_all_close("x", x.download(), want, {1e-5, 1e-6});
}

TEST(Random, BadArgumentsAreClearErrors) {
  Device& dev = test::device();
  Tensor x = Tensor::empty(dev, {8});
  Tensor y = Tensor::empty(dev, {9});
  Stream s(dev);
  EXPECT_THROW(kernels::randn_ar1(s, x, 1.5f, 1, 0), InvalidArgument);
  EXPECT_THROW(kernels::randn_ar1(s, x, NAN, 1, 0), InvalidArgument);
  EXPECT_THROW(kernels::randn(s, x, 1, 0, 0.f, INFINITY), InvalidArgument);
  EXPECT_THROW(kernels::sensor_noise(s, x, y, 0.01f, 0.f, 1, 0), InvalidArgument);
  EXPECT_THROW(kernels::sensor_noise(s, x, x, -1.f, 0.f, 1, 0), InvalidArgument);
  Tensor empty = Tensor::empty(dev, {0});
  EXPECT_THROW(kernels::randn(s, empty, 1, 0), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
