#include <vkjr2/kernels/metrics.hpp>
#include <vkjr2/kernels/ref/metrics_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// y = clamp(x + noise) in [0, 1]: a correlated pair, as in image restoration.
std::vector<float> noisy(const std::vector<float>& x, std::uint32_t seed, float sigma) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, sigma);
  std::vector<float> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = std::clamp(x[i] + noise(rng), 0.f, 1.f);
  return y;
}

std::vector<float> run_ssim(Device& dev, const Shape& s, std::span<const float> xv,
                            std::span<const float> yv, float range) {
  Tensor x = Tensor::from(dev, s, xv), y = Tensor::from(dev, s, yv),
         out = Tensor::empty(dev, {s[0]});
  Stream st(dev);
  kernels::ssim(st, x, y, range, out);
  st.run();
  return out.download();
}

std::vector<float> to_float(const std::vector<double>& v) { return {v.begin(), v.end()}; }

TEST(MetricsKernels, PsnrMatchesReference) {
  const std::vector<Shape> edges = {{1, 1, 1, 1}, {2, 3, 7, 5}, {3, 1, 33, 47}, {2, 3, 64, 61}};
  test::check_op("psnr", {.seed = 801, .cases = int(edges.size()) + 4}, [&](test::OpCase& c) {
    const Shape s = c.edge_or(edges, [&] { return c.nchw(3, 3, 64, 64); });
    c.describe("a, b " + s.str());
    for (float range : {1.f, 255.f}) {
      const std::string l = " L=" + std::to_string(int(range));
      const auto av = c.floats(s.numel(), 0.f, range), bv = c.floats(s.numel(), 0.f, range);
      Tensor a = c.tensor(s, av), b = c.tensor(s, bv);
      Tensor out = c.empty({s[0]});
      Stream st(c.device);
      kernels::psnr(st, a, b, range, out);
      st.run();
      c.expect("psnr" + l, out, to_float(ref::psnr(av, bv, s[0], s[1], s[2], s[3], range)),
               {1e-4, 0});
    }
  });
}

TEST(MetricsKernels, PsnrOfIdenticalImagesIsInfinite) {
  Device& dev = test::device();
  const auto av = test::random_floats(2 * 3 * 9 * 9, 802, 0.f, 1.f);
  auto bv = av;
  bv[3 * 81 + 5] += 0.5f;  // second image differs in one pixel
  Tensor a = Tensor::from(dev, {2, 3, 9, 9}, av), b = Tensor::from(dev, {2, 3, 9, 9}, bv);
  Tensor out = Tensor::empty(dev, {2});
  Stream st(dev);
  kernels::psnr(st, a, b, 1.f, out);
  st.run();
  const auto got = out.download();
  EXPECT_TRUE(std::isinf(got[0]) && got[0] > 0) << got[0];
  EXPECT_NEAR(got[1], 10 * std::log10(243.0 / 0.25), 1e-4);  // mse = 0.25 / 243
}

TEST(MetricsKernels, SsimMatchesReference) {
  const std::vector<Shape> edges = {{1, 1, 11, 11}, {2, 3, 16, 13}, {1, 1, 11, 40},
                                    {1, 2, 37, 12}, {3, 3, 29, 31}, {1, 1, 70, 65}};
  test::check_op("ssim", {.seed = 803, .cases = int(edges.size()) + 4}, [&](test::OpCase& c) {
    // Random images at least one 11×11 window large, no larger than the edges
    // (the reference's direct windows are slow).
    const Shape s = c.edge_or(edges, [&]() -> Shape {
      return {c.uniform(1, 2), c.uniform(1, 3), c.uniform(11, 48), c.uniform(11, 48)};
    });
    c.describe("x, y " + s.str());
    const auto xv = c.floats(s.numel(), 0.f, 1.f);
    const auto yv = noisy(xv, std::uint32_t(c.rng()()), 0.2f);
    const auto want = to_float(ref::ssim(xv, yv, s[0], s[1], s[2], s[3], 1.0));
    c.expect("ssim", run_ssim(c.device, s, xv, yv, 1.f), want, {0, 1e-4});
    // Data range 255: the same images scaled by 255 give the same SSIM.
    std::vector<float> x255(xv), y255(yv);
    for (float& v : x255) v *= 255.f;
    for (float& v : y255) v *= 255.f;
    c.expect("ssim L=255", run_ssim(c.device, s, x255, y255, 255.f), want, {0, 1e-4});
  });
}

