#include <vkjr2/kernels/psf_conv.hpp>
#include <vkjr2/kernels/ref/psf_conv_ref.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using ref::PsfConvDims;

Shape x_shape(const PsfConvDims& d) { return {d.n, d.c, d.h, d.w}; }
Shape beta_shape(const PsfConvDims& d) { return {d.n, d.k, d.h, d.w}; }
Shape psi_shape(const PsfConvDims& d) { return {d.k, d.s, d.s}; }
Shape norm_shape(const PsfConvDims& d) { return {d.n, 1, d.h, d.w}; }

std::size_t count(const Shape& s) { return static_cast<std::size_t>(s.numel()); }

struct Inputs {
  std::vector<float> x, beta, psi;
};

// Positive weights and kernels keep the normalized form's denominator away
// from zero, as physical PSFs and mixing weights are.
Inputs random_inputs(const PsfConvDims& d, std::uint32_t seed) {
  return {test::random_floats(count(x_shape(d)), seed, 0.f, 1.f),
          test::random_floats(count(beta_shape(d)), seed + 1, 0.2f, 1.f),
          test::random_floats(count(psi_shape(d)), seed + 2, 0.1f, 1.f)};
}

std::vector<float> forward(const PsfConvDims& d, const std::vector<float>& x,
                           const std::vector<float>& beta, const std::vector<float>& psi,
                           bool normalize, std::vector<float>* norm_out = nullptr) {
  Device& dev = test::device();
  Tensor tx = Tensor::from(dev, x_shape(d), x);
  Tensor tb = Tensor::from(dev, beta_shape(d), beta);
  Tensor tp = Tensor::from(dev, psi_shape(d), psi);
  Tensor ty = Tensor::empty(dev, x_shape(d));
  Tensor tn = Tensor::empty(dev, norm_shape(d));
  Stream s(dev);
  kernels::psf_conv(s, tx, tb, tp, ty, tn, {normalize});
  s.run();
  if (norm_out) *norm_out = tn.download();
  return ty.download();
}

TEST(PsfConv, MatchesReferenceOnRandomShapes) {
  std::mt19937 rng(2024);
  for (int trial = 0; trial < 10; ++trial) {
    PsfConvDims d;
    d.n = 1 + int(rng() % 2);
    d.c = 1 + int(rng() % 4);
    d.k = 1 + int(rng() % 12);
    d.h = 1 + int(rng() % 37);
    d.w = 1 + int(rng() % 41);
    d.s = 1 + 2 * int(rng() % 4);
    const bool normalize = trial % 2 == 1;
    SCOPED_TRACE("trial " + std::to_string(trial) + " seed 2024: N" + std::to_string(d.n) + " C" +
                 std::to_string(d.c) + " K" + std::to_string(d.k) + " " + std::to_string(d.h) +
                 "x" + std::to_string(d.w) + " S" + std::to_string(d.s) +
                 (normalize ? " normalized" : " plain"));
    const Inputs in = random_inputs(d, 100 + trial);
    std::vector<float> norm;
    const auto y = forward(d, in.x, in.beta, in.psi, normalize, &norm);
    std::vector<float> ry, rnorm;
    ref::psf_conv(d, in.x, in.beta, in.psi, normalize, ry, rnorm);
    for (std::size_t i = 0; i < y.size(); ++i) {
      ASSERT_NEAR(y[i], ry[i], 1e-4f * (1 + std::fabs(ry[i]))) << "y[" << i << "]";
    }
    for (std::size_t i = 0; i < norm.size(); ++i) {
      ASSERT_NEAR(norm[i], rnorm[i], 1e-4f * (1 + std::fabs(rnorm[i]))) << "norm[" << i << "]";
    }
  }
}

