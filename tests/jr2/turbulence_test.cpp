#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/turbulence.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>
#include <vkjr2/sim/tilt.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "support/expect_error.hpp"
#include "support/temp_dir.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

// A textured scene (0..1): sinusoids at several scales, enough detail
// everywhere for the registration.
std::vector<float> texture(int h, int w) {
  std::vector<float> v(std::size_t(h) * w);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      v[std::size_t(y) * w + x] =
          float(0.5 + 0.15 * std::sin(0.35 * x + 0.1 * y) + 0.12 * std::cos(0.29 * y - 0.07 * x) +
                0.08 * std::sin(0.8 * x) * std::cos(0.7 * y) + 0.05 * std::sin(0.13 * (x + y)));
    }
  }
  return v;
}

// The texture as a grey RGB scene [1, 3, size, size] on the device.
Tensor grey_scene(Device& dev, int size) {
  const auto scene = texture(size, size);
  std::vector<float> rgb;
  for (int c = 0; c < 3; ++c) rgb.insert(rgb.end(), scene.begin(), scene.end());
  return Tensor::from(dev, {1, 3, size, size}, rgb);
}

// Per-pixel one-axis temporal variance of flows [T, 2, H, W], averaged over
// the pixels at least `border` from the edge.
double mean_temporal_variance(const std::vector<float>& flow, int t, int h, int w, int border) {
  const std::size_t plane = std::size_t(h) * w;
  double sum = 0;
  int n = 0;
  for (int y = border; y < h - border; ++y) {
    for (int x = border; x < w - border; ++x) {
      for (int a = 0; a < 2; ++a) {
        double m = 0, m2 = 0;
        for (int f = 0; f < t; ++f) {
          const double v = flow[std::size_t(2 * f + a) * plane + std::size_t(y) * w + x];
          m += v;
          m2 += v * v;
        }
        m /= t;
        sum += m2 / t - m * m;
        ++n;
      }
    }
  }
  return sum / n;
}

// Frames of a scene shifted as a whole by known translations: the measured
// variance is the translations' own.
TEST(Jr2Turbulence, MeasuresTheVarianceOfKnownShifts) {
  Device& dev = test::device();
  const int t = 12, h = 64, w = 72;
  std::mt19937 rng(3);
  std::normal_distribution<double> shift(0.0, 0.8);
  std::vector<double> sx(t), sy(t);
  std::vector<float> frames;
  for (int f = 0; f < t; ++f) {
    sx[std::size_t(f)] = shift(rng);
    sy[std::size_t(f)] = shift(rng);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        // frame(x) = scene(x − s): registered back by a flow of +s.
        const double u = x - sx[std::size_t(f)], v = y - sy[std::size_t(f)];
        frames.push_back(float(0.5 + 0.15 * std::sin(0.35 * u + 0.1 * v) +
                               0.12 * std::cos(0.29 * v - 0.07 * u) +
                               0.08 * std::sin(0.8 * u) * std::cos(0.7 * v)));
      }
    }
  }
  double want = 0;
  for (const auto* s : {&sx, &sy}) {
    double m = 0, m2 = 0;
    for (double v : *s) {
      m += v;
      m2 += v * v;
    }
    m /= t;
    want += 0.5 * (m2 / t - m * m);
  }
  Stream s(dev);
  const TiltMeasure got = measure_tilt(s, Tensor::from(dev, {t, 1, h, w}, frames));
  EXPECT_EQ(got.frames, t);
  EXPECT_GT(got.coverage, 0.5);
  EXPECT_NEAR(got.variance_px2, want, 0.05 * want) << "shift variance " << want << " px²";
  EXPECT_NEAR(got.mean_variance_px2, want, 0.05 * want);
  // A bright square wandering over a fifth of the frame (a moving object):
  // the mean over the pixels follows it, the median (the estimate) does not.
  std::uniform_int_distribution<int> jump(-6, 6);
  for (int f = 0; f < t; ++f) {
    const int ox = 30 + jump(rng), oy = 22 + jump(rng);
    for (int y = oy; y < oy + 14; ++y) {
      for (int x = ox; x < ox + 14; ++x) {
        frames[(std::size_t(f) * h + y) * w + x] = float(0.9 + 0.05 * std::sin(0.9 * (x - ox)));
      }
    }
  }
  const TiltMeasure moved = measure_tilt(s, Tensor::from(dev, {t, 1, h, w}, frames));
  EXPECT_NEAR(moved.variance_px2, want, 0.15 * want) << "median with a moving object";
  EXPECT_GT(moved.mean_variance_px2, 1.5 * want) << "the mean is pulled by the object";
}

