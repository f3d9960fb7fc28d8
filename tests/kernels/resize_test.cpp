#include <vkjr2/kernels/ref/resize_ref.hpp>
#include <vkjr2/kernels/resize.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::ResizeMode;

constexpr ResizeMode kModes[] = {ResizeMode::bilinear_half_pixel, ResizeMode::bilinear_legacy,
                                 ResizeMode::bilinear_align_corners, ResizeMode::nearest};

struct Case {
  std::int64_t n, c, h, w, oh, ow;
};

std::int64_t uniform_int(std::mt19937& rng, int lo, int hi) {
  return std::int64_t(std::uniform_int_distribution<int>(lo, hi)(rng));
}

// x's planes zero-padded to the canvas, on the host.
std::vector<float> host_canvas(const std::vector<float>& xv, const Case& k,
                               const kernels::ResizeCanvas& c) {
  std::vector<float> canvas(std::size_t(k.n * k.c * c.height * c.width), 0.f);
  for (std::int64_t p = 0; p < k.n * k.c; ++p) {
    for (std::int64_t r = 0; r < k.h; ++r) {
      for (std::int64_t col = 0; col < k.w; ++col) {
        canvas[std::size_t((p * c.height + c.top + r) * c.width + c.left + col)] =
            xv[std::size_t((p * k.h + r) * k.w + col)];
      }
    }
  }
  return canvas;
}

std::string str(const Case& k) {
  return "[" + std::to_string(k.n) + "," + std::to_string(k.c) + "," + std::to_string(k.h) + "," +
         std::to_string(k.w) + "] -> " + std::to_string(k.oh) + "x" + std::to_string(k.ow);
}

std::string str(const Case& k, ResizeMode m) {
  return str(k) + " mode " + std::to_string(static_cast<int>(m));
}

// Edge cases (1×1 in or out, up- and downscales, odd and tall sizes), then
// random ones.
const std::vector<Case> kEdges = {
    {1, 1, 1, 1, 1, 1},   {1, 2, 1, 1, 5, 3},    {1, 1, 6, 5, 1, 1},   {2, 3, 8, 8, 4, 4},
    {1, 3, 7, 9, 14, 18}, {1, 2, 17, 13, 5, 29}, {1, 1, 64, 3, 11, 7}, {1, 1, 10, 10, 23, 23}};

Case draw_case(test::OpCase& c) {
  if (c.index < int(kEdges.size())) return kEdges[std::size_t(c.index)];
  auto uni = [&](int lo, int hi) { return std::int64_t(c.uniform(lo, hi)); };
  return {uni(1, 2), uni(1, 4), uni(1, 40), uni(1, 40), uni(1, 40), uni(1, 40)};
}

TEST(ResizeKernels, MatchReference) {
  const int cases = int(kEdges.size()) + 5;
  test::check_op("resize", {.seed = 601, .cases = cases}, [](test::OpCase& c) {
    const Case k = draw_case(c);
    c.describe(str(k));
    const Shape xs{k.n, k.c, k.h, k.w}, ys{k.n, k.c, k.oh, k.ow};
    const auto xv = c.floats(xs.numel()), dyv = c.floats(ys.numel());
    Tensor x = c.tensor(xs, xv), dy = c.tensor(ys, dyv);
    for (ResizeMode m : kModes) {
      const std::string mode = " mode " + std::to_string(static_cast<int>(m));
      Tensor y = c.empty(ys), dx = c.empty(xs);
      Stream s(c.device);
      kernels::resize(s, x, m, y);
      kernels::resize_backward(s, dy, m, dx);
      s.run();
      c.expect("y" + mode, y, ref::resize(xv, k.n * k.c, k.h, k.w, k.oh, k.ow, m), {1e-5, 1e-5});
      c.expect("dx" + mode, dx, ref::resize_backward(dyv, k.n * k.c, k.h, k.w, k.oh, k.ow, m),
               {1e-4, 1e-4});
    }
  });
}