// The FFT path against the C++ reference, odd sizes and kernel chunks
// included (a large basis at 1×1 pixel forces several chunks).
TEST(PsfConv, FftPathMatchesReference) {
  std::mt19937 rng(77);
  Device& dev = test::device();
  for (int trial = 0; trial < 8; ++trial) {
    PsfConvDims d;
    d.n = 1 + int(rng() % 2);
    d.c = 1 + int(rng() % 4);
    d.k = 1 + int(rng() % 12);
    d.h = 1 + int(rng() % 45);
    d.w = 1 + int(rng() % 50);
    d.s = 1 + 2 * int(rng() % 6);
    const bool normalize = trial % 2 == 0;
    SCOPED_TRACE("trial " + std::to_string(trial) + " seed 77: N" + std::to_string(d.n) + " C" +
                 std::to_string(d.c) + " K" + std::to_string(d.k) + " " + std::to_string(d.h) +
                 "x" + std::to_string(d.w) + " S" + std::to_string(d.s));
    const Inputs in = random_inputs(d, 300 + trial);
    Tensor tx = Tensor::from(dev, x_shape(d), in.x), tb = Tensor::from(dev, beta_shape(d), in.beta);
    Tensor tp = Tensor::from(dev, psi_shape(d), in.psi);
    Tensor ty = Tensor::empty(dev, x_shape(d)), tn = Tensor::empty(dev, norm_shape(d));
    const kernels::PsfConvFft fft(dev, tp, d.n, d.c, d.h, d.w);
    EXPECT_GE(fft.padded_height(), d.h + d.s - 1);
    Stream s(dev);
    fft.forward(s, tx, tb, ty, tn, {normalize});
    s.run();
    std::vector<float> ry, rnorm;
    ref::psf_conv(d, in.x, in.beta, in.psi, normalize, ry, rnorm);
    // FFT rounding grows with the padded size: relative to the largest value.
    double scale = 0;
    for (float v : ry) scale = std::max(scale, double(std::fabs(v)));
    test::expect_all_close("ty", ty.download(), ry, {1e-4, 1e-5 * (1 + scale)});
    test::expect_all_close("tn", tn.download(), rnorm, {1e-4, 1e-5 * (1 + scale)});
  }
  // Kernels in chunks: small temporaries force 6 passes of ≤ 2 kernels, and
  // Ψ̂ in chunks of 12160 B / (18·21·8 B) = 4 kernels.
  {
    const PsfConvDims d{1, 1, 11, 13, 17, 5};
    const Inputs in = random_inputs(d, 400);
    Tensor tx = Tensor::from(dev, x_shape(d), in.x), tb = Tensor::from(dev, beta_shape(d), in.beta);
    Tensor tp = Tensor::from(dev, psi_shape(d), in.psi);
    Tensor ty = Tensor::empty(dev, x_shape(d)), tn = Tensor::empty(dev, norm_shape(d));
    const std::int64_t per_kernel = 2 * 18 * 21 * 2 * 4;  // (C+1) full complex Hp×Wp planes, bytes
    const kernels::PsfConvFft fft(dev, tp, d.n, d.c, d.h, d.w, 2 * per_kernel + 64);
    ASSERT_EQ(fft.padded_height(), 18);
    ASSERT_EQ(fft.padded_width(), 21);
    EXPECT_EQ(fft.chunk(), 2);
    Stream s(dev);
    fft.forward(s, tx, tb, ty, tn, {true});
    s.run();
    std::vector<float> ry, rnorm;
    ref::psf_conv(d, in.x, in.beta, in.psi, true, ry, rnorm);
    test::expect_all_close("ty", ty.download(), ry, {1e-4, 1e-5});
    test::expect_all_close("tn", tn.download(), rnorm, {1e-4, 1e-5});
  }
  // Bad shapes.
  Tensor psi_even = Tensor::empty(dev, {2, 4, 4});
  EXPECT_THROW(kernels::PsfConvFft(dev, psi_even, 1, 1, 8, 8), InvalidArgument);
  Tensor psi = Tensor::empty(dev, {2, 3, 3});
  EXPECT_THROW(kernels::PsfConvFft(dev, psi, 1, 5, 8, 8), InvalidArgument);
  const kernels::PsfConvFft ok(dev, psi, 1, 1, 8, 8);
  Tensor x = Tensor::empty(dev, {1, 1, 8, 9}), b = Tensor::empty(dev, {1, 2, 8, 8});
  Tensor y = Tensor::empty(dev, {1, 1, 8, 8}), n = Tensor::empty(dev, {1, 1, 8, 8});
  Stream s(dev);
  EXPECT_THROW(ok.forward(s, x, b, y, n), InvalidArgument);
}