// A simulated video: the registration finds the simulator's own tilt
// variance (its flow maps), and the raw D/r0 grows with the true one.
TEST(Jr2Turbulence, FindsTheSimulatorsTilt) {
  Device& dev = test::device();
  const int t = 16, size = 96;
  const Tensor x = grey_scene(dev, size);
  const auto blur = sim::load_shipped_blur_models(dev);
  double previous_raw = 0;
  for (double d_over_r0 : {2.0, 6.0}) {
    const SimulatedVideo video =
        simulate_video(dev, x, probe_sim_params(d_over_r0, size), probe_sim_options(), blur, 7, t);
    const std::vector<float>& frames = video.grey;
    const std::vector<float>& flows = video.flow;
    Stream s(dev);
    const TiltOptions o;
    const double truth = mean_temporal_variance(flows, t, size, size, o.border);
    const TiltMeasure got = measure_tilt(s, Tensor::from(dev, {t, 1, size, size}, frames), o);
    EXPECT_NEAR(got.variance_px2, truth, 0.25 * truth) << "D/r0 " << d_over_r0;
    const double raw = raw_d_over_r0(got.variance_px2, t, probe_sim_params(d_over_r0, size), 0.9);
    EXPECT_GT(raw, previous_raw * 1.5) << "D/r0 " << d_over_r0;
    previous_raw = raw;
  }
}

// The texture map by summed areas equals the window's structure tensor summed
// directly; the statistics of flows with a known temporal pattern.
TEST(Jr2Turbulence, TextureMapAndTiltStatistics) {
  const int h = 13, w = 17, r = 2;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<float> img(std::size_t(h) * w);
  for (float& v : img) v = u(rng);
  const std::vector<float> got = texture_map(img, h, w, r);
  auto at = [&](int y, int x) { return double(img[std::size_t(y) * w + x]); };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double a = 0, c = 0, d = 0;
      int n = 0;
      for (int yy = std::max(y - r, 0); yy <= std::min(y + r, h - 1); ++yy) {
        for (int xx = std::max(x - r, 0); xx <= std::min(x + r, w - 1); ++xx) {
          const double gx = 0.5 * (at(yy, std::min(xx + 1, w - 1)) - at(yy, std::max(xx - 1, 0)));
          const double gy = 0.5 * (at(std::min(yy + 1, h - 1), xx) - at(std::max(yy - 1, 0), xx));
          a += gx * gx;
          c += gx * gy;
          d += gy * gy;
          ++n;
        }
      }
      a /= n;
      c /= n;
      d /= n;
      const double want = 0.5 * (a + d) - std::sqrt(0.25 * (a - d) * (a - d) + c * c);
      ASSERT_NEAR(got[std::size_t(y) * w + x], want, 1e-6) << y << "," << x;
    }
  }
  // Flows alternating ±1 px in x, none in y: x has variance 1 and lag-1
  // covariance −1, y none; the one-axis figures are their means.
  const int t = 4;
  const std::size_t plane = std::size_t(h) * w;
  std::vector<float> flow(std::size_t(t) * 2 * plane, 0.f);
  for (int f = 0; f < t; ++f) {
    for (std::size_t p = 0; p < plane; ++p)
      flow[std::size_t(2 * f) * plane + p] = f % 2 ? 1.f : -1.f;
  }
  TiltOptions o;
  o.border = 2;
  o.min_eigenvalue = 1e-9f;
  const std::vector<float> textured(plane, 1.f);
  const TiltMeasure m = tilt_statistics(flow, t, h, w, textured, o);
  EXPECT_NEAR(m.variance_px2, 0.5, 1e-12);
  EXPECT_NEAR(m.lag1_covariance_px2, -0.5, 1e-12);
  EXPECT_NEAR(m.coverage, double((h - 4) * (w - 4)) / double(plane), 1e-12);
  test::expect_invalid_argument(
      [&] { (void)tilt_statistics(flow, t, h, w, std::vector<float>(plane, 0.f), o); },
      "texture enough");
  test::expect_invalid_argument(
      [&] { (void)tilt_statistics(std::span(flow).first(10), t, h, w, textured, o); },
      "flow values");
}

