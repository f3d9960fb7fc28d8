#include <vkjr2/kernels/norm.hpp>
#include <vkjr2/kernels/ref/norm_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

constexpr float kEps = 1e-6f;  // NAFNet's

// One channel (x̂ = 0), one pixel, a partial 256-pixel group, NAFNet's widths.
const std::vector<Shape> kEdges = {
    {1, 1, 3, 3}, {2, 3, 1, 1}, {1, 5, 17, 17}, {2, 16, 9, 31}, {1, 64, 16, 17}};

TEST(NormKernels, LayerNormMatchesReference) {
  test::check_op(
      "layer_norm_channels", {.seed = 901, .cases = int(kEdges.size()) + 5}, [](test::OpCase& c) {
        const Shape s = c.edge_or(kEdges, [&] { return c.nchw(3, 40, 30, 30); });
        c.describe("x " + s.str());
        const std::int64_t n = s[0], ch = s[1], hw = s[2] * s[3];
        // An offset per tensor: the variance must not cancel against the mean.
        const float offset = float(c.uniform(-50, 50));
        auto xv = c.floats(s.numel(), offset - 2.f, offset + 2.f);
        const auto gv = c.floats(ch, 0.5f, 1.5f), bv = c.floats(ch);
        const auto dyv = c.floats(s.numel());
        Tensor x = c.tensor(s, xv), gamma = c.tensor({ch}, gv);
        Tensor beta = c.tensor({ch}, bv), dy = c.tensor(s, dyv);
        Tensor y = c.empty(s), dx = c.empty(s), dg = c.empty({ch}), db = c.empty({ch});
        Stream st(c.device);
        kernels::layer_norm_channels(st, x, gamma, beta, kEps, y);
        kernels::layer_norm_channels_backward(st, x, gamma, dy, kEps, &dx, &dg, &db);
        st.run();
        std::vector<float> rdx, rdg, rdb;
        ref::layer_norm_channels_backward(xv, n, ch, hw, gv, dyv, kEps, rdx, rdg, rdb);
        c.expect("y", y, ref::layer_norm_channels(xv, n, ch, hw, gv, bv, kEps), {1e-4, 1e-4});
        c.expect("dx", dx, rdx, {1e-4, 1e-4});
        // Sums over N·H·W pixels of O(1) terms.
        const double sum_tol = 1e-5 * double(n * hw);
        c.expect("dgamma", dg, rdg, {1e-4, sum_tol});
        c.expect("dbeta", db, rdb, {1e-4, sum_tol});
      });
}

TEST(NormKernels, LayerNormGradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const Shape s{2, 5, 3, 4};
  const std::int64_t ch = s[1];
  const std::uint32_t seed = 902;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto xv = test::random_floats(std::size_t(s.numel()), seed, -2.f, 2.f);
  const auto gv = test::random_floats(std::size_t(ch), seed + 1, 0.5f, 1.5f);
  const auto bv = test::random_floats(std::size_t(ch), seed + 2);
  const auto w = test::random_floats(std::size_t(s.numel()), seed + 3);
  Tensor x = Tensor::from(dev, s, xv), gamma = Tensor::from(dev, {ch}, gv);
  Tensor beta = Tensor::from(dev, {ch}, bv), wt = Tensor::from(dev, s, w);
  Tensor dx = Tensor::empty(dev, s), dg = Tensor::empty(dev, {ch}), db = Tensor::empty(dev, {ch});
  {
    Stream st(dev);
    kernels::layer_norm_channels_backward(st, x, gamma, wt, kEps, &dx, &dg, &db);
    st.run();
  }
  // L = Σ w ⊙ layer_norm(x; gamma, beta), evaluated on the device.
  auto loss = [&](std::span<const float> xs, std::span<const float> gs, std::span<const float> bs) {
    Tensor xt = Tensor::from(dev, s, xs), gt = Tensor::from(dev, {ch}, gs);
    Tensor bt = Tensor::from(dev, {ch}, bs), y = Tensor::empty(dev, s);
    Stream st(dev);
    kernels::layer_norm_channels(st, xt, gt, bt, kEps, y);
    st.run();
    return test::weighted_sum(y.download(), w);
  };
  test::expect_gradient_matches([&](std::span<const float> xs) { return loss(xs, gv, bv); }, xv,
                                dx.download(), "dx", {.step = 1e-2});
  test::expect_gradient_matches([&](std::span<const float> gs) { return loss(xv, gs, bv); }, gv,
                                dg.download(), "dgamma");
  test::expect_gradient_matches([&](std::span<const float> bs) { return loss(xv, gv, bs); }, bv,
                                db.download(), "dbeta");
}

