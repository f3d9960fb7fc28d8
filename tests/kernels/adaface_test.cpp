#include <vkjr2/kernels/adaface.hpp>
#include <vkjr2/kernels/ref/adaface_ref.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

Tensor labels_tensor(const Device& dev, const std::vector<std::int32_t>& labels) {
  Tensor t = Tensor::empty(dev, Shape{std::int64_t(labels.size())}, DType::i32);
  t.upload_bytes(labels.data(), labels.size() * sizeof(std::int32_t));
  return t;
}

std::vector<std::int32_t> random_labels(std::size_t rows, std::size_t classes, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<std::int32_t> out(rows);
  for (auto& c : out) c = std::int32_t(rng() % classes);
  return out;
}

TEST(AdaFaceKernels, ScalerMatchesReferenceAndUpdatesOnlyWhenAsked) {
  Device& dev = test::device();
  const kernels::AdaFaceParams p;
  const std::uint32_t seed = 71;
  for (std::int64_t rows : {2, 3, 65, 200}) {
    SCOPED_TRACE("rows " + std::to_string(rows) + " seed " + std::to_string(seed));
    // Norms across and beyond the clip range [0.001, 100].
    auto norms = test::random_floats(std::size_t(rows), seed + std::uint32_t(rows), -5.f, 120.f);
    Tensor n = Tensor::from(dev, Shape{rows}, norms);
    for (bool update : {true, false}) {
      float mean = 20.f, std_dev = 100.f;
      if (!update) mean = 18.f, std_dev = 3.f;  // eval: a trained state
      Tensor mu = Tensor::from(dev, {1}, std::vector<float>{mean});
      Tensor sigma = Tensor::from(dev, {1}, std::vector<float>{std_dev});
      Tensor z = Tensor::empty(dev, Shape{rows});
      Stream s(dev);
      kernels::adaface_scaler(s, n, mu, sigma, update, p, z);
      s.run();
      const auto want = ref::adaface_scaler(norms, mean, std_dev, update, p);
      test::expect_all_close("z", z.download(), want, {1e-4, 1e-5});
      EXPECT_NEAR(mu.download()[0], mean, 1e-5 * mean);
      EXPECT_NEAR(sigma.download()[0], std_dev, 1e-5 * std_dev);
      if (!update) {
        EXPECT_EQ(mu.download()[0], 18.f);
        EXPECT_EQ(sigma.download()[0], 3.f);
      }
    }
  }
}

TEST(AdaFaceKernels, ScalerFollowsTheRunningStatisticsOverSteps) {
  // Ten updates with α = 0.5 pull μ, σ from (20, 100) towards the batch's.
  Device& dev = test::device();
  kernels::AdaFaceParams p;
  p.alpha = 0.5f;
  const std::vector<float> norms = {10.f, 12.f, 14.f, 16.f};  // mean 13, std 2.582
  Tensor n = Tensor::from(dev, {4}, norms), z = Tensor::empty(dev, {4});
  Tensor mu = Tensor::from(dev, {1}, std::vector<float>{20.f});
  Tensor sigma = Tensor::from(dev, {1}, std::vector<float>{100.f});
  Stream s(dev);
  for (int i = 0; i < 10; ++i) kernels::adaface_scaler(s, n, mu, sigma, true, p, z);
  s.run();
  const double w = std::pow(0.5, 10), std_batch = std::sqrt(20.0 / 3.0);
  EXPECT_NEAR(mu.download()[0], 13.0 + (20.0 - 13.0) * w, 1e-4);
  EXPECT_NEAR(sigma.download()[0], std_batch + (100.0 - std_batch) * w, 1e-4);
}

TEST(AdaFaceKernels, MarginMatchesReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 72;
  kernels::AdaFaceParams p;
  for (const auto& [rows, classes] : std::vector<std::pair<std::int64_t, std::int64_t>>{
           {1, 1}, {3, 7}, {5, 1001}, {17, 300}, {2, 1025}}) {
    SCOPED_TRACE("shape [" + std::to_string(rows) + ", " + std::to_string(classes) + "] seed " +
                 std::to_string(seed));
    const auto n = std::size_t(rows * classes);
    // Beyond ±1: the clamp edges (zero gradient) are exercised too.
    const auto cv = test::random_floats(n, seed, -1.05f, 1.05f);
    const auto zv = test::random_floats(std::size_t(rows), seed + 1);
    const auto dyv = test::random_floats(n, seed + 2);
    const auto lv = random_labels(std::size_t(rows), std::size_t(classes), seed + 3);
    Tensor c = Tensor::from(dev, Shape{rows, classes}, cv);
    Tensor z = Tensor::from(dev, Shape{rows}, zv),
           dy = Tensor::from(dev, Shape{rows, classes}, dyv);
    Tensor lab = labels_tensor(dev, lv);
    Tensor logits = Tensor::empty(dev, Shape{rows, classes});
    Tensor dc = Tensor::empty(dev, Shape{rows, classes});
    Stream s(dev);
    kernels::adaface_margin(s, c, lab, z, p, logits);
    kernels::adaface_margin_backward(s, c, lab, z, dy, p, dc);
    s.run();
    // Logits are scaled by s = 64: absolute tolerance in those units.
    test::expect_all_close("logits", logits.download(),
                           ref::adaface_margin(cv, lv, zv, std::size_t(classes), p), {1e-4, 1e-4});
    test::expect_all_close("dc", dc.download(),
                           ref::adaface_margin_backward(cv, lv, zv, dyv, std::size_t(classes), p),
                           {1e-4, 1e-4});
  }
}

