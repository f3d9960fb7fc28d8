#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/kernels/ref/fft_ref.hpp>

#include <fftw3.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::FftKind;
using kernels::FftNorm;
using kernels::FftPlan;

struct Case {
  std::int64_t b, h, w;
  std::string str() const {
    return "[" + std::to_string(b) + ", " + std::to_string(h) + ", " + std::to_string(w) + "]";
  }
};

// Every length the issue names (1, 2, 3, 5, 6, 12, 15, 60, 64, 100, 125, 128,
// 243, 256, 360, 1000, 1024) appears as H and W, in few big cases: odd
// lengths, radix-7 lengths, 1-pixel axes, batches.
const std::vector<Case> kC2cCases = {
    {3, 1, 1},     {2, 2, 3},     {1, 5, 6},     {4, 12, 15},    {1, 60, 64},     {2, 100, 125},
    {1, 128, 243}, {1, 243, 128}, {1, 256, 360}, {1, 360, 1000}, {1, 1024, 1024}, {2, 49, 14},
    {1, 1, 1000},  {1, 1024, 1},  {3, 64, 64},   {1, 125, 6},    {1, 15, 256},
};
const std::vector<Case> kRealCases = {
    {2, 1, 1},    {1, 1, 7},     {3, 4, 1},     {2, 6, 5},      {1, 5, 12},     {2, 15, 60},
    {1, 64, 100}, {1, 125, 128}, {1, 243, 256}, {1, 1000, 360}, {1, 256, 1024}, {1, 14, 49},
};

std::vector<double> to_double(std::span<const float> v) { return {v.begin(), v.end()}; }

// FFTW (single precision) as the peer reference.
std::vector<double> fftw_c2c(const std::vector<float>& x, const Case& c, bool inverse) {
  std::vector<float> in = x, out(x.size());
  const int n[2] = {int(c.h), int(c.w)};
  const int dist = int(c.h * c.w);
  fftwf_plan plan =
      fftwf_plan_many_dft(2, n, int(c.b), reinterpret_cast<fftwf_complex*>(in.data()), nullptr, 1,
                          dist, reinterpret_cast<fftwf_complex*>(out.data()), nullptr, 1, dist,
                          inverse ? FFTW_BACKWARD : FFTW_FORWARD, FFTW_ESTIMATE);
  fftwf_execute(plan);
  fftwf_destroy_plan(plan);
  return to_double(out);
}
std::vector<double> fftw_r2c(const std::vector<float>& x, const Case& c) {
  const std::int64_t half = c.w / 2 + 1;
  std::vector<float> in = x, out(std::size_t(2 * c.b * c.h * half));
  const int n[2] = {int(c.h), int(c.w)};
  fftwf_plan plan = fftwf_plan_many_dft_r2c(2, n, int(c.b), in.data(), nullptr, 1, int(c.h * c.w),
                                            reinterpret_cast<fftwf_complex*>(out.data()), nullptr,
                                            1, int(c.h * half), FFTW_ESTIMATE);
  fftwf_execute(plan);
  fftwf_destroy_plan(plan);
  return to_double(out);
}
std::vector<double> fftw_c2r(const std::vector<float>& spectrum, const Case& c) {
  std::vector<float> in = spectrum, out(std::size_t(c.b * c.h * c.w));
  const int n[2] = {int(c.h), int(c.w)};
  const std::int64_t half = c.w / 2 + 1;
  fftwf_plan plan = fftwf_plan_many_dft_c2r(
      2, n, int(c.b), reinterpret_cast<fftwf_complex*>(in.data()), nullptr, 1, int(c.h * half),
      out.data(), nullptr, 1, int(c.h * c.w), FFTW_ESTIMATE);
  fftwf_execute(plan);
  fftwf_destroy_plan(plan);
  return to_double(out);
}

std::vector<float> run_plan(const FftPlan& plan, const std::vector<float>& x, bool inverse,
                            Device& dev = test::device()) {
  const Shape& in_shape = inverse ? plan.spectrum_shape() : plan.signal_shape();
  const Shape& out_shape = inverse ? plan.signal_shape() : plan.spectrum_shape();
  Tensor in = Tensor::from(dev, in_shape, x);
  Tensor out = Tensor::empty(dev, out_shape);
  Stream s(dev);
  if (inverse) {
    plan.inverse(s, in, out);
  } else {
    plan.forward(s, in, out);
  }
  s.run();
  return out.download();
}

constexpr double kTol = 1e-5;  // relative L2 vs FFTW (fp32 both)

// The listed cases, then random ones with supported lengths up to 400.
Case draw_case(test::OpCase& c, const std::vector<Case>& edges) {
  if (c.index < int(edges.size())) return edges[std::size_t(c.index)];
  return {c.uniform(1, 3), kernels::fft_next_length(c.uniform(1, 400)),
          kernels::fft_next_length(c.uniform(1, 400))};
}

