#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "support/frame_gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2::sim {
namespace {

namespace fs = std::filesystem;

// A small model trained here (seconds): 9×9 PSFs, 6 kernels, a_4..a_15.
class BlurModelTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    path_ = fs::temp_directory_path() /
            ("vkjr2_blur_model_" + std::to_string(::getpid()) + ".safetensors");
    P2sArtifactConfig c;
    c.basis.size = 9;
    c.basis.count = 6;
    c.basis.samples = 200;
    c.basis.min_pupil_px = 32;
    c.train.steps = 40;
    c.train.batch = 64;
    c.train.train_samples = 256;
    c.train.test_samples = 32;
    c.train.min_pupil_px = 32;
    c.hidden = 16;
    make_p2s_artifact(test::device(), params(1, 1, 8, 8), c, path_);
    // The same optics at 610 nm: another sampling (Nyquist ×610/525).
    red_path_ = fs::temp_directory_path() /
                ("vkjr2_blur_model_red_" + std::to_string(::getpid()) + ".safetensors");
    Params red = params(1, 1, 8, 8);
    red.optics.wavelengths_m = {kRed};
    make_p2s_artifact(test::device(), red, c, red_path_);
  }
  static void TearDownTestSuite() {
    fs::remove(path_);
    fs::remove(red_path_);
  }
  // Channel 0 at the preset's 525 nm, channel 1 at 610 nm.
  static Params two_wavelengths(int h, int w) {
    Params p = params(1, 2, h, w);
    p.optics.wavelengths_m = {525e-9, kRed};
    return p;
  }
  static constexpr double kRed = 610e-9;
  static fs::path red_path_;
  static Params params(int batch, int channels, int h, int w) {
    Params p = preset("strong");
    p.zernike_modes = 15;
    p.image = {h, w, channels, batch};
    return p;
  }
  static fs::path path_;
};
fs::path BlurModelTest::path_;
fs::path BlurModelTest::red_path_;

// The 1×1-convolution form on the device equals the network itself.
TEST_F(BlurModelTest, WeightsMatchTheNetwork) {
  Device& dev = test::device();
  const P2sModel model = load_p2s_model(dev, path_);
  const P2sBlurModel blur(dev, model);
  EXPECT_EQ(blur.j_max(), 15);
  EXPECT_EQ(blur.basis().shape(), (Shape{6, 9, 9}));
  // Planes a_2..a_16 (two more than the model reads, as a field may hold).
  const int n = 2, h = 3, w = 5, in = 12, planes = 15, points = h * w;
  std::mt19937 rng(4);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> rows(std::size_t(n * points * in));  // [n·points, in]
  for (double& v : rows) v = g(rng);
  std::vector<float> maps(std::size_t(n * planes * points),
                          7.f);  // [n, planes, h, w]; a_2, a_3, a_16 unused
  for (int b = 0; b < n; ++b)
    for (int p = 0; p < points; ++p)
      for (int i = 0; i < in; ++i)
        maps[(std::size_t(b) * planes + 2 + i) * points + p] =
            float(rows[(std::size_t(b) * points + p) * in + i]);
  Tensor coeffs = Tensor::from(dev, {n, planes, h, w}, maps);
  Tensor beta = Tensor::empty(dev, {n, 6, h, w});
  Stream s(dev);
  blur.weights(s, coeffs, beta);
  s.run();
  const auto want_rows = predict_betas(dev, *model.net, rows);  // [n·points, 6]
  std::vector<float> want(want_rows.size());
  for (int b = 0; b < n; ++b)
    for (int p = 0; p < points; ++p)
      for (int k = 0; k < 6; ++k)
        want[(std::size_t(b) * 6 + k) * points + p] =
            want_rows[(std::size_t(b) * points + p) * 6 + k];
  test::expect_all_close("beta", beta.download(), want, {1e-4, 1e-5});
  // A coefficient scale (λ_0/λ_c) is the network on scaled inputs.
  std::vector<double> scaled = rows;
  for (double& v : scaled) v *= 0.8;
  const auto want_scaled_rows = predict_betas(dev, *model.net, scaled);
  blur.weights(s, coeffs, beta, 0.8f);
  s.run();
  const auto got_scaled = beta.download();
  for (int b = 0; b < n; ++b)
    for (int p = 0; p < points; ++p)
      for (int k = 0; k < 6; ++k)
        EXPECT_NEAR(got_scaled[(std::size_t(b) * 6 + k) * points + p],
                    want_scaled_rows[(std::size_t(b) * points + p) * 6 + k], 1e-4);
  blur.weights(s, coeffs, beta);  // the unscaled layer is still there
  s.run();
  test::expect_all_close("beta", beta.download(), want, {1e-4, 1e-5});
  Tensor wrong = Tensor::empty(dev, {n, 12, h, w});  // a_2..a_13 only
  EXPECT_THROW(blur.weights(s, wrong, beta), InvalidArgument);
  EXPECT_THROW(blur.weights(s, coeffs, beta, 0.f), InvalidArgument);
  EXPECT_THROW(blur.weights(s, coeffs, beta, std::nanf("")), InvalidArgument);
}