TEST(Jr2Turbulence, RawDOverR0InvertsTheZTiltFormula) {
  const sim::Params p = probe_sim_params(3.0, 64);
  // The per-axis variance in pixels² the formula gives at D/r0 = 3, before
  // the correlation's shortfall.
  const double ifov = sim::pixel_pitch_m(p) / p.optics.focal_length_m;
  const double var = sim::tilt_angle_variance_rad2(p, 0) / (ifov * ifov);
  const double factor = correlated_variance_factor(30, 0.9);
  EXPECT_NEAR(raw_d_over_r0(var * factor, 30, p, 0.9), 3.0, 1e-9);
  EXPECT_NEAR(correlated_variance_factor(10, 0.0), 0.9, 1e-12);  // (T − 1)/T
  EXPECT_LT(correlated_variance_factor(30, 0.9), correlated_variance_factor(30, 0.5));
  test::expect_invalid_argument([] { (void)correlated_variance_factor(1, 0.5); }, "frames 1");
  test::expect_invalid_argument([] { (void)correlated_variance_factor(8, 1.0); }, "rho");
}

TEST(Jr2Turbulence, CalibrationFitsAndRoundTrips) {
  std::vector<double> raw, truth;
  for (double r : {0.5, 1.0, 2.0, 4.0, 7.0}) {
    raw.push_back(r);
    truth.push_back(1.3 * std::pow(r, 0.8));
  }
  TiltOptions o;
  o.radius = 5;
  const TurbulenceCalibration c = fit_calibration(raw, truth, o, 0.85, "lk");
  EXPECT_NEAR(c.gain, 1.3, 1e-9);
  EXPECT_NEAR(c.exponent, 0.8, 1e-9);
  test::TempDir dir;
  const auto path = dir.path / "cal.safetensors";
  TurbulenceCalibration saved = c;
  saved.metadata["fitted_on"] = "five numbers";
  saved.save(path);
  const TurbulenceCalibration back = TurbulenceCalibration::load(path);
  EXPECT_DOUBLE_EQ(back.gain, c.gain);
  EXPECT_DOUBLE_EQ(back.exponent, c.exponent);
  EXPECT_DOUBLE_EQ(back.tilt_correlation, 0.85);
  EXPECT_EQ(back.tilt.radius, 5);
  EXPECT_EQ(back.registration, "lk");
  EXPECT_EQ(back.metadata.at("fitted_on"), "five numbers");
  test::expect_invalid_argument(
      [&] {
        (void)fit_calibration(std::vector<double>{1, 2}, std::vector<double>{1, 2}, o, 0.9, "dis");
      },
      "at least 3 videos");
  test::expect_invalid_argument(
      [&] {
        (void)fit_calibration(std::vector<double>{2, 2, 2}, std::vector<double>{1, 2, 3}, o, 0.9,
                              "dis");
      },
      "do not vary");
  test::expect_invalid_argument(
      [&] {
        (void)fit_calibration(std::vector<double>{1, -2, 3}, std::vector<double>{1, 2, 3}, o, 0.9,
                              "dis");
      },
      "positive");
  // Another safetensors file is not a calibration.
  const auto other = dir.path / "other.safetensors";
  TurbulenceCalibration::identity().save(other);
  {
    auto file = nets::read_safetensors(other);
    file.metadata["kind"] = "vkjr2.restorer";
    nets::write_safetensors(other, file.tensors, file.metadata);
  }
  try {
    (void)TurbulenceCalibration::load(other);
    ADD_FAILURE() << "a file of another kind was read as a calibration";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is not a turbulence calibration"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("other.safetensors"), std::string::npos) << e.what();
  }
}