TEST(Fft, C2cMatchesFftw) {
  test::check_op("fft c2c", {.seed = 31, .cases = int(kC2cCases.size()) + 4}, [](test::OpCase& c) {
    const Case k = draw_case(c, kC2cCases);
    c.describe("shape " + k.str());
    const auto x = c.floats(2 * k.b * k.h * k.w);
    const FftPlan plan(c.device, {k.b, k.h, k.w}, FftKind::c2c, FftNorm::none);
    c.expect_rel_l2("forward", run_plan(plan, x, false, c.device), fftw_c2c(x, k, false), kTol);
    c.expect_rel_l2("inverse", run_plan(plan, x, true, c.device), fftw_c2c(x, k, true), kTol);
  });
}

TEST(Fft, ReferenceAgreesWithFftwAndDevice) {
  // The plain C++ reference (double) checks FFTW's use here and the device
  // on sizes with every radix, 7 included.
  const Case c{2, 21, 40};
  const auto x = test::random_floats(std::size_t(2 * c.b * c.h * c.w), 5);
  const auto want = ref::fft2d_c2c(x, c.b, c.h, c.w, false);
  std::vector<float> fftw(want.size());
  const auto f = fftw_c2c(x, c, false);
  std::copy(f.begin(), f.end(), fftw.begin());
  EXPECT_LE(test::rel_l2(fftw, want), 1e-6);
  const FftPlan plan(test::device(), {c.b, c.h, c.w}, FftKind::c2c, FftNorm::none);
  EXPECT_LE(test::rel_l2(run_plan(plan, x, false), want), kTol);
  const auto xr = test::random_floats(std::size_t(c.b * c.h * c.w), 6);
  const FftPlan rplan(test::device(), {c.b, c.h, c.w}, FftKind::r2c);
  EXPECT_LE(test::rel_l2(run_plan(rplan, xr, false), ref::fft2d_r2c(xr, c.b, c.h, c.w)), kTol);
}

TEST(Fft, InverseOfForwardIsIdentityForEveryNorm) {
  const std::uint32_t seed = 77;
  const std::vector<Case> cases = {{2, 7, 9}, {1, 100, 1024}, {3, 1, 16}, {1, 1, 1}};
  for (const Case& c : cases) {
    for (FftNorm norm : {FftNorm::backward, FftNorm::none, FftNorm::ortho}) {
      SCOPED_TRACE("shape=" + c.str() + " norm=" + std::to_string(int(norm)) +
                   " seed=" + std::to_string(seed));
      const auto x = test::random_floats(std::size_t(2 * c.b * c.h * c.w), seed);
      const FftPlan plan(test::device(), {c.b, c.h, c.w}, FftKind::c2c, norm);
      const auto back = run_plan(plan, run_plan(plan, x, false), true);
      const double n = norm == FftNorm::none ? double(c.h * c.w) : 1.0;
      std::vector<double> want(x.size());
      for (std::size_t i = 0; i < x.size(); ++i) want[i] = n * x[i];
      EXPECT_LE(test::rel_l2(back, want), kTol);
    }
  }
}

TEST(Fft, R2cAndC2rMatchFftw) {
  test::check_op("fft r2c/c2r", {.seed = 2024, .cases = int(kRealCases.size()) + 4},
                 [](test::OpCase& c) {
                   const Case k = draw_case(c, kRealCases);
                   c.describe("shape " + k.str());
                   const auto x = c.floats(k.b * k.h * k.w);
                   const FftPlan plan(c.device, {k.b, k.h, k.w}, FftKind::r2c, FftNorm::none);
                   const auto spectrum = run_plan(plan, x, false, c.device);
                   c.expect_rel_l2("r2c", spectrum, fftw_r2c(x, k), kTol);
                   // c2r of a consistent (Hermitian) spectrum; unnormalized like FFTW.
                   const auto back = run_plan(plan, spectrum, true, c.device);
                   c.expect_rel_l2("c2r", back, fftw_c2r(spectrum, k), kTol);
                   std::vector<double> want(x.size());
                   for (std::size_t i = 0; i < x.size(); ++i) want[i] = double(k.h * k.w) * x[i];
                   c.expect_rel_l2("c2r(r2c(x)) = N x", back, want, kTol);
                 });
}

TEST(Fft, C2rIgnoresImaginaryPartsOfRealBins) {
  // DC and Nyquist bins of each row must be real; like FFTW, their imaginary
  // parts do not change the output.
  const Case c{1, 4, 8};
  const auto x = test::random_floats(std::size_t(c.h * c.w), 3);
  const FftPlan plan(test::device(), {c.h, c.w}, FftKind::r2c);
  auto spectrum = run_plan(plan, x, false);
  const std::int64_t half = c.w / 2 + 1;
  spectrum[1] += 0.5f;                    // imag of bin (0, 0)
  spectrum[2 * (half - 1) + 1] -= 0.25f;  // imag of bin (0, W/2)
  const auto back = run_plan(plan, spectrum, true);
  EXPECT_LE(test::rel_l2(back, to_double(x)), kTol);
}