// Blur removes detail: the frame's gradient energy falls well below the
// tilt-only frame's, and brightness is kept (normalized form).
TEST_F(BlurModelTest, BlurSmoothsAndKeepsBrightness) {
  Device& dev = test::device();
  const auto blur = load_blur_model(dev, path_);
  const Params p = params(1, 1, 48, 48);
  SimOptions with, without;
  without.blur = false;
  Simulator a(dev, p, blur, with), b(dev, p, nullptr, without);
  std::vector<float> xs(48 * 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 48; ++x) xs[std::size_t(y) * 48 + x] = ((x / 2 + y / 2) % 2) ? 0.9f : 0.1f;
  Tensor x = Tensor::from(dev, {1, 1, 48, 48}, xs);
  Tensor ya = Tensor::empty(dev, x.shape()), yb = Tensor::empty(dev, x.shape());
  a.reset(3);
  b.reset(3);
  Stream s(dev);
  a.frame(s, x, ya);
  b.frame(s, x, yb);
  s.run();
  auto energy = [](const std::vector<float>& v) {
    double e = 0;
    for (int r = 0; r < 48; ++r)
      for (int c = 1; c < 48; ++c)
        e += std::pow(double(v[std::size_t(r) * 48 + c] - v[std::size_t(r) * 48 + c - 1]), 2);
    return e;
  };
  const auto va = ya.download(), vb = yb.download();
  EXPECT_LT(energy(va), 0.5 * energy(vb));
  double ma = 0, mb = 0;
  for (std::size_t i = 0; i < va.size(); ++i) {
    ma += va[i];
    mb += vb[i];
  }
  EXPECT_NEAR(ma / double(va.size()), mb / double(vb.size()), 0.02);
  EXPECT_EQ(a.beta().shape(), (Shape{1, 6, 48, 48}));
}

TEST_F(BlurModelTest, TiltAndBlurBackwardMatchesFiniteDifferences) {
  Device& dev = test::device();
  const auto blur = load_blur_model(dev, path_);
  const Params p = params(1, 2, 11, 13);
  Simulator sim(dev, p, blur, {});
  test::expect_frame_gradient(sim, test::random_floats(std::size_t(2 * 11 * 13), 9, 0.f, 1.f), 8, 5,
                              "simulator tilt+blur d/dx");
}

TEST_F(BlurModelTest, MismatchedOpticsAndMissingFilesAreClearErrors) {
  Device& dev = test::device();
  const auto blur = load_blur_model(dev, path_);
  Params p = params(1, 1, 16, 16);
  p.optics.pixel_pitch_m *= 2;  // another sampling than the basis was made for
  EXPECT_THROW(Simulator(dev, p, blur, {}), InvalidArgument);
  p = params(1, 1, 16, 16);
  p.zernike_modes = 10;  // fewer modes than the network takes
  EXPECT_THROW(Simulator(dev, p, blur, {}), InvalidArgument);
  EXPECT_THROW(load_blur_model(dev, "/nonexistent/model.safetensors"), Error);
}