TEST(PsfConv, DeltaKernelWithUnitWeightsIsIdentity) {
  PsfConvDims d{1, 3, 2, 9, 11, 5};
  std::vector<float> psi(count(psi_shape(d)), 0.f);
  psi[12] = 0.5f;       // centre of kernel 0
  psi[25 + 12] = 0.5f;  // centre of kernel 1
  const auto x = test::random_floats(count(x_shape(d)), 3);
  const std::vector<float> beta(count(beta_shape(d)), 1.f);
  const auto y = forward(d, x, beta, psi, false);
  for (std::size_t i = 0; i < y.size(); ++i) ASSERT_NEAR(y[i], x[i], 1e-6f);
}

TEST(PsfConv, NormalizedFormPreservesAConstantImage) {
  // Any positive blur of a constant image is the same constant, borders included.
  PsfConvDims d{1, 2, 4, 13, 10, 7};
  const Inputs in = random_inputs(d, 9);
  const std::vector<float> x(count(x_shape(d)), 0.7f);
  const auto y = forward(d, x, in.beta, in.psi, true);
  for (float v : y) ASSERT_NEAR(v, 0.7f, 1e-5f);
}

void gradcheck(bool normalize) {
  Device& dev = test::device();
  const PsfConvDims d{2, 3, 3, 6, 7, 3};
  const Inputs in = random_inputs(d, normalize ? 51 : 50);
  const auto w = test::random_floats(count(x_shape(d)), 77);

  Tensor tx = Tensor::from(dev, x_shape(d), in.x);
  Tensor tb = Tensor::from(dev, beta_shape(d), in.beta);
  Tensor tp = Tensor::from(dev, psi_shape(d), in.psi);
  Tensor ty = Tensor::empty(dev, x_shape(d));
  Tensor tn = Tensor::empty(dev, norm_shape(d));
  Tensor tdy = Tensor::from(dev, x_shape(d), w);
  Tensor tdx = Tensor::empty(dev, x_shape(d));
  Tensor tdb = Tensor::empty(dev, beta_shape(d));
  Stream s(dev);
  kernels::psf_conv(s, tx, tb, tp, ty, tn, {normalize});
  kernels::psf_conv_backward(s, tx, tb, tp, ty, tn, tdy, tdx, tdb, {normalize});
  s.run();

  const std::string form = normalize ? "normalized" : "plain";
  test::expect_gradient_matches(
      [&](std::span<const float> x) {
        return test::weighted_sum(forward(d, {x.begin(), x.end()}, in.beta, in.psi, normalize), w);
      },
      in.x, tdx.download(), "psf_conv " + form + " dL/dx");
  test::expect_gradient_matches(
      [&](std::span<const float> beta) {
        return test::weighted_sum(forward(d, in.x, {beta.begin(), beta.end()}, in.psi, normalize),
                                  w);
      },
      in.beta, tdb.download(), "psf_conv " + form + " dL/dbeta");
}

TEST(PsfConv, GradientPlain) { gradcheck(false); }
TEST(PsfConv, GradientNormalized) { gradcheck(true); }

TEST(PsfConv, BadShapesAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor x = Tensor::empty(dev, {1, 3, 8, 8});
  Tensor beta = Tensor::empty(dev, {1, 4, 8, 8});
  Tensor y = Tensor::empty(dev, {1, 3, 8, 8});
  Tensor norm = Tensor::empty(dev, {1, 1, 8, 8});
  Tensor even = Tensor::empty(dev, {4, 4, 4});
  EXPECT_THROW(kernels::psf_conv(s, x, beta, even, y, norm), InvalidArgument);
  Tensor wrong_k = Tensor::empty(dev, {5, 3, 3});
  try {
    kernels::psf_conv(s, x, beta, wrong_k, y, norm);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("K = 4"), std::string::npos) << e.what();
  }
  Tensor five = Tensor::empty(dev, {1, 5, 8, 8});
  Tensor psi = Tensor::empty(dev, {4, 3, 3});
  EXPECT_THROW(kernels::psf_conv(s, five, beta, psi, five, norm), InvalidArgument);
  Tensor beta_small = Tensor::empty(dev, {1, 4, 7, 8});
  EXPECT_THROW(kernels::psf_conv(s, x, beta_small, psi, y, norm), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
