#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "support/expect.hpp"
#include "support/frame_gradcheck.hpp"
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
  }
  static void TearDownTestSuite() { fs::remove(path_); }
  static Params params(int batch, int channels, int h, int w) {
    Params p = preset("strong");
    p.zernike_modes = 15;
    p.image = {h, w, channels, batch};
    return p;
  }
  static fs::path path_;
};
fs::path BlurModelTest::path_;

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
  test::expect_all_near(beta.download(), want, 1e-4, 1e-5);
  Tensor wrong = Tensor::empty(dev, {n, 12, h, w});  // a_2..a_13 only
  EXPECT_THROW(blur.weights(s, wrong, beta), InvalidArgument);
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

}  // namespace
}  // namespace vkjr2::sim