TEST(Jr2Turbulence, BadVideosAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  const auto scene = texture(40, 40);
  test::expect_invalid_argument(
      [&] {
        (void)measure_tilt(s, Tensor::from(dev, {1, 1, 40, 40}, scene));
      },
      "1 frame");
  std::vector<float> two = scene;
  two.insert(two.end(), scene.begin(), scene.end());
  two[1700] = std::nanf("");
  test::expect_invalid_argument(
      [&] {
        (void)measure_tilt(s, Tensor::from(dev, {2, 1, 40, 40}, two));
      },
      "frame 1 holds a non-finite pixel");
  test::expect_invalid_argument(
      [&] {
        (void)measure_tilt(s, Tensor::from(dev, {2, 1, 40, 40}, std::vector<float>(3200, 0.5f)));
      },
      "texture enough");
  test::expect_invalid_argument(
      [&] {
        (void)measure_tilt(s, Tensor::from(dev, {2, 1, 12, 40}, std::vector<float>(960, 0.5f)));
      },
      "leave nothing inside");
  test::expect_invalid_argument(
      [&] {
        (void)measure_tilt(s, Tensor::from(dev, {2, 3, 20, 20}, std::vector<float>(2400)));
      },
      "must be grey frames");
  TiltOptions bad;
  bad.radius = 0;
  test::expect_invalid_argument([&] { bad.validate(); }, "radius 0");
}

// The spectral fluctuation computed directly: per tile, a plain DFT of the
// Hann-windowed, mean-removed tile, the mean power over the band's bins, the
// sd over frames of its log; the median over the tiles.
double reference_fluctuation(const std::vector<float>& grey, int t, int h, int w, double lo,
                             double hi, int tile, int stride) {
  const auto origins = [&](int size) {
    std::vector<int> o;
    if (size < tile) return std::vector<int>{0};
    for (int x = 0; x + tile <= size; x += stride) o.push_back(x);
    return o;
  };
  const int th = std::min(h, tile), tw = std::min(w, tile);
  const auto hann = [](int n, int i) { return 0.5 - 0.5 * std::cos(2 * M_PI * i / (n - 1)); };
  std::vector<double> per_tile;
  for (int y0 : origins(h)) {
    for (int x0 : origins(w)) {
      std::vector<double> logs;
      for (int f = 0; f < t; ++f) {
        const float* im = grey.data() + std::size_t(f) * h * w;
        double mean = 0;
        for (int y = 0; y < th; ++y) {
          for (int x = 0; x < tw; ++x) mean += im[(y0 + y) * w + x0 + x];
        }
        mean /= th * tw;
        double power = 0;
        int bins = 0;
        for (int u = 0; u < th; ++u) {
          for (int v = 0; v < tw; ++v) {
            const double fy = (u <= (th - 1) / 2 ? u : u - th) / double(th);
            const double fx = (v <= (tw - 1) / 2 ? v : v - tw) / double(tw);
            const double r = std::hypot(fx, fy);
            if (r < lo || r >= hi) continue;
            double re = 0, imag = 0;
            for (int y = 0; y < th; ++y) {
              for (int x = 0; x < tw; ++x) {
                const double val = (im[(y0 + y) * w + x0 + x] - mean) * hann(th, y) * hann(tw, x);
                const double a = -2 * M_PI * (double(u) * y / th + double(v) * x / tw);
                re += val * std::cos(a);
                imag += val * std::sin(a);
              }
            }
            power += re * re + imag * imag;
            ++bins;
          }
        }
        logs.push_back(std::log(power / bins));
      }
      double m = 0, v = 0;
      for (double l : logs) m += l / t;
      for (double l : logs) v += (l - m) * (l - m) / t;
      per_tile.push_back(std::sqrt(v));
    }
  }
  std::sort(per_tile.begin(), per_tile.end());
  const std::size_t n = per_tile.size();
  return n % 2 ? per_tile[n / 2] : 0.5 * (per_tile[n / 2 - 1] + per_tile[n / 2]);
}