// One pass over a virtual zero-padded canvas against the reference resize of
// the padded planes built on the host (padding before and after x on either
// axis, or none; down- and upscaled).
TEST(ResizeKernels, ZeroPaddedMatchesPadThenResize) {
  Device& dev = test::device();
  const std::uint32_t seed = 602;
  std::mt19937 rng(seed);
  auto uni = [&](int lo, int hi) { return uniform_int(rng, lo, hi); };
  struct PadCase {
    Case k;
    kernels::ResizeCanvas canvas;
  };
  std::vector<PadCase> pads = {{{1, 3, 7, 12, 5, 5}, {12, 12, 0, 0}},
                               {{1, 3, 12, 7, 9, 9}, {12, 12, 0, 0}},
                               {{1, 3, 12, 7, 9, 9}, {12, 12, 0, 2}},  // centred (face-api's)
                               {{2, 1, 5, 5, 8, 3}, {9, 6, 3, 1}},
                               {{1, 2, 6, 4, 6, 4}, {6, 4, 0, 0}}};
  for (int i = 0; i < 6; ++i) {
    const Case k{uni(1, 2), uni(1, 3), uni(1, 30), uni(1, 30), uni(1, 40), uni(1, 40)};
    const std::int64_t top = uni(0, 10), left = uni(0, 10);
    pads.push_back({k, {k.h + top + uni(0, 10), k.w + left + uni(0, 10), top, left}});
  }
  for (const auto& [k, canvas_at] : pads) {
    const auto [ch, cw, top, left] = canvas_at;
    for (ResizeMode m : kModes) {
      SCOPED_TRACE(str(k, m) + " canvas " + std::to_string(ch) + "x" + std::to_string(cw) + " at " +
                   std::to_string(top) + "," + std::to_string(left) +
                   " seed=" + std::to_string(seed));
      const Shape xs{k.n, k.c, k.h, k.w}, ys{k.n, k.c, k.oh, k.ow};
      const auto xv = test::random_floats(std::size_t(xs.numel()), seed);
      const std::vector<float> canvas = host_canvas(xv, k, canvas_at);
      Tensor x = Tensor::from(dev, xs, xv), y = Tensor::empty(dev, ys);
      Stream s(dev);
      kernels::resize_zero_padded(s, x, canvas_at, m, y);
      s.run();
      const auto want = ref::resize(canvas, k.n * k.c, ch, cw, k.oh, k.ow, m);
      const auto got = y.download();
      for (std::size_t i = 0; i < want.size(); ++i) {
        ASSERT_NEAR(got[i], want[i], 1e-5 * (1 + std::fabs(want[i]))) << "y at " << i;
      }
    }
  }
}