// Channels of two wavelengths blur with two models (two groups, sliced and
// concatenated): the backward still matches finite differences.
TEST_F(BlurModelTest, PerChannelWavelengthBackwardMatchesFiniteDifferences) {
  Device& dev = test::device();
  const std::vector<std::shared_ptr<const BlurModel>> models = {load_blur_model(dev, red_path_),
                                                                load_blur_model(dev, path_)};
  Simulator sim(dev, two_wavelengths(11, 13), models, {});
  EXPECT_EQ(sim.blur_model(0), models[1].get());
  EXPECT_EQ(sim.blur_model(1), models[0].get());
  test::expect_frame_gradient(sim, test::random_floats(std::size_t(2 * 11 * 13), 10, 0.f, 1.f), 8,
                              5, "simulator two wavelengths d/dx");
}

// More than 4 channels: groups of at most 4 that share one β. A 6-channel
// frame of one plane repeated is the 1-channel frame repeated.
TEST_F(BlurModelTest, MoreThanFourChannelsShareOneBeta) {
  Device& dev = test::device();
  const auto blur = load_blur_model(dev, path_);
  const int h = 16, w = 20;
  const auto plane = test::random_floats(std::size_t(h) * std::size_t(w), 12, 0.f, 1.f);
  std::vector<float> xs;
  for (int c = 0; c < 6; ++c) xs.insert(xs.end(), plane.begin(), plane.end());
  Simulator six(dev, params(1, 6, h, w), blur, {}), one(dev, params(1, 1, h, w), blur, {});
  const Tensor x6 = Tensor::from(dev, {1, 6, h, w}, xs), y6 = Tensor::empty(dev, x6.shape());
  const Tensor x1 = Tensor::from(dev, {1, 1, h, w}, plane), y1 = Tensor::empty(dev, x1.shape());
  six.reset(4);
  one.reset(4);
  Stream s(dev);
  six.frame(s, x6, y6);
  one.frame(s, x1, y1);
  s.run();
  const auto got = y6.download(), want = y1.download();
  for (int c = 0; c < 6; ++c) {
    test::expect_all_close("got",
                           std::vector<float>(got.begin() + std::ptrdiff_t(c) * h * w,
                                              got.begin() + std::ptrdiff_t(c + 1) * h * w),
                           want, {1e-5, 1e-5});
  }
  EXPECT_EQ(six.beta(5).shape(), six.beta(0).shape());
}