TEST(NormKernels, LayerNormOfAConstantPixelIsBetaAndNaNStaysInItsPixel) {
  Device& dev = test::device();
  // Pixel 0: constant over the channels (x̂ = 0, y = beta); pixel 1: a NaN.
  const std::vector<float> xv = {3.f, NAN, 3.f, 1.f, 3.f, 2.f};  // [1, 3, 1, 2]
  Tensor x = Tensor::from(dev, {1, 3, 1, 2}, xv);
  Tensor gamma = Tensor::from(dev, {3}, std::vector<float>{2.f, 2.f, 2.f});
  Tensor beta = Tensor::from(dev, {3}, std::vector<float>{0.5f, -1.f, 4.f});
  Tensor y = Tensor::empty(dev, {1, 3, 1, 2});
  Stream st(dev);
  kernels::layer_norm_channels(st, x, gamma, beta, kEps, y);
  st.run();
  const auto yv = y.download();
  EXPECT_EQ(yv[0], 0.5f);
  EXPECT_EQ(yv[2], -1.f);
  EXPECT_EQ(yv[4], 4.f);
  for (int c = 0; c < 3; ++c) EXPECT_TRUE(std::isnan(yv[std::size_t(2 * c + 1)])) << c;
}

TEST(NormKernels, LayerNormBadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream st(dev);
  Tensor x = Tensor::empty(dev, {1, 4, 5, 5}), y = Tensor::empty(dev, {1, 4, 5, 5});
  Tensor g4 = Tensor::empty(dev, {4}), g3 = Tensor::empty(dev, {3});
  test::expect_invalid_argument([&] { kernels::layer_norm_channels(st, x, g3, g4, kEps, y); },
                                "gamma");
  test::expect_invalid_argument([&] { kernels::layer_norm_channels(st, x, g4, g3, kEps, y); },
                                "beta");
  test::expect_invalid_argument([&] { kernels::layer_norm_channels(st, x, g4, g4, 0.f, y); },
                                "eps");
  test::expect_invalid_argument(
      [&] {
        kernels::layer_norm_channels(st, x, g4, g4, std::numeric_limits<float>::quiet_NaN(), y);
      },
      "eps");
  Tensor flat = Tensor::empty(dev, {4, 25});
  test::expect_invalid_argument([&] { kernels::layer_norm_channels(st, flat, g4, g4, kEps, flat); },
                                "rank");
  Tensor y_bad = Tensor::empty(dev, {1, 4, 5, 4});
  test::expect_invalid_argument([&] { kernels::layer_norm_channels(st, x, g4, g4, kEps, y_bad); },
                                "y");
  test::expect_invalid_argument(
      [&] { kernels::layer_norm_channels_backward(st, x, g4, y, kEps, nullptr, nullptr, nullptr); },
      "null");
  test::expect_invalid_argument(
      [&] { kernels::layer_norm_channels_backward(st, x, g4, y, kEps, &y_bad, nullptr, nullptr); },
      "dx");
  test::expect_invalid_argument(
      [&] { kernels::layer_norm_channels_backward(st, x, g4, y, kEps, nullptr, &g3, nullptr); },
      "dgamma");
}

}  // namespace
}  // namespace vkjr2