// The network-input pass: resize_zero_padded, the per-channel affine, the
// result in the interior of padded planes whose border stays as it was; the
// non-finite flag. Against the reference resize of the host-built canvas.
TEST(ResizeKernels, IntoPaddedMatchesResizeThenAffine) {
  Device& dev = test::device();
  const std::uint32_t seed = 603;
  std::mt19937 rng(seed);
  auto uni = [&](int lo, int hi) { return uniform_int(rng, lo, hi); };
  struct IntoCase {
    Case k;
    kernels::ResizeCanvas canvas;
    std::uint32_t hp, wp;
    std::int32_t top, left;
  };
  // The landmark net's own (a 255×312 crop to 112², conv0's padded input),
  // the vec4 store path, and random ones (most take the scalar stores).
  std::vector<IntoCase> cases = {{{1, 3, 255, 312, 112, 112}, {312, 312, 29, 0}, 114, 120, 0, 4},
                                 {{2, 3, 9, 6, 8, 8}, {9, 9, 0, 1}, 10, 16, 1, 4},
                                 {{1, 1, 5, 5, 5, 7}, {5, 5, 0, 0}, 7, 9, 2, 1}};
  for (int i = 0; i < 5; ++i) {
    const Case k{uni(1, 2), uni(1, 3), uni(1, 30), uni(1, 30), uni(1, 30), uni(1, 30)};
    const std::int64_t top = uni(0, 6), left = uni(0, 6);
    const auto pt = std::int32_t(uni(0, 3)), pl = std::int32_t(uni(0, 5));
    cases.push_back({k,
                     {k.h + top + uni(0, 6), k.w + left + uni(0, 6), top, left},
                     std::uint32_t(k.oh + pt + uni(0, 3)),
                     std::uint32_t(k.ow + pl + uni(0, 5)),
                     pt,
                     pl});
  }
  for (const IntoCase& ic : cases) {
    const Case& k = ic.k;
    const auto [ch, cw, top, left] = ic.canvas;
    for (ResizeMode m : kModes) {
      SCOPED_TRACE(str(k, m) + " padded " + std::to_string(ic.hp) + "x" + std::to_string(ic.wp) +
                   " at " + std::to_string(ic.top) + "," + std::to_string(ic.left) +
                   " seed=" + std::to_string(seed));
      const Shape xs{k.n, k.c, k.h, k.w};
      auto xv = test::random_floats(std::size_t(xs.numel()), seed, 0.f, 255.f);
      const auto sv = test::random_floats(std::size_t(k.c), seed + 1, 0.5f, 2.f);
      const auto bv = test::random_floats(std::size_t(k.c), seed + 2);
      const std::vector<float> canvas = host_canvas(xv, k, ic.canvas);
      const auto resized = ref::resize(canvas, k.n * k.c, ch, cw, k.oh, k.ow, m);
      const std::size_t plane = std::size_t(ic.hp) * ic.wp;
      std::vector<float> want(std::size_t(k.n * k.c) * plane, 7.f);  // the border: untouched
      for (std::int64_t p = 0; p < k.n * k.c; ++p) {
        const std::size_t c = std::size_t(p % k.c);
        for (std::int64_t r = 0; r < k.oh; ++r) {
          for (std::int64_t col = 0; col < k.ow; ++col) {
            want[std::size_t(p) * plane + std::size_t(r + ic.top) * ic.wp +
                 std::size_t(col + ic.left)] =
                std::fma(resized[std::size_t((p * k.oh + r) * k.ow + col)], sv[c], bv[c]);
          }
        }
      }
      kernels::Planes y;
      y.data =
          Tensor::from(dev, Shape{std::int64_t(want.size())}, std::vector<float>(want.size(), 7.f));
      y.shape = Shape{k.n, k.c, k.oh, k.ow};
      y.layout = kernels::PlaneLayout{std::uint32_t(ic.hp), std::uint32_t(ic.wp),
                                      std::int32_t(ic.top), std::int32_t(ic.left)};
      Tensor x = Tensor::from(dev, xs, xv),
             flag = Tensor::from(dev, Shape{1}, std::vector<float>{0.f});
      Tensor scale = Tensor::from(dev, Shape{k.c}, sv), shift = Tensor::from(dev, Shape{k.c}, bv);
      Stream s(dev);
      kernels::resize_into_padded(s, x, ic.canvas, m, scale, shift, y, &flag);
      s.run();
      const auto got = y.data.download();
      for (std::size_t i = 0; i < want.size(); ++i) {
        ASSERT_NEAR(got[i], want[i], 1e-5 * (1 + std::fabs(want[i]))) << "y at " << i;
      }
      EXPECT_EQ(flag.download()[0], 0.f);
      // One NaN source pixel that an output reads sets the flag (the first
      // pixel of the first plane: every mode's tap of output (0, 0) when
      // the canvas starts with the source).
      if (top == 0 && left == 0) {
        xv[0] = std::nanf("");
        Tensor xn = Tensor::from(dev, xs, xv);
        kernels::resize_into_padded(s, xn, ic.canvas, m, scale, shift, y, &flag);
        s.run();
        EXPECT_EQ(flag.download()[0], 1.f);
      }
    }
  }
}

TEST(ResizeKernels, ConventionsOnKnownValues) {
  // x = 0..7 on one row; downsample 8 -> 4 and upsample 4 -> 8.
  Device& dev = test::device();
  std::vector<float> ramp(8);
  for (int i = 0; i < 8; ++i) ramp[std::size_t(i)] = float(i);
  Tensor x = Tensor::from(dev, {1, 1, 1, 8}, ramp);
  Tensor half = Tensor::empty(dev, {1, 1, 1, 4}), legacy = Tensor::empty(dev, {1, 1, 1, 4});
  Tensor corners = Tensor::empty(dev, {1, 1, 1, 4}), near = Tensor::empty(dev, {1, 1, 1, 4});
  Stream s(dev);
  kernels::resize(s, x, ResizeMode::bilinear_half_pixel, half);
  kernels::resize(s, x, ResizeMode::bilinear_legacy, legacy);
  kernels::resize(s, x, ResizeMode::bilinear_align_corners, corners);
  kernels::resize(s, x, ResizeMode::nearest, near);
  s.run();
  EXPECT_EQ(half.download(), (std::vector<float>{0.5f, 2.5f, 4.5f, 6.5f}));  // src = 2d + 0.5
  EXPECT_EQ(legacy.download(), (std::vector<float>{0.f, 2.f, 4.f, 6.f}));    // src = 2d
  EXPECT_EQ(near.download(), (std::vector<float>{0.f, 2.f, 4.f, 6.f}));
  const auto c = corners.download();  // src = 7d/3
  for (int d = 0; d < 4; ++d) EXPECT_NEAR(c[std::size_t(d)], 7.f * float(d) / 3.f, 1e-5);

  Tensor up = Tensor::empty(dev, {1, 1, 1, 8});
  Tensor x4 = Tensor::from(dev, {1, 1, 1, 4}, std::vector<float>{0, 1, 2, 3});
  kernels::resize(s, x4, ResizeMode::bilinear_legacy, up);
  s.run();
  // src = d/2; the last output clamps onto the last pixel.
  EXPECT_EQ(up.download(), (std::vector<float>{0, 0.5f, 1, 1.5f, 2, 2.5f, 3, 3}));
  kernels::resize(s, x4, ResizeMode::bilinear_half_pixel, up);
  s.run();
  // src = (d + 0.5)/2 − 0.5, clamped to [0, 3].
  EXPECT_EQ(up.download(), (std::vector<float>{0, 0.25f, 0.75f, 1.25f, 1.75f, 2.25f, 2.75f, 3}));
}