TEST(Fft, ParsevalAndLinearity) {
  const Case c{2, 60, 64};
  const std::uint32_t seed = 8;
  SCOPED_TRACE("seed=" + std::to_string(seed));
  const std::size_t n = std::size_t(2 * c.b * c.h * c.w);
  const auto x = test::random_floats(n, seed), y = test::random_floats(n, seed + 1);
  const FftPlan plan(test::device(), {c.b, c.h, c.w}, FftKind::c2c, FftNorm::ortho);
  const auto fx = run_plan(plan, x, false), fy = run_plan(plan, y, false);
  // Parseval (unitary transform): Σ|x|² = Σ|X|².
  double ex = 0, efx = 0;
  for (std::size_t i = 0; i < n; ++i) {
    ex += double(x[i]) * x[i];
    efx += double(fx[i]) * fx[i];
  }
  EXPECT_NEAR(efx / ex, 1.0, 1e-5);
  // Linearity: F(a x + b y) = a F x + b F y.
  const float a = 0.75f, b = -1.5f;
  std::vector<float> z(n);
  std::vector<double> want(n);
  for (std::size_t i = 0; i < n; ++i) {
    z[i] = a * x[i] + b * y[i];
    want[i] = double(a) * fx[i] + double(b) * fy[i];
  }
  EXPECT_LE(test::rel_l2(run_plan(plan, z, false), want), kTol);
}

TEST(Fft, AdjointIsUnnormalizedInverse) {
  // Backprop through F uses Fᴴ: ⟨F x, y⟩ = ⟨x, Fᴴ y⟩ with Fᴴ = the
  // FftNorm::none inverse (= N × the backward-normalized inverse).
  const Case c{2, 12, 100};
  const std::size_t n = std::size_t(2 * c.b * c.h * c.w);
  const auto x = test::random_floats(n, 11), y = test::random_floats(n, 12);
  const FftPlan plan(test::device(), {c.b, c.h, c.w}, FftKind::c2c, FftNorm::none);
  const auto fx = run_plan(plan, x, false), fhy = run_plan(plan, y, true);
  // ⟨a, b⟩ = Σ a · conj(b) over complex pairs.
  auto inner = [&](const std::vector<float>& a, const std::vector<float>& b) {
    std::complex<double> s = 0;
    for (std::size_t i = 0; i < n; i += 2) {
      s += std::complex<double>(a[i], a[i + 1]) * std::conj(std::complex<double>(b[i], b[i + 1]));
    }
    return s;
  };
  const auto lhs = inner(fx, y), rhs = inner(x, fhy);
  EXPECT_LE(std::abs(lhs - rhs), 1e-5 * std::abs(lhs) + 1e-3) << lhs << " vs " << rhs;
}

TEST(Fft, GradientsByFiniteDifferences) {
  // L(x) = Σ g ⊙ F(x) over (re, im) pairs: dL/dx = Fᴴ g for c2c, and for r2c
  // the unnormalized c2r of g with bins 0 < v < W/2 halved (fft.hpp).
  Device& dev = test::device();
  const std::uint32_t seed = 19;
  SCOPED_TRACE("seed=" + std::to_string(seed));
  for (FftKind kind : {FftKind::c2c, FftKind::r2c}) {
    SCOPED_TRACE(kind == FftKind::c2c ? "c2c" : "r2c");
    const Case c{1, 6, 10};
    const FftPlan plan(dev, {c.b, c.h, c.w}, kind, FftNorm::none);
    const auto x = test::random_floats(std::size_t(plan.signal_shape().numel()), seed);
    auto g = test::random_floats(std::size_t(plan.spectrum_shape().numel()), seed + 1);
    auto loss = [&](std::span<const float> xs) {
      const auto fx = run_plan(plan, {xs.begin(), xs.end()}, false);
      double l = 0;
      for (std::size_t i = 0; i < fx.size(); ++i) l += double(g[i]) * fx[i];
      return l;
    };
    std::vector<float> g_in = g;
    if (kind == FftKind::r2c) {
      const std::int64_t half = c.w / 2 + 1;
      for (std::int64_t r = 0; r < c.b * c.h; ++r) {
        for (std::int64_t v = 1; v < half; ++v) {
          if (2 * v == c.w) continue;  // Nyquist
          g_in[2 * (r * half + v)] *= 0.5f;
          g_in[2 * (r * half + v) + 1] *= 0.5f;
        }
      }
    }
    const auto analytic = run_plan(plan, g_in, true);
    test::expect_gradient_matches(loss, x, analytic, "fft", {.step = 1e-2, .rtol = 1e-2});
  }
}