// A channel no model was made for is an error naming it and the fix.
TEST_F(BlurModelTest, AChannelWithoutAModelForItsWavelengthIsAClearError) {
  Device& dev = test::device();
  try {
    Simulator sim(dev, two_wavelengths(16, 16), load_blur_model(dev, path_), {});
    ADD_FAILURE() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("channel 1 (λ = 610"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--channel 1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(
      Simulator(dev, two_wavelengths(16, 16), std::vector<std::shared_ptr<const BlurModel>>{}, {}),
      InvalidArgument);
}

// The shipped model (artifacts/p2s_default.safetensors) loads and fits the presets.
TEST(BlurModelDefault, ShippedModelFitsThePresets) {
  Device& dev = test::device();
  const auto blur = load_default_blur_model(dev);
  for (const char* name : {"weak", "moderate", "strong"}) {
    Params p = preset(name);
    p.image = {32, 32, 3, 1};
    EXPECT_NO_THROW(Simulator(dev, p, blur, {})) << name;
  }
}

// The shipped models cover kRgbWavelengthsM for the presets' optics, and an
// RGB frame with one wavelength per channel is, channel by channel, the grey
// frame simulated at that channel's wavelength with the same seed: the
// turbulence is the same (coefficients in radians at λ_0, scaled by λ_0/λ_c;
// the tilt is achromatic), and each channel blurs with its own model.
TEST(BlurModelDefault, RgbChannelsAreTheGreyFramesAtTheirWavelengths) {
  Device& dev = test::device();
  const auto models = load_shipped_blur_models(dev);
  ASSERT_GE(models.size(), 3u);
  const int h = 40, w = 48;
  Params rgb = preset("strong");
  rgb.optics.wavelengths_m.assign(std::begin(kRgbWavelengthsM), std::end(kRgbWavelengthsM));
  rgb.image = {h, w, 3, 1};
  const Derived d = derive(rgb);
  SimOptions o;
  o.field.tilt_rho = 0.9;
  Simulator sim(dev, rgb, models, o);
  for (int c = 0; c < 3; ++c) {
    ASSERT_NE(sim.blur_model(c), nullptr);
    EXPECT_NEAR(sim.blur_model(c)->nyquist() / d.channels[std::size_t(c)].nyquist, 1.0, 0.02) << c;
  }
  EXPECT_NE(sim.blur_model(0), sim.blur_model(1));
  EXPECT_NE(sim.blur_model(1), sim.blur_model(2));
  std::vector<float> xs(std::size_t(3 * h * w));
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        xs[(std::size_t(c) * h + y) * w + x] = ((x / 3 + y / 3 + c) % 2) ? 0.85f : 0.15f;
  auto run = [&](Simulator& s, const std::vector<float>& in, int channels) {
    const Shape shape{1, channels, h, w};
    const Tensor x = Tensor::from(dev, shape, in), y = Tensor::empty(dev, shape);
    s.reset(11);
    Stream st(dev);
    std::vector<float> frames;
    for (int t = 0; t < 2; ++t) {  // two frames of a video
      s.frame(st, x, y);
      st.run();
      const auto v = y.download();
      frames.insert(frames.end(), v.begin(), v.end());
    }
    return frames;
  };
  const auto got = run(sim, xs, 3);
  std::vector<std::vector<float>> grey(3);
  for (int c = 0; c < 3; ++c) {
    Params p = rgb;
    p.optics.wavelengths_m = {kRgbWavelengthsM[c]};
    p.image.channels = 1;
    Simulator one(dev, p, models, o);
    const std::vector<float> plane(xs.begin() + std::ptrdiff_t(c) * h * w,
                                   xs.begin() + std::ptrdiff_t(c + 1) * h * w);
    grey[std::size_t(c)] = run(one, plane, 1);
    std::vector<float> want, have;
    for (int t = 0; t < 2; ++t) {
      const auto at = std::ptrdiff_t(t) * h * w;
      want.insert(want.end(), grey[std::size_t(c)].begin() + at,
                  grey[std::size_t(c)].begin() + at + h * w);
      const auto from = std::ptrdiff_t(t * 3 + c) * h * w;
      have.insert(have.end(), got.begin() + from, got.begin() + from + h * w);
    }
    test::expect_all_close("have", have, want, {2e-4, 1e-4});
  }
  // The wavelength matters: the red and blue grey frames of one scene differ.
  Params p = rgb;
  p.image.channels = 1;
  std::vector<float> frames[2];
  for (int i = 0; i < 2; ++i) {
    p.optics.wavelengths_m = {kRgbWavelengthsM[i == 0 ? 0 : 2]};
    Simulator one(dev, p, models, o);
    frames[i] = run(one, std::vector<float>(xs.begin(), xs.begin() + h * w), 1);
  }
  double diff = 0;
  for (std::size_t i = 0; i < frames[0].size(); ++i)
    diff = std::max(diff, std::fabs(double(frames[0][i] - frames[1][i])));
  EXPECT_GT(diff, 0.05);
}

}  // namespace
}  // namespace vkjr2::sim
