#include <vkjr2/kernels/ref/warp_ref.hpp>
#include <vkjr2/kernels/warp.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::SamplePadding;

struct Dims {
  int n, c, h, w;
  std::string str() const {
    return std::to_string(n) + "x" + std::to_string(c) + "x" + std::to_string(h) + "x" +
           std::to_string(w);
  }
};

// 1×1 images, odd sizes, widths that do not divide the 128-pixel workgroup,
// channel counts around the ×4 unrolled loop, up to 64 channels.
const std::vector<Dims> kDims = {{1, 1, 1, 1},  {1, 3, 17, 23}, {2, 4, 9, 65}, {1, 64, 6, 7},
                                 {3, 5, 13, 1}, {2, 1, 1, 31},  {1, 7, 32, 33}};

const char* padding_name(SamplePadding p) { return p == SamplePadding::zeros ? "zeros" : "border"; }

// Displacements of integer part in [-3, 3] and fractional part in
// [0.15, 0.85]: positions never lie near a pixel edge, where bilinear sampling
// is not differentiable and float rounding could pick another cell. Pixels
// near the border sample outside the image.
std::vector<float> smooth_flow(std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> whole(-3, 3);
  std::uniform_real_distribution<float> frac(0.15f, 0.85f);
  std::vector<float> f(count);
  for (float& v : f) v = float(whole(rng)) + frac(rng);
  return f;
}

// The edge dimensions, then random ones.
Dims draw_dims(test::OpCase& c) {
  if (c.index < int(kDims.size())) return kDims[std::size_t(c.index)];
  return {c.uniform(1, 3), c.uniform(1, 12), c.uniform(1, 48), c.uniform(1, 48)};
}

std::vector<float> run_warp(Device& dev, const Dims& d, std::span<const float> img,
                            std::span<const float> flow, SamplePadding padding) {
  Tensor ti = Tensor::from(dev, {d.n, d.c, d.h, d.w}, img);
  Tensor tf = Tensor::from(dev, {d.n, 2, d.h, d.w}, flow);
  Tensor to = Tensor::empty(dev, {d.n, d.c, d.h, d.w});
  Stream s(dev);
  kernels::warp(s, ti, tf, to, padding);
  s.run();
  return to.download();
}

TEST(WarpKernel, ForwardMatchesReference) {
  test::check_op("warp", {.seed = 2024, .cases = 11}, [](test::OpCase& c) {
    const Dims d = draw_dims(c);
    c.describe(d.str());
    const auto img = c.floats(std::int64_t(d.n) * d.c * d.h * d.w);
    const auto flow = c.floats(std::int64_t(d.n) * 2 * d.h * d.w, -4, 4);
    for (SamplePadding padding : {SamplePadding::zeros, SamplePadding::border}) {
      const auto want = ref::warp(img, flow, d.n, d.c, d.h, d.w, padding);
      c.expect(std::string("out ") + padding_name(padding),
               run_warp(c.device, d, img, flow, padding), want, test::peak_relative(want, 1e-4));
    }
  });
}

TEST(WarpKernel, ZeroFlowIsIdentity) {
  Device& dev = test::device();
  const Dims d{2, 3, 11, 13};
  const auto img = test::random_floats(std::size_t(d.n) * d.c * d.h * d.w, 5);
  const std::vector<float> flow(std::size_t(d.n) * 2 * d.h * d.w, 0.f);
  for (SamplePadding padding : {SamplePadding::zeros, SamplePadding::border}) {
    SCOPED_TRACE(padding_name(padding));
    EXPECT_EQ(run_warp(dev, d, img, flow, padding), img);
  }
}

struct WarpGrads {
  std::vector<float> d_img, d_flow;
};

WarpGrads run_backward(Device& dev, const Dims& d, std::span<const float> img,
                       std::span<const float> flow, std::span<const float> d_out,
                       SamplePadding padding) {
  const Shape img_shape{d.n, d.c, d.h, d.w}, flow_shape{d.n, 2, d.h, d.w};
  Tensor ti = Tensor::from(dev, img_shape, img);
  Tensor tf = Tensor::from(dev, flow_shape, flow);
  Tensor tg = Tensor::from(dev, img_shape, d_out);
  Tensor di = Tensor::empty(dev, img_shape), df = Tensor::empty(dev, flow_shape);
  Stream s(dev);
  kernels::warp_backward(s, ti, tf, tg, &di, &df, padding);
  s.run();
  return {di.download(), df.download()};
}