// Random frames of random shapes against the direct computation; the
// statistic's invariances: a static video does not fluctuate, and a
// brightness offset or a contrast gain of the whole video changes nothing.
TEST(Jr2Turbulence, SpectralFluctuationMatchesItsReference) {
  std::mt19937 rng(5);
  const sim::Params optics = probe_sim_params(2.0, 64);
  for (int trial = 0; trial < 3; ++trial) {
    const int t = 3 + int(rng() % 4), h = 18 + int(rng() % 20), w = 18 + int(rng() % 20);
    SpectrumOptions o;
    o.tile = 16 + int(rng() % 8);
    o.stride = 4 + int(rng() % 9);
    o.band_lo = 0.15;
    o.band_hi = 0.45;
    std::uniform_real_distribution<float> u(0.f, 1.f);
    std::vector<float> grey(std::size_t(t) * h * w);
    for (float& v : grey) v = u(rng);
    const SpectrumMeasure m = spectral_fluctuation(grey, t, h, w, optics, o);
    const double lo = m.band_lo_px, hi = m.band_hi_px;
    EXPECT_NEAR(lo, 0.15 * 0.2 * 3.45e-6 / (1.6 * 525e-9), 1e-9);
    EXPECT_NEAR(m.fluctuation, reference_fluctuation(grey, t, h, w, lo, hi, o.tile, o.stride), 1e-4)
        << t << "×" << h << "×" << w << " tile " << o.tile << " stride " << o.stride;
    EXPECT_EQ(m.frames, t);
    EXPECT_GT(m.tiles, 0);
    std::vector<float> brighter = grey;
    for (float& v : brighter) v = 0.1f + 0.5f * v;
    EXPECT_NEAR(spectral_fluctuation(brighter, t, h, w, optics, o).fluctuation, m.fluctuation,
                1e-4);
    std::vector<float> still(grey.begin(), grey.begin() + std::ptrdiff_t(h) * w);
    for (int f = 1; f < t; ++f) still.insert(still.end(), grey.begin(), grey.begin() + h * w);
    EXPECT_NEAR(spectral_fluctuation(still, t, h, w, optics, o).fluctuation, 0.0, 1e-5);
  }
}

// Through the simulator, the blur fluctuates more at a higher D/r0; bad
// input is a clear error.
TEST(Jr2Turbulence, SpectralFluctuationGrowsWithTheTurbulence) {
  Device& dev = test::device();
  const int t = 12, size = 96;
  const Tensor x = grey_scene(dev, size);
  const auto blur = sim::load_shipped_blur_models(dev);
  double previous = 0;
  for (double d_over_r0 : {1.5, 6.0}) {
    const sim::Params p = probe_sim_params(d_over_r0, size);
    const SimulatedVideo video = simulate_video(dev, x, p, probe_sim_options(), blur, 3, t);
    const SpectrumMeasure m = spectral_fluctuation(video.grey, t, size, size, p);
    EXPECT_EQ(m.tiles, 4);  // 64² tiles at 32 px steps
    EXPECT_GT(m.fluctuation, 1.5 * previous) << "D/r0 " << d_over_r0;
    previous = m.fluctuation;
  }
  const sim::Params optics = probe_sim_params(2.0, size);
  const std::vector<float> scene = texture(size, size);
  test::expect_invalid_argument([&] { (void)spectral_fluctuation(scene, 1, size, size, optics); },
                                "1 frame");
  std::vector<float> two = scene;
  two.insert(two.end(), scene.begin(), scene.end());
  two[size * size + 5] = std::nanf("");
  test::expect_invalid_argument([&] { (void)spectral_fluctuation(two, 2, size, size, optics); },
                                "frame 1 holds a non-finite pixel");
  test::expect_invalid_argument(
      [&] { (void)spectral_fluctuation(std::vector<float>(2 * 10 * 10, 0.5f), 2, 10, 10, optics); },
      "frequency bins");
  test::expect_invalid_argument(
      [&] { (void)spectral_fluctuation(std::vector<float>(2 * 64 * 64, 0.5f), 2, 64, 64, optics); },
      "no tile");
  SpectrumOptions bad;
  bad.band_hi = 0.05;
  test::expect_invalid_argument([&] { bad.validate(); }, "spectral band");
  bad = {};
  bad.stride = 100;
  test::expect_invalid_argument([&] { bad.validate(); }, "stride 100");
}