TEST(AdaFaceKernels, MarginGradientMatchesFiniteDifferences) {
  Device& dev = test::device();
  const std::int64_t rows = 4, classes = 6;
  const std::uint32_t seed = 73;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const kernels::AdaFaceParams p;
  // |cos| ≤ 0.9 and |ẑ| ≤ 1 keep every clamp and clip inactive (θ′ in [0.05, 3.09]).
  const auto cv = test::random_floats(24, seed, -0.9f, 0.9f);
  const auto zv = test::random_floats(4, seed + 1);
  const auto wv = test::random_floats(24, seed + 2);
  const auto lv = random_labels(4, 6, seed + 3);
  Tensor z = Tensor::from(dev, {rows}, zv), lab = labels_tensor(dev, lv);
  Tensor w = Tensor::from(dev, {rows, classes}, wv), dc = Tensor::empty(dev, {rows, classes});
  {
    Tensor c = Tensor::from(dev, {rows, classes}, cv);
    Stream s(dev);
    kernels::adaface_margin_backward(s, c, lab, z, w, p, dc);
    s.run();
  }
  auto loss = [&](std::span<const float> xs) {
    Tensor xt = Tensor::from(dev, {rows, classes}, xs), y = Tensor::empty(dev, {rows, classes});
    Stream st(dev);
    kernels::adaface_margin(st, xt, lab, z, p, y);
    st.run();
    return test::weighted_sum(y.download(), wv);
  };
  // Logits are O(64): a step of 1e-3 keeps fp32 rounding ~1e-2 relative at worst.
  test::expect_gradient_matches(loss, cv, dc.download(), "adaface_margin",
                                {.step = 1e-3, .rtol = 2e-2, .atol = 2e-2, .samples = 24});
}

TEST(AdaFaceKernels, ClipEdgesGiveBoundaryValuesAndZeroGradient) {
  Device& dev = test::device();
  const kernels::AdaFaceParams p;
  const double s = p.s, m = p.m, eps = p.eps;
  // Row 0: cos 0.99, ẑ = 1 → θ − m < eps: θ′ = eps, logit s(cos eps − 2m).
  // Row 1: cos −0.99, ẑ = −1 → θ + m > π − eps: θ′ = π − eps, logit −s cos eps.
  // Row 2: cos 1.5 (clamped to 1 − eps), ẑ = −1 (θ′ open): d cos = 0 by the clamp.
  // Row 3: open; label column 1.
  const std::vector<float> cv = {0.99f, 0.1f, -0.99f, 0.1f, 1.5f, 0.1f, -0.2f, 0.3f};
  const std::vector<float> zv = {1.f, -1.f, -1.f, 0.5f};
  const std::vector<std::int32_t> lv = {0, 0, 0, 1};
  Tensor c = Tensor::from(dev, {4, 2}, cv), z = Tensor::from(dev, {4}, zv);
  Tensor lab = labels_tensor(dev, lv), ones = Tensor::from(dev, {4, 2}, std::vector<float>(8, 1));
  Tensor y = Tensor::empty(dev, {4, 2}), dc = Tensor::empty(dev, {4, 2});
  Stream st(dev);
  kernels::adaface_margin(st, c, lab, z, p, y);
  kernels::adaface_margin_backward(st, c, lab, z, ones, p, dc);
  st.run();
  const auto yv = y.download(), dv = dc.download();
  EXPECT_NEAR(yv[0], s * (std::cos(eps) - 2 * m), 1e-4);
  EXPECT_EQ(dv[0], 0.f);
  EXPECT_NEAR(yv[2], -s * std::cos(eps), 1e-4);
  EXPECT_EQ(dv[2], 0.f);
  const double c1 = 1 - eps, theta = std::acos(c1) + m;
  EXPECT_NEAR(yv[4], s * std::cos(theta), 1e-3);
  EXPECT_EQ(dv[4], 0.f);
  // Open rows: s on the other columns, s·sin θ′/sin θ on the label column.
  EXPECT_NEAR(yv[6], s * -0.2, 1e-5);
  EXPECT_NEAR(dv[6], s, 1e-5);
  const double t3 = std::acos(0.3) - m * 0.5;
  EXPECT_NEAR(yv[7], s * (std::cos(t3) - 1.5 * m), 1e-4);
  EXPECT_NEAR(dv[7], s * std::sin(t3) / std::sqrt(1 - 0.09), 1e-4);
}