TEST(WarpKernel, BackwardMatchesReference) {
  test::check_op("warp backward", {.seed = 77, .cases = 11}, [](test::OpCase& c) {
    const Dims d = draw_dims(c);
    c.describe(d.str());
    const std::int64_t numel = std::int64_t(d.n) * d.c * d.h * d.w;
    const auto img = c.floats(numel);
    const auto flow = smooth_flow(std::size_t(d.n) * 2 * d.h * d.w, c.seed + 1);
    const auto d_out = c.floats(numel);
    for (SamplePadding padding : {SamplePadding::zeros, SamplePadding::border}) {
      const WarpGrads got = run_backward(c.device, d, img, flow, d_out, padding);
      std::vector<float> d_img, d_flow;
      ref::warp_backward(img, flow, d_out, d.n, d.c, d.h, d.w, padding, d_img, d_flow);
      const std::string how = std::string(" ") + padding_name(padding);
      c.expect("d_img" + how, got.d_img, d_img, test::peak_relative(d_img, 1e-4));
      c.expect("d_flow" + how, got.d_flow, d_flow, test::peak_relative(d_flow, 1e-4));
    }
  });
}

// Only one of the two gradients, and large flows that pile many output
// pixels onto the same input pixels (a stress for the d_img scatter).
TEST(WarpKernel, BackwardSingleGradientAndPileUps) {
  Device& dev = test::device();
  const Dims d{1, 2, 19, 21};
  const std::uint32_t seed = 8;
  SCOPED_TRACE("seed=" + std::to_string(seed));
  const std::size_t numel = std::size_t(d.n) * d.c * d.h * d.w;
  const auto img = test::random_floats(numel, seed);
  auto flow = smooth_flow(std::size_t(d.n) * 2 * d.h * d.w, seed + 1);
  for (float& f : flow) f *= 5.f;  // most samples clamp to the border
  const auto d_out = test::random_floats(numel, seed + 2, -1e3f, 1e3f);
  std::vector<float> d_img, d_flow;
  ref::warp_backward(img, flow, d_out, d.n, d.c, d.h, d.w, SamplePadding::border, d_img, d_flow);
  Tensor ti = Tensor::from(dev, {d.n, d.c, d.h, d.w}, img);
  Tensor tf = Tensor::from(dev, {d.n, 2, d.h, d.w}, flow);
  Tensor tg = Tensor::from(dev, {d.n, d.c, d.h, d.w}, d_out);
  Tensor di = Tensor::empty(dev, ti.shape()), df = Tensor::empty(dev, tf.shape());
  Stream s(dev);
  kernels::warp_backward(s, ti, tf, tg, &di, nullptr, SamplePadding::border);
  kernels::warp_backward(s, ti, tf, tg, nullptr, &df, SamplePadding::border);
  s.run();
  test::expect_all_close("d_img", di.download(), d_img, test::peak_relative(d_img, 1e-4));
  test::expect_all_close("d_flow", df.download(), d_flow, test::peak_relative(d_flow, 1e-4));
}

// The fixed-point d_img scale follows max |d_out|: tiny and huge gradients
// keep full fp32 relative accuracy.
TEST(WarpKernel, BackwardImageAtExtremeScales) {
  Device& dev = test::device();
  const Dims d{1, 2, 9, 10};
  const std::uint32_t seed = 21;
  const std::size_t numel = std::size_t(d.n) * d.c * d.h * d.w;
  const auto img = test::random_floats(numel, seed);
  const auto flow = smooth_flow(std::size_t(d.n) * 2 * d.h * d.w, seed + 1);
  for (float scale : {1e-30f, 1e-6f, 1e30f}) {
    SCOPED_TRACE("scale=" + std::to_string(scale) + " seed=" + std::to_string(seed));
    auto d_out = test::random_floats(numel, seed + 2);
    for (float& g : d_out) g *= scale;
    std::vector<float> d_img, d_flow;
    ref::warp_backward(img, flow, d_out, d.n, d.c, d.h, d.w, SamplePadding::zeros, d_img, d_flow);
    test::expect_all_close("d_img",
                           run_backward(dev, d, img, flow, d_out, SamplePadding::zeros).d_img,
                           d_img, test::peak_relative(d_img, 1e-4));
  }
}

TEST(WarpKernel, BackwardIsDeterministic) {
  Device& dev = test::device();
  const Dims d{2, 3, 31, 29};
  const std::size_t numel = std::size_t(d.n) * d.c * d.h * d.w;
  const auto img = test::random_floats(numel, 3);
  auto flow = test::random_floats(std::size_t(d.n) * 2 * d.h * d.w, 4, -2, 2);
  const auto d_out = test::random_floats(numel, 5);
  const WarpGrads a = run_backward(dev, d, img, flow, d_out, SamplePadding::zeros);
  const WarpGrads b = run_backward(dev, d, img, flow, d_out, SamplePadding::zeros);
  EXPECT_EQ(a.d_img, b.d_img);
  EXPECT_EQ(a.d_flow, b.d_flow);
}