TEST(MetricsKernels, SsimKnownValues) {
  Device& dev = test::device();
  const Shape s{1, 1, 16, 16};
  // SSIM(x, x) = 1.
  const auto xv = test::random_floats(256, 804, 0.f, 1.f);
  EXPECT_NEAR(run_ssim(dev, s, xv, xv, 1.f)[0], 1.0, 1e-5);
  // Constant images a and b: variances vanish, so
  // SSIM = (2ab + C1) / (a² + b² + C1) exactly (the C2 factors cancel).
  const std::vector<float> a(256, 0.5f), b(256, 0.25f);
  const double c1 = 1e-4;
  const double want = (2 * 0.5 * 0.25 + c1) / (0.25 + 0.0625 + c1);
  EXPECT_NEAR(ref::ssim(a, b, 1, 1, 16, 16, 1.0)[0], want, 1e-12);
  EXPECT_NEAR(run_ssim(dev, s, a, b, 1.f)[0], want, 1e-5);
  // A checkerboard against its inverse: strong negative correlation. The
  // value is the reference's (direct 11×11 windows in double).
  std::vector<float> board(256), inverse(256);
  for (int i = 0; i < 256; ++i) {
    board[std::size_t(i)] = float(((i / 16) + (i % 16)) % 2);
    inverse[std::size_t(i)] = 1.f - board[std::size_t(i)];
  }
  const double board_ssim = ref::ssim(board, inverse, 1, 1, 16, 16, 1.0)[0];
  EXPECT_LT(board_ssim, -0.9);
  EXPECT_NEAR(run_ssim(dev, s, board, inverse, 1.f)[0], board_ssim, 1e-4);
}

TEST(MetricsKernels, SsimGradientMatchesFiniteDifferences) {
  Device& dev = test::device();
  const std::uint32_t seed = 805;
  SCOPED_TRACE("seed=" + std::to_string(seed));
  const Shape s{2, 2, 13, 14};
  const auto xv = test::random_floats(std::size_t(s.numel()), seed, 0.f, 1.f);
  const auto yv = noisy(xv, seed + 1, 0.2f);
  const std::vector<float> w = {0.8f, -1.7f};
  Tensor x = Tensor::from(dev, s, xv), y = Tensor::from(dev, s, yv);
  Tensor d_ssim = Tensor::from(dev, {2}, w), dx = Tensor::empty(dev, s);
  Stream st(dev);
  kernels::ssim_backward(st, x, y, 1.f, d_ssim, dx);
  st.run();
  test::GradCheckOptions o;
  o.step = 4e-3;
  o.atol = 2e-4;
  o.rtol = 2e-2;
  o.samples = 64;
  o.seed = seed;
  test::expect_gradient_matches(
      [&](std::span<const float> xi) {
        return test::weighted_sum(run_ssim(dev, s, xi, yv, 1.f), w);
      },
      xv, dx.download(), "ssim", o);
}

TEST(MetricsKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream st(dev);
  Tensor a = Tensor::empty(dev, {2, 1, 12, 12}), b = Tensor::empty(dev, {2, 1, 12, 12});
  Tensor out2 = Tensor::empty(dev, {2}), out3 = Tensor::empty(dev, {3});
  EXPECT_THROW(kernels::ssim(st, a, b, 1.f, out3), InvalidArgument);
  EXPECT_THROW(kernels::psnr(st, a, b, 0.f, out2), InvalidArgument);
  EXPECT_THROW(kernels::ssim(st, a, b, -1.f, out2), InvalidArgument);
  Tensor c = Tensor::empty(dev, {2, 1, 12, 13});
  EXPECT_THROW(kernels::psnr(st, a, c, 1.f, out2), InvalidArgument);
  Tensor small = Tensor::empty(dev, {2, 1, 10, 12});
  try {
    kernels::ssim(st, small, small, 1.f, out2);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("11"), std::string::npos) << e.what();
  }
  try {
    Tensor empty = Tensor::empty(dev, {0, 1, 12, 12});
    kernels::psnr(st, empty, empty, 1.f, out2);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos) << e.what();
  }
  EXPECT_THROW(kernels::ssim_backward(st, a, b, 1.f, out2, c), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