// Both cues: the fit recovers a known law, the estimate applies it, and the
// file keeps the cues and their options; a file whose cues and exponents
// disagree is refused.
TEST(Jr2Turbulence, TwoCueCalibrationFitsAndRoundTrips) {
  std::vector<double> raw, blur, truth;
  for (double r : {0.5, 1.0, 2.0, 4.0, 7.0}) {
    for (double b : {0.05, 0.2}) {
      raw.push_back(r);
      blur.push_back(b * (1 + 0.1 * r));
      truth.push_back(2.0 * std::pow(raw.back(), 0.3) * std::pow(blur.back(), 0.7));
    }
  }
  TurbulenceCalibration base;
  base.exponent = 1;
  base.blur_exponent = 1;
  base.spectrum.tile = 48;
  base.blur_correlation = 0.5;
  const TurbulenceCalibration c = fit_calibration(base, raw, blur, truth);
  EXPECT_NEAR(c.gain, 2.0, 1e-9);
  EXPECT_NEAR(c.exponent, 0.3, 1e-9);
  EXPECT_NEAR(c.blur_exponent, 0.7, 1e-9);
  EXPECT_EQ(c.cues(), "tilt+spectrum");
  base.exponent = 0;  // the spectrum alone
  const TurbulenceCalibration s = fit_calibration(base, {}, blur, truth);
  EXPECT_EQ(s.cues(), "spectrum");
  EXPECT_EQ(s.exponent, 0.0);
  test::expect_invalid_argument([&] { (void)fit_calibration(base, {}, {}, truth); }, "spectral");

  // The estimate: the corrected fluctuation, with the law's exponents.
  const sim::Params optics = probe_sim_params(3.0, 64);
  TiltMeasure tilt;
  tilt.frames = 30;
  tilt.variance_px2 = 0.5;
  SpectrumMeasure spectrum;
  spectrum.frames = 30;
  spectrum.fluctuation = 0.1;
  const TurbulenceEstimate e = estimate_turbulence(tilt, spectrum, optics, c);
  EXPECT_NEAR(e.blur, 0.1 / std::sqrt(correlated_variance_factor(30, 0.5)), 1e-12);
  EXPECT_NEAR(e.d_over_r0, 2.0 * std::pow(e.raw_d_over_r0, 0.3) * std::pow(e.blur, 0.7), 1e-9);
  test::expect_invalid_argument([&] { (void)estimate_turbulence(tilt, optics, c); },
                                "spectral cue");

  test::TempDir dir;
  const auto path = dir.path / "two.safetensors";
  c.save(path);
  const TurbulenceCalibration back = TurbulenceCalibration::load(path);
  EXPECT_DOUBLE_EQ(back.blur_exponent, c.blur_exponent);
  EXPECT_DOUBLE_EQ(back.blur_correlation, 0.5);
  EXPECT_EQ(back.spectrum.tile, 48);
  EXPECT_EQ(back.cues(), "tilt+spectrum");
  // A tilt-only file of the earlier layout (no spectral keys) is a tilt-only
  // calibration; one whose cues contradict its exponents is refused.
  {
    auto file = nets::read_safetensors(path);
    for (const char* k : {"cues", "blur_exponent", "blur_correlation", "spectrum.band_lo",
                          "spectrum.band_hi", "spectrum.tile", "spectrum.stride"}) {
      file.metadata.erase(k);
    }
    nets::write_safetensors(path, file.tensors, file.metadata);
  }
  EXPECT_EQ(TurbulenceCalibration::load(path).cues(), "tilt");
  c.save(path);
  {
    auto file = nets::read_safetensors(path);
    file.metadata["cues"] = "tilt";
    nets::write_safetensors(path, file.tensors, file.metadata);
  }
  try {
    (void)TurbulenceCalibration::load(path);
    ADD_FAILURE() << "a calibration whose cues contradict its exponents was read";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("names the cues 'tilt'"), std::string::npos)
        << err.what();
  }
}

}  // namespace
}  // namespace vkjr2::jr2