TEST(AdaFaceKernels, BadLabelGivesNaNRowAndBadInputsAreClearErrors) {
  Device& dev = test::device();
  const kernels::AdaFaceParams p;
  const auto cv = test::random_floats(6, 74, -0.5f, 0.5f);
  Tensor c = Tensor::from(dev, {2, 3}, cv), z = Tensor::from(dev, {2}, std::vector<float>{0, 0});
  Tensor lab = labels_tensor(dev, {1, 3});  // 3 is out of range for 3 classes
  Tensor y = Tensor::empty(dev, {2, 3}), dc = Tensor::empty(dev, {2, 3});
  Stream s(dev);
  kernels::adaface_margin(s, c, lab, z, p, y);
  kernels::adaface_margin_backward(s, c, lab, z, c, p, dc);
  s.run();
  const auto yv = y.download(), dv = dc.download();
  for (int j = 0; j < 3; ++j) {
    EXPECT_FALSE(std::isnan(yv[std::size_t(j)])) << j;
    EXPECT_TRUE(std::isnan(yv[std::size_t(3 + j)])) << j;
    EXPECT_TRUE(std::isnan(dv[std::size_t(3 + j)])) << j;
  }
  Tensor neg = labels_tensor(dev, {-1, 0});
  kernels::adaface_margin(s, c, neg, z, p, y);
  s.run();
  EXPECT_TRUE(std::isnan(y.download()[0]));

  Tensor mu = Tensor::from(dev, {1}, std::vector<float>{20.f});
  Tensor sigma = Tensor::from(dev, {1}, std::vector<float>{100.f});
  Tensor one = Tensor::from(dev, {1}, std::vector<float>{5.f}), z1 = Tensor::empty(dev, {1});
  // One norm: no unbiased std to update with; eval mode is fine.
  EXPECT_THROW(kernels::adaface_scaler(s, one, mu, sigma, true, p, z1), InvalidArgument);
  EXPECT_NO_THROW(kernels::adaface_scaler(s, one, mu, sigma, false, p, z1));
  EXPECT_THROW(kernels::adaface_scaler(s, z, mu, sigma, true, p, z1), InvalidArgument);
  EXPECT_THROW(kernels::adaface_scaler(s, z, z, sigma, true, p, z), InvalidArgument);
  Tensor f32_labels = Tensor::from(dev, {2}, std::vector<float>{0, 1});
  EXPECT_THROW(kernels::adaface_margin(s, c, f32_labels, z, p, y), InvalidArgument);
  EXPECT_THROW(kernels::adaface_margin(s, c, labels_tensor(dev, {0, 1, 2}), z, p, y),
               InvalidArgument);
  EXPECT_THROW(kernels::adaface_margin(s, c, lab, Tensor::empty(dev, {3}), p, y), InvalidArgument);
  EXPECT_THROW(kernels::adaface_margin(s, c, lab, z, p, Tensor::empty(dev, {3, 2})),
               InvalidArgument);
  EXPECT_THROW(kernels::adaface_margin(s, c.reshape({6}), lab, z, p, y.reshape({6})),
               InvalidArgument);
  EXPECT_THROW(kernels::adaface_margin_backward(s, c, lab, z, Tensor::empty(dev, {2, 2}), p, dc),
               InvalidArgument);
  EXPECT_THROW(kernels::adaface_margin(s, Tensor::empty(dev, {0, 3}), labels_tensor(dev, {}),
                                       Tensor::empty(dev, {0}), p, Tensor::empty(dev, {0, 3})),
               InvalidArgument);
  kernels::AdaFaceParams bad = p;
  bad.s = 0.f;
  EXPECT_THROW(kernels::adaface_margin(s, c, lab, z, bad, y), InvalidArgument);
  bad = p;
  bad.alpha = std::nanf("");
  EXPECT_THROW(kernels::adaface_scaler(s, z, mu, sigma, true, bad, z), InvalidArgument);
  try {
    kernels::adaface_scaler(s, one, mu, sigma, true, p, z1);
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("at least 2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vkjr2