TEST(WarpKernel, GradcheckImage) {
  Device& dev = test::device();
  const Dims d{1, 2, 5, 6};
  const std::uint32_t seed = 11;
  for (SamplePadding padding : {SamplePadding::zeros, SamplePadding::border}) {
    SCOPED_TRACE(std::string(padding_name(padding)) + " seed=" + std::to_string(seed));
    const std::size_t numel = std::size_t(d.n) * d.c * d.h * d.w;
    const auto img = test::random_floats(numel, seed);
    const auto flow = smooth_flow(std::size_t(d.n) * 2 * d.h * d.w, seed + 1);
    const auto w = test::random_floats(numel, seed + 2);
    const WarpGrads g = run_backward(dev, d, img, flow, w, padding);
    auto loss = [&](std::span<const float> x) {
      return test::weighted_sum(run_warp(dev, d, x, flow, padding), w);
    };
    test::expect_gradient_matches(loss, img, g.d_img, "d_img", {.seed = seed});
  }
}

TEST(WarpKernel, GradcheckFlow) {
  Device& dev = test::device();
  const Dims d{2, 3, 4, 5};
  const std::uint32_t seed = 12;
  for (SamplePadding padding : {SamplePadding::zeros, SamplePadding::border}) {
    SCOPED_TRACE(std::string(padding_name(padding)) + " seed=" + std::to_string(seed));
    const std::size_t numel = std::size_t(d.n) * d.c * d.h * d.w;
    const auto img = test::random_floats(numel, seed);
    const auto flow = smooth_flow(std::size_t(d.n) * 2 * d.h * d.w, seed + 1);
    const auto w = test::random_floats(numel, seed + 2);
    const WarpGrads g = run_backward(dev, d, img, flow, w, padding);
    auto loss = [&](std::span<const float> x) {
      return test::weighted_sum(run_warp(dev, d, img, x, padding), w);
    };
    test::expect_gradient_matches(loss, flow, g.d_flow, "d_flow", {.seed = seed});
  }
}

// NaN or infinite displacements give NaN in every channel of that pixel; NaN
// in the image propagates to the pixels whose taps read it, zero-weight taps
// included (as in PyTorch: 0 · NaN = NaN).
TEST(WarpKernel, NonFiniteInputs) {
  Device& dev = test::device();
  // 2 channels: one channel per texel read; 3 and 5: the RGBA-packed sampler.
  for (const int c : {2, 3, 5}) {
    SCOPED_TRACE("channels " + std::to_string(c));
    const Dims d{1, c, 3, 4};
    std::vector<float> img(std::size_t(12 * c), 1.f);
    std::vector<float> flow(24, 0.f);
    flow[5] = NAN;            // dx of pixel 5
    flow[12 + 7] = INFINITY;  // dy of pixel 7
    img[12 + 2] = NAN;        // channel 1, pixel 2
    const auto out = run_warp(dev, d, img, flow, SamplePadding::zeros);
    for (int ch = 0; ch < c; ++ch) {
      for (int p = 0; p < 12; ++p) {
        SCOPED_TRACE("channel " + std::to_string(ch) + " pixel " + std::to_string(p));
        const bool bad_flow = p == 5 || p == 7;
        // pixel 1 reads pixel 2 at weight 0
        EXPECT_EQ(std::isnan(out[std::size_t(12 * ch + p)]),
                  bad_flow || (ch == 1 && (p == 2 || p == 1)));
      }
    }
  }
}

TEST(WarpKernel, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor img = Tensor::empty(dev, {1, 3, 8, 8});
  Tensor flow = Tensor::empty(dev, {1, 2, 8, 8});
  Tensor out = Tensor::empty(dev, {1, 3, 8, 8});
  Tensor bad_flow = Tensor::empty(dev, {1, 3, 8, 8});
  test::expect_invalid_argument([&] { kernels::warp(s, img, bad_flow, out); }, "flow");
  Tensor small_out = Tensor::empty(dev, {1, 3, 8, 7});
  test::expect_invalid_argument([&] { kernels::warp(s, img, flow, small_out); }, "out");
  Tensor empty = Tensor::empty(dev, {0, 3, 8, 8});
  test::expect_invalid_argument([&] { kernels::warp(s, empty, flow, out); }, "empty");
  Tensor flat = Tensor::empty(dev, {3, 8, 8});
  test::expect_invalid_argument([&] { kernels::warp(s, flat, flow, out); }, "rank");
  test::expect_invalid_argument(
      [&] { kernels::warp_backward(s, img, flow, out, nullptr, nullptr); }, "null");
  test::expect_invalid_argument(
      [&] { kernels::warp_backward(s, img, flow, small_out, &out, nullptr); }, "d_out");
  test::expect_invalid_argument([&] { kernels::warp_backward(s, img, flow, out, &out, &img); },
                                "d_flow");
}

}  // namespace
}  // namespace vkjr2
