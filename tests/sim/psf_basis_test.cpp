// Wave-optics PSFs against a host FFTW reference and the Airy pattern, their
// energy inside the crop, and the PCA basis (synthetic low-rank data, and the
// held-out reconstruction error of a default-sized basis vs K).
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/psf_basis.hpp>
#include <vkjr2/sim/zernike.hpp>

#include <fftw3.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "support/test_device.hpp"

namespace vkjr2::sim {
namespace {

std::size_t sz(std::int64_t v) { return static_cast<std::size_t>(v); }

// The PSF by a host FFTW transform of a field built from zernike_phase.
std::vector<float> reference_psf(const PsfSampling& s, const PsfGrid& g,
                                 std::span<const double> coeffs) {
  const int n = g.fft_size;
  const PupilGrid pg{n, g.diameter_px};
  const std::vector<double> mask = pupil_mask(pg);
  std::vector<double> phase(mask.size());
  zernike_phase(coeffs, 4, pg, phase);
  fftwf_complex* buf = fftwf_alloc_complex(mask.size());
  for (std::size_t i = 0; i < mask.size(); ++i) {
    buf[i][0] = float(mask[i] * std::cos(phase[i]));
    buf[i][1] = float(mask[i] * std::sin(phase[i]));
  }
  fftwf_plan plan = fftwf_plan_dft_2d(n, n, buf, buf, FFTW_FORWARD, FFTW_ESTIMATE);
  fftwf_execute(plan);
  const int h = s.size / 2;
  std::vector<double> psf;
  double total = 0;
  for (int r = -h; r <= h; ++r)
    for (int c = -h; c <= h; ++c) {
      const int rr = ((r * g.oversample) % n + n) % n, cc = ((c * g.oversample) % n + n) % n;
      const float* x = buf[sz(rr) * sz(n) + sz(cc)];
      psf.push_back(double(x[0]) * x[0] + double(x[1]) * x[1]);
      total += psf.back();
    }
  fftwf_destroy_plan(plan);
  fftwf_free(buf);
  std::vector<float> out;
  for (const double v : psf) out.push_back(float(v / total));
  return out;
}

// [2 J1(x)/x]², x = π r / (2q) with r in pixels (first zero at r = 1.2197·2q).
double airy(double r_px, double q) {
  const double x = std::numbers::pi * r_px / (2 * q);
  if (x < 1e-9) return 1.0;
  const double a = 2 * std::cyl_bessel_j(1.0, x) / x;
  return a * a;
}

TEST(PsfBasis, GridMatchesTheSampling) {
  const PsfGrid g = psf_grid(PsfSampling{0.61, 33, 36, 64});
  EXPECT_EQ(g.fft_size, 80);  // ceil(1.22 · 64) = 79 → 80 = 2⁴·5
  EXPECT_EQ(g.oversample, 1);
  EXPECT_DOUBLE_EQ(g.diameter_px, 80 / 1.22);
  // q < 0.5: the pupil would not fit, so the FFT oversamples and every m-th bin is used.
  const PsfGrid fine = psf_grid(PsfSampling{0.3, 15, 15, 32});
  EXPECT_EQ(fine.oversample, 2);
  EXPECT_EQ(fine.fft_size % 2, 0);
  EXPECT_GE(fine.diameter_px, 32);
  EXPECT_LE(fine.diameter_px, fine.fft_size);
  EXPECT_GE(fine.period_px(), 15);
  EXPECT_THROW(psf_grid(PsfSampling{0.61, 32, 36, 64}), InvalidArgument);  // even crop
  EXPECT_THROW(psf_grid(PsfSampling{-1, 33, 36, 64}), InvalidArgument);
  EXPECT_THROW(psf_grid(PsfSampling{0.61, 33, 3, 64}), InvalidArgument);
}

TEST(PsfBasis, MatchesHostFftw) {
  for (const PsfSampling s : {PsfSampling{0.75, 9, 15, 16}, PsfSampling{0.3, 11, 10, 20}}) {
    SCOPED_TRACE("nyquist " + std::to_string(s.nyquist) + ", seed 7");
    const WavePsf psf(test::device(), s);
    const NollSampler noll(s.j_max);
    Rng rng(7);
    const std::vector<double> a = draw_aberrations(rng, noll, 1.0, 5.0, 5);
    const std::vector<float> got = psf.compute(a);
    ASSERT_EQ(got.size(), sz(5) * sz(s.size) * sz(s.size));
    for (int i = 0; i < 5; ++i) {
      const std::vector<float> want = reference_psf(
          s, psf.grid(),
          std::span<const double>(a).subspan(sz(i) * sz(psf.modes()), sz(psf.modes())));
      const float peak = *std::max_element(want.begin(), want.end());
      for (std::size_t p = 0; p < want.size(); ++p)
        ASSERT_NEAR(got[sz(i) * want.size() + p], want[p], 2e-5f * peak)
            << "psf " << i << " px " << p;
    }
  }
}

TEST(PsfBasis, ZeroAberrationIsTheAiryPattern) {
  // q chosen so that the first zero 1.2197·2q falls on pixel 5 of the axis.
  const double q_zero5 = 5.0 / (2 * 1.2196698912665045);
  for (const double q : {q_zero5, 0.61}) {
    SCOPED_TRACE("nyquist " + std::to_string(q));
    const PsfSampling s{q, 21, 4, 128};
    const WavePsf psf(test::device(), s);
    const std::vector<float> h = psf.compute(std::vector<double>{0.0});
    const int c = s.size / 2;
    const float peak = h[sz(c) * sz(s.size) + sz(c)];
    EXPECT_EQ(peak, *std::max_element(h.begin(), h.end()));
    double max_err = 0;
    for (int r = 0; r < s.size; ++r)
      for (int col = 0; col < s.size; ++col) {
        const double want = airy(std::hypot(r - c, col - c), q);
        max_err = std::max(max_err, std::abs(h[sz(r) * sz(s.size) + sz(col)] / peak - want));
      }
    // A 128-sample pupil: its staircase edge gives errors ~1e-3 of the peak.
    EXPECT_LT(max_err, 4e-3);
    if (q == q_zero5) {
      const auto axis = [&](int d) { return h[sz(c) * sz(s.size) + sz(c + d)] / peak; };
      EXPECT_LT(axis(5), 1e-3f);
      EXPECT_LT(axis(5), axis(4));
      EXPECT_LT(axis(5), axis(6));
      EXPECT_GT(axis(6), 5e-3f);  // the first bright ring (1.75 %) lies beyond
    }
  }
}

TEST(PsfBasis, EnergyInsideTheCrop) {
  // q = 0.61, S = 33, D/r0 = 6: every PSF of 64 draws keeps ≥ 80 % of its energy.
  const PsfSampling s{0.61, 33, 36, 64};
  const WavePsf psf(test::device(), s);
  const NollSampler noll(36);
  Rng rng(11);
  const std::vector<double> a = draw_aberrations(rng, noll, 6.0, 6.0, 64);
  std::vector<float> h(sz(64) * sz(33 * 33));
  std::vector<double> energy(64);
  psf.compute(a, h, energy);
  const double worst = *std::min_element(energy.begin(), energy.end());
  std::printf("energy in 33×33 at D/r0 = 6: worst %.4f of 64\n", worst);
  EXPECT_GE(worst, 0.8);
  EXPECT_LE(*std::max_element(energy.begin(), energy.end()), 1.0 + 1e-9);
  for (int i = 0; i < 64; ++i) {
    double sum = 0;
    for (int p = 0; p < 33 * 33; ++p) sum += h[sz(i) * sz(33 * 33) + sz(p)];
    ASSERT_NEAR(sum, 1.0, 1e-5);
  }
}

TEST(PsfBasis, PcaRecoversALowRankModel) {
  // Data = m + Σ_k c_k u_k with orthonormal u_k (DCT-like), c_k ~ N(0, σ_k²).
  // The estimated variances follow σ_k² within 4σ of a variance estimate,
  // 4·√(2/M)·σ_k², and the rank-4 reconstruction is exact.
  const int size = 7, d = size * size, m = 4000;
  const std::vector<double> sigma2{4.0, 2.0, 1.0, 0.5};
  std::vector<std::vector<double>> u(4, std::vector<double>(sz(d)));
  for (int k = 0; k < 4; ++k) {
    double norm = 0;
    for (int i = 0; i < d; ++i) {
      u[sz(k)][sz(i)] = std::cos(std::numbers::pi * (k + 1) * (i + 0.5) / d);
      norm += u[sz(k)][sz(i)] * u[sz(k)][sz(i)];
    }
    for (auto& v : u[sz(k)]) v /= std::sqrt(norm);
  }
  Rng rng(3);
  std::vector<float> x(sz(m) * sz(d));
  for (int s = 0; s < m; ++s)
    for (int k = 0; k < 4; ++k) {
      const double c = std::sqrt(sigma2[sz(k)]) * rng.normal();
      for (int i = 0; i < d; ++i) x[sz(s) * sz(d) + sz(i)] += float(c * u[sz(k)][sz(i)]);
    }
  for (int s = 0; s < m; ++s)
    for (int i = 0; i < d; ++i) x[sz(s) * sz(d) + sz(i)] += 1.0f / float(d);
  const PsfBasis b = psf_basis_from_samples(x, size, 5, 0.61, 15);
  ASSERT_EQ(b.count(), 5);
  EXPECT_EQ(b.variances[0], 0.f);
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(b.variances[sz(k + 1)], sigma2[sz(k)], 4 * std::sqrt(2.0 / m) * sigma2[sz(k)]);
    double dot = 0;
    for (int i = 0; i < d; ++i) dot += b.kernels[sz(k + 1) * sz(d) + sz(i)] * u[sz(k)][sz(i)];
    // Sampling noise mixes neighbouring components by θ ≈ σ_i σ_j / (√M (σ_i² − σ_j²))
    // = 0.022 here, from both sides: √2 · 0.022 = 0.032; at 4σ, 1 − cos(0.126) = 8e-3.
    EXPECT_NEAR(std::abs(dot), 1.0, 8e-3) << "component " << k;
  }
  const std::vector<float> betas = project(b, x);
  EXPECT_LT(mean_relative_l2(reconstruct(b, betas), x, d), 1e-5);
  // The Gram route (M < S²) gives the same components.
  const std::vector<float> few(x.begin(), x.begin() + 30 * d);
  const PsfBasis g = psf_basis_from_samples(few, size, 5, 0.61, 15);
  const PsfBasis c = psf_basis_from_samples(
      [&] {  // the same 30 samples, repeated so that M ≥ S² takes the covariance route
        std::vector<float> r;
        for (int t = 0; t < 2; ++t) r.insert(r.end(), few.begin(), few.end());
        return r;
      }(),
      size, 5, 0.61, 15);
  for (std::size_t i = 0; i < g.kernels.size(); ++i)
    ASSERT_NEAR(g.kernels[i], c.kernels[i], 2e-4f) << i;
  EXPECT_THROW(psf_basis_from_samples(few, size, 40, 0.61, 15), InvalidArgument);
}

TEST(PsfBasis, DefaultBasisReconstructsHeldOutPsfs) {
  // The default basis (q = 0.61, S = 33, M = 2000, K = 100, D/r0 ∈ [0.5, 8]) on
  // 256 held-out PSFs from another seed: relative L2 error vs K.
  const auto t0 = std::chrono::steady_clock::now();
  const PsfBasisConfig config;
  const PsfBasis basis = make_psf_basis(test::device(), 0.61, 36, config);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(basis.count(), 100);
  ASSERT_EQ(basis.size, 33);
  const int d = 33 * 33;
  double mean_sum = 0;
  for (int i = 0; i < d; ++i) mean_sum += basis.kernels[sz(i)];
  EXPECT_NEAR(mean_sum, 1.0, 1e-5);
  for (int k = 1; k < 100; ++k) {
    double norm = 0, dot0 = 0;
    for (int i = 0; i < d; ++i) {
      const double v = basis.kernels[sz(k) * sz(d) + sz(i)];
      norm += v * v;
      dot0 += v * basis.kernels[sz(k - 1) * sz(d) + sz(i)];
    }
    EXPECT_NEAR(norm, 1.0, 1e-5) << k;
    if (k > 1) {
      EXPECT_NEAR(dot0, 0.0, 1e-4) << k;  // consecutive PCs are orthogonal
    }
    if (k < 99) {
      EXPECT_LE(basis.variances[sz(k + 1)], basis.variances[sz(k)]) << k;
    }
  }
  // Held-out PSFs drawn like the basis' own: a_4..a_231 (the residual modes).
  const int drawn = config.residual_j_max;
  const WavePsf psf(test::device(), PsfSampling{0.61, 33, drawn, 64});
  Rng rng(config.seed + 1000);
  const NollSampler noll(drawn);
  const std::vector<float> held = psf.compute(draw_aberrations(rng, noll, 0.5, 8.0, 256));
  const std::vector<float> betas = project(basis, held);
  std::printf("default basis: %.2f s; held-out relative L2 vs K:", seconds);
  double previous = 1e9;
  for (const int k : {1, 5, 10, 20, 50, 100}) {
    const double err = mean_relative_l2(reconstruct(basis, betas, k), held, d);
    std::printf(" K=%d %.4f", k, err);
    EXPECT_LT(err, previous) << "K " << k;
    previous = err;
  }
  std::printf("\n");
  // K = 100: measured 0.0511 (0.0284 for PSFs of a_4..a_36 alone: the residual
  // modes add fine speckle the leading components do not span; docs/p2s.md).
  EXPECT_LT(previous, 0.06);
}

// The residual modes (a_37..a_231 in the PSFs, not inputs) widen the mean
// PSF: its short-exposure MTF at r = 0.1 D moves toward Fried's
// exp{−3.44 (r/r0)^(5/3) [1 − (r/D)^(1/3)]} (docs/p2s.md, "Residual modes").
TEST(PsfBasis, ResidualModesBlurTheMeanPsf) {
  const double q = 0.6087, u = 0.1, dr = 3.0;
  const auto mtf = [&](int residual) {
    PsfBasisConfig c;
    c.size = 33;
    c.count = 2;
    c.samples = 300;
    c.d_over_r0_min = c.d_over_r0_max = dr;
    c.residual_j_max = residual;
    const PsfBasis b = make_psf_basis(test::device(), q, 36, c);
    const double nu = u / (2 * q);
    double re = 0;
    const int centre = b.size / 2;
    for (int r = 0; r < b.size; ++r)
      for (int x = 0; x < b.size; ++x)
        re += b.kernels[sz(r * b.size + x)] * std::cos(2 * std::numbers::pi * nu * (x - centre));
    return re / (2 / std::numbers::pi * (std::acos(u) - u * std::sqrt(1 - u * u)));
  };
  const double fried = std::exp(-3.44 * std::pow(u * dr, 5.0 / 3.0) * (1 - std::cbrt(u)));
  const double without = mtf(36), with = mtf(kMaxZernikeModes);
  std::printf("mean-PSF MTF at r = 0.1 D, D/r0 = 3: 36 modes %.4f, 231 modes %.4f, Fried %.4f\n",
              without, with, fried);
  EXPECT_GT(without - fried, 0.06);  // 36 modes miss the residual's blur
  EXPECT_LT(with - fried, 0.035);    // the rest: a_232.., the 33² crop
  EXPECT_GT(with - fried, -0.01);
}

TEST(PsfBasis, LeadingColumns) {
  const std::vector<double> rows{1, 2, 3, 4, 5, 6};
  EXPECT_EQ(leading_columns(rows, 3, 2), (std::vector<double>{1, 2, 4, 5}));
  EXPECT_EQ(leading_columns(rows, 3, 3), rows);
  EXPECT_THROW(leading_columns(rows, 4, 2), InvalidArgument);
  EXPECT_THROW(leading_columns(rows, 3, 4), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::sim