TEST(ResizeKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const std::uint32_t seed = 602;
  const Shape xs{1, 2, 5, 7}, ys{1, 2, 8, 4};
  const auto xv = test::random_floats(std::size_t(xs.numel()), seed);
  const auto wv = test::random_floats(std::size_t(ys.numel()), seed + 1);
  for (ResizeMode m : kModes) {
    SCOPED_TRACE("mode " + std::to_string(static_cast<int>(m)) + " seed=" + std::to_string(seed));
    Tensor w = Tensor::from(dev, ys, wv), dx = Tensor::empty(dev, xs);
    Stream s(dev);
    kernels::resize_backward(s, w, m, dx);
    s.run();
    test::expect_gradient_matches(
        [&](std::span<const float> xi) {
          Tensor x = Tensor::from(dev, xs, xi), y = Tensor::empty(dev, ys);
          Stream st(dev);
          kernels::resize(st, x, m, y);
          st.run();
          return test::weighted_sum(y.download(), wv);
        },
        xv, dx.download(), "resize");
  }
}

TEST(ResizeKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor x = Tensor::empty(dev, {1, 2, 8, 8});
  Tensor wrong_c = Tensor::empty(dev, {1, 3, 4, 4});
  EXPECT_THROW(kernels::resize(s, x, ResizeMode::nearest, wrong_c), InvalidArgument);
  Tensor flat = Tensor::empty(dev, {64});
  EXPECT_THROW(kernels::resize(s, flat, ResizeMode::nearest, x), InvalidArgument);
  EXPECT_THROW(kernels::resize(s, x, static_cast<ResizeMode>(7), x), InvalidArgument);
  try {  // a canvas smaller than x
    kernels::resize_zero_padded(s, x, {8, 7, 0, 0}, ResizeMode::bilinear_legacy, x);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("canvas 8×7"), std::string::npos) << e.what();
  }
  try {  // x does not fit at that offset
    kernels::resize_zero_padded(s, x, {10, 10, 3, 0}, ResizeMode::bilinear_legacy, x);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("at (3, 0)"), std::string::npos) << e.what();
  }
  {  // resize_into_padded: padded planes too small for y, scale of the wrong size
    kernels::Planes y;
    y.data = Tensor::empty(dev, {2 * 6 * 8});
    y.shape = Shape{1, 2, 6, 6};
    y.layout = kernels::PlaneLayout{6, 8, 1, 0};
    Tensor sc = Tensor::empty(dev, {2}), sc3 = Tensor::empty(dev, {3});
    try {
      kernels::resize_into_padded(s, x, {8, 8, 0, 0}, ResizeMode::bilinear_legacy, sc, sc, y);
      FAIL();
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("do not hold y"), std::string::npos) << e.what();
    }
    y.layout.top = 0;
    try {
      kernels::resize_into_padded(s, x, {8, 8, 0, 0}, ResizeMode::bilinear_legacy, sc3, sc, y);
      FAIL();
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("one value per channel"), std::string::npos) << e.what();
    }
  }
  try {
    Tensor empty = Tensor::empty(dev, {1, 2, 0, 8});
    kernels::resize_backward(s, x, ResizeMode::bilinear_legacy, empty);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vkjr2