TEST(Fft, InPlaceAndOneShot) {
  Device& dev = test::device();
  for (const Case& c : std::vector<Case>{{2, 1, 16}, {1, 12, 30}}) {  // one pass; several
    SCOPED_TRACE("shape=" + c.str());
    const auto x = test::random_floats(std::size_t(2 * c.b * c.h * c.w), 4);
    Tensor t = Tensor::from(dev, {c.b, c.h, c.w, 2}, x);
    Stream s(dev);
    kernels::fft2(s, t, t, false, FftNorm::none);
    s.run();
    EXPECT_LE(test::rel_l2(t.download(), fftw_c2c(x, c, false)), kTol);
  }
}

TEST(Fft, BadInputsAreClearErrors) {
  Device& dev = test::device();
  for (std::int64_t bad : {11, 13, 1023, 2 * 17}) {
    try {
      FftPlan plan(dev, {1, 8, bad}, FftKind::c2c);
      FAIL() << bad;
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("not a supported FFT length"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW(FftPlan(dev, {1, 0, 8}, FftKind::c2c), InvalidArgument);
  EXPECT_THROW(FftPlan(dev, {0, 8, 8}, FftKind::c2c), InvalidArgument);
  EXPECT_THROW(FftPlan(dev, {8}, FftKind::c2c), InvalidArgument);
  EXPECT_EQ(kernels::fft_next_length(11), 12);
  EXPECT_EQ(kernels::fft_next_length(1021), 1024);
  EXPECT_TRUE(kernels::fft_supported_length(1000));
  EXPECT_FALSE(kernels::fft_supported_length(22));

  const FftPlan plan(dev, {2, 8, 6}, FftKind::r2c);
  Stream s(dev);
  Tensor real = Tensor::empty(dev, {2, 8, 6}), spec = Tensor::empty(dev, {2, 8, 4, 2});
  Tensor wrong = Tensor::empty(dev, {2, 8, 6, 2}), empty = Tensor::empty(dev, {0});
  EXPECT_THROW(plan.forward(s, wrong, spec), InvalidArgument);
  EXPECT_THROW(plan.forward(s, real, wrong), InvalidArgument);
  EXPECT_THROW(plan.inverse(s, real, real), InvalidArgument);
  EXPECT_THROW(plan.forward(s, empty, spec), InvalidArgument);
  EXPECT_THROW(kernels::fft2(s, real, real, false), InvalidArgument);
}

TEST(Fft, NaNSpreadsToItsWholeImageOnly) {
  const Case c{2, 4, 4};
  auto x = test::random_floats(std::size_t(2 * c.b * c.h * c.w), 9);
  x[6] = NAN;  // image 0
  const FftPlan plan(test::device(), {c.b, c.h, c.w}, FftKind::c2c);
  const auto fx = run_plan(plan, x, false);
  // Each output of image 0 is NaN in its real or imaginary part (or both).
  for (std::size_t i = 0; i < fx.size(); i += 2) {
    EXPECT_EQ(std::isnan(fx[i]) || std::isnan(fx[i + 1]), i < fx.size() / 2) << i;
  }
}

// Prints c2c forward times; asserts nothing about them (the validation layer,
// on in CI, inflates them: run with VKJR2_VALIDATION=0 for real numbers).
TEST(Fft, TimingPrintOnly) {
  Device& dev = test::device();
  for (const Shape& shape : {Shape{1, 256, 256}, Shape{1, 1024, 1024}, Shape{1024, 1, 1024}}) {
    const FftPlan plan(dev, shape, FftKind::c2c);
    const auto x = test::random_floats(std::size_t(plan.signal_shape().numel()), 1);
    Tensor in = Tensor::from(dev, plan.signal_shape(), x);
    Tensor out = Tensor::empty(dev, plan.spectrum_shape());
    Stream s(dev);
    plan.forward(s, in, out);  // warm-up: pipeline JIT
    s.run();
    const int reps = shape.numel() < 1'000'000 ? 10 : 3;
    double best = 1e30;
    for (int r = 0; r < reps; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      plan.forward(s, in, out);
      s.run();
      const auto t1 = std::chrono::steady_clock::now();
      best = std::min(best, std::chrono::duration<double, std::milli>(t1 - t0).count());
    }
    std::printf("[fft] c2c forward %s: %.2f ms (best of %d, incl. submit)\n", shape.str().c_str(),
                best, reps);
  }
  if (dev.profiling_enabled()) std::printf("%s\n", dev.profile_report().c_str());
}

}  // namespace
}  // namespace vkjr2
