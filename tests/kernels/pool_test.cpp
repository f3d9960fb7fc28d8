#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/pool.hpp>
#include <vkjr2/kernels/ref/pool_ref.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::Pool2d;

struct Case {
  std::int64_t n, c, h, w;
  Pool2d p;
};

std::string str(const Case& k) {
  const Pool2d& p = k.p;
  return "x [" + std::to_string(k.n) + "," + std::to_string(k.c) + "," + std::to_string(k.h) + "," +
         std::to_string(k.w) + "] k " + std::to_string(p.kernel_h) + "x" +
         std::to_string(p.kernel_w) + " s " + std::to_string(p.stride_h) + "x" +
         std::to_string(p.stride_w) + " pad " + std::to_string(p.pad_top) + "/" +
         std::to_string(p.pad_bottom) + "/" + std::to_string(p.pad_left) + "/" +
         std::to_string(p.pad_right);
}

// Fixed edge cases (1x1 images, TF SAME, overlapping windows, odd sizes),
// then random ones.
const std::vector<Case> kEdges = {
    {1, 1, 1, 1, kernels::pool_valid(1, 1, 1, 1)},
    {1, 1, 1, 1, kernels::pool_same(3, 3, 2, 2, 1, 1)},
    {2, 3, 7, 9, kernels::pool_valid(2, 2, 2, 2)},
    {1, 2, 8, 8, kernels::pool_same(3, 3, 2, 2, 8, 8)},
    {2, 1, 13, 17, kernels::pool_same(3, 3, 1, 1, 13, 17)},
    {1, 3, 31, 29, Pool2d{3, 2, 2, 1, 1, 2, 0, 1}},
    {1, 1, 67, 5, kernels::pool_same(2, 2, 2, 2, 67, 5)},
    {1, 2, 23, 19, Pool2d{9, 8, 3, 2, 4, 1, 0, 7}},    // wider than the unrolled 7×7
    {1, 32, 72, 72, kernels::pool_valid(3, 3, 2, 2)},  // the face ResNet's
};
constexpr int kCases = 15;

Case draw_case(test::OpCase& c) {
  if (c.index < int(kEdges.size())) return kEdges[std::size_t(c.index)];
  auto uni = [&](int lo, int hi) { return c.uniform(lo, hi); };
  Case k{uni(1, 3), uni(1, 5), uni(1, 40), uni(1, 40), {}};
  const int kh = uni(1, 4), kw = uni(1, 4);
  if (uni(0, 1)) {
    k.p = kernels::pool_same(kh, kw, uni(1, 3), uni(1, 3), k.h, k.w);
  } else {
    k.h = std::max<std::int64_t>(k.h, kh);
    k.w = std::max<std::int64_t>(k.w, kw);
    k.p = Pool2d{kh,
                 kw,
                 uni(1, 3),
                 uni(1, 3),
                 uni(0, kh - 1),
                 uni(0, kh - 1),
                 uni(0, kw - 1),
                 uni(0, kw - 1)};
  }
  return k;
}

// Distinct values 0.1 apart in random order: no ties, and a finite-difference
// step of 1e-2 never changes the argmax.
std::vector<float> distinct_values(std::size_t n, std::uint32_t seed) {
  std::vector<float> v(n);
  std::iota(v.begin(), v.end(), 0.f);
  std::shuffle(v.begin(), v.end(), std::mt19937(seed));
  for (float& f : v) f = 0.1f * (f - float(n) / 2);
  return v;
}

constexpr test::Tol kTol{1e-5, 1e-5};

std::vector<std::int32_t> download_i32(const Tensor& t) {
  std::vector<std::int32_t> v(std::size_t(t.numel()));
  t.download_bytes(v.data(), v.size() * sizeof(std::int32_t));
  return v;
}

TEST(PoolKernels, MaxPoolMatchesReference) {
  test::check_op("max_pool2d", {.seed = 501, .cases = kCases}, [](test::OpCase& c) {
    const Case k = draw_case(c);
    c.describe(str(k));
    const Shape xs{k.n, k.c, k.h, k.w};
    const auto xv = c.floats(xs.numel());
    const Shape ys = kernels::pool_output_shape(xs, k.p);
    Tensor x = c.tensor(xs, xv), y = c.empty(ys), idx = c.empty(ys, DType::i32);
    const auto dyv = c.floats(ys.numel());
    Tensor dy = c.tensor(ys, dyv), dx = c.empty(xs);
    Stream s(c.device);
    kernels::max_pool2d(s, x, k.p, y, idx);
    kernels::max_pool2d_backward(s, dy, idx, k.p, dx);
    // Inference forms: no indices; into the zero-padded input of a 3×3
    // 'same' conv (the interior is the pool, the border stays zero).
    Tensor y2 = c.empty(ys);
    kernels::max_pool2d(s, x, k.p, y2, Tensor());
    kernels::Conv2dParams cp;
    cp.pad = kernels::same_padding(ys[2], ys[3], 3, 3, 1, 1);
    cp.algo = kernels::Conv2dAlgo::blocked;  // (one channel would run depthwise)
    const kernels::PlaneLayout yl =
        kernels::Conv2dPlan(c.device, ys, Shape{8, ys[1], 3, 3}, cp).input_layout();
    ASSERT_FALSE(yl.plain());
    const kernels::Planes yp = kernels::Planes::make(s, ys, yl);
    kernels::max_pool2d_into_padded(s, x, k.p, yp);
    s.run();
    const auto r = ref::max_pool2d(xv, k.n * k.c, k.h, k.w, k.p);
    ASSERT_EQ(r.oh, ys[2]);
    ASSERT_EQ(r.ow, ys[3]);
    c.expect("y", y, r.y, test::kExact);
    c.expect_equal("indices", idx, r.indices);
    c.expect("dx", dx, ref::max_pool2d_backward(dyv, r.indices, k.n * k.c, k.h, k.w, k.p), kTol);
    c.expect("y without indices", y2, r.y, test::kExact);
    std::vector<float> want_padded(std::size_t(ys[0] * ys[1]) * yl.hp * yl.wp, 0.f);
    for (std::int64_t pl = 0; pl < ys[0] * ys[1]; ++pl) {
      for (std::int64_t oy = 0; oy < ys[2]; ++oy) {
        for (std::int64_t ox = 0; ox < ys[3]; ++ox) {
          want_padded[std::size_t((pl * yl.hp + oy + yl.top) * yl.wp + ox + yl.left)] =
              r.y[std::size_t((pl * ys[2] + oy) * ys[3] + ox)];
        }
      }
    }
    c.expect("y into padded planes", yp.data, want_padded, test::kExact);
  });
}

TEST(PoolKernels, AvgPoolMatchesReference) {
  test::check_op("avg_pool2d", {.seed = 502, .cases = kCases}, [](test::OpCase& c) {
    const Case k = draw_case(c);
    c.describe(str(k));
    const Shape xs{k.n, k.c, k.h, k.w};
    const auto xv = c.floats(xs.numel());
    const Shape ys = kernels::pool_output_shape(xs, k.p);
    const auto dyv = c.floats(ys.numel());
    Tensor x = c.tensor(xs, xv), dy = c.tensor(ys, dyv);
    for (bool include_pad : {false, true}) {
      Tensor y = c.empty(ys), dx = c.empty(xs);
      Stream s(c.device);
      kernels::avg_pool2d(s, x, k.p, include_pad, y);
      kernels::avg_pool2d_backward(s, dy, k.p, include_pad, dx);
      s.run();
      const std::string pad = include_pad ? " (padding counted)" : " (padding not counted)";
      c.expect("y" + pad, y, ref::avg_pool2d(xv, k.n * k.c, k.h, k.w, k.p, include_pad).y, kTol);
      c.expect("dx" + pad, dx, ref::avg_pool2d_backward(dyv, k.n * k.c, k.h, k.w, k.p, include_pad),
               kTol);
    }
  });
}

TEST(PoolKernels, AvgPoolPaddingConventions) {
  // 3x3 SAME average of a constant image: TF (exclude padding) keeps the
  // constant everywhere; PyTorch-style (include padding) shrinks the borders.
  Device& dev = test::device();
  const Pool2d p = kernels::pool_same(3, 3, 1, 1, 4, 4);
  Tensor x = Tensor::from(dev, {1, 1, 4, 4}, std::vector<float>(16, 2.f));
  Tensor a = Tensor::empty(dev, {1, 1, 4, 4}), b = Tensor::empty(dev, {1, 1, 4, 4});
  Stream s(dev);
  kernels::avg_pool2d(s, x, p, false, a);
  kernels::avg_pool2d(s, x, p, true, b);
  s.run();
  for (float v : a.download()) EXPECT_FLOAT_EQ(v, 2.f);
  const auto bv = b.download();
  EXPECT_FLOAT_EQ(bv[0], 2.f * 4 / 9);  // corner: 4 of 9 taps inside
  EXPECT_FLOAT_EQ(bv[1], 2.f * 6 / 9);  // edge: 6 of 9
  EXPECT_FLOAT_EQ(bv[5], 2.f);          // interior
}

TEST(PoolKernels, GlobalAvgPoolMatchesReference) {
  // Planes ≤ 64 values run one invocation each, larger ones a workgroup each.
  const std::vector<Shape> edges = {{1, 1, 1, 1},  {2, 3, 7, 5},   {1, 256, 2, 2}, {1, 70, 8, 8},
                                    {1, 5, 5, 13}, {1, 4, 33, 31}, {3, 2, 64, 65}};
  test::check_op("global_avg_pool", {.seed = 503, .cases = 11}, [&](test::OpCase& c) {
    const Shape xs = c.edge_or(edges, [&] { return c.nchw(3, 40, 50, 50); });
    c.describe("x " + xs.str());
    const auto xv = c.floats(xs.numel());
    const Shape ys{xs[0], xs[1], 1, 1};
    const auto dyv = c.floats(ys.numel());
    Tensor x = c.tensor(xs, xv), y = c.empty(ys), dy = c.tensor(ys, dyv), dx = c.empty(xs);
    Stream s(c.device);
    kernels::global_avg_pool(s, x, y);
    kernels::global_avg_pool_backward(s, dy, dx);
    s.run();
    c.expect("y", y, ref::global_avg_pool(xv, xs[0] * xs[1], xs[2] * xs[3]), kTol);
    const std::int64_t hw = xs[2] * xs[3];
    std::vector<float> want_dx(xv.size());
    for (std::size_t i = 0; i < want_dx.size(); ++i)
      want_dx[i] = dyv[i / std::size_t(hw)] / float(hw);
    c.expect("dx", dx, want_dx, {0, 1e-7});
  });
}

// Loss Σ w ⊙ pool(x) evaluated on the device.
template <class Forward>
double device_loss(Device& dev, const Shape& xs, const Shape& ys, std::span<const float> xv,
                   std::span<const float> wv, Forward forward) {
  Tensor x = Tensor::from(dev, xs, xv), y = Tensor::empty(dev, ys);
  Stream s(dev);
  forward(s, x, y);
  s.run();
  return test::weighted_sum(y.download(), wv);
}

TEST(PoolKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const std::uint32_t seed = 504;
  SCOPED_TRACE("seed=" + std::to_string(seed));
  const Shape xs{1, 2, 7, 6};
  const Pool2d p = kernels::pool_same(3, 3, 2, 2, 7, 6);
  const Shape ys = kernels::pool_output_shape(xs, p);
  const auto xv = distinct_values(std::size_t(xs.numel()), seed);
  const auto wv = test::random_floats(std::size_t(ys.numel()), seed + 1);
  Tensor x = Tensor::from(dev, xs, xv), w = Tensor::from(dev, ys, wv);
  Tensor y = Tensor::empty(dev, ys), idx = Tensor::empty(dev, ys, DType::i32);
  Tensor dmax = Tensor::empty(dev, xs), davg = Tensor::empty(dev, xs),
         dglob = Tensor::empty(dev, xs);
  Tensor dglob_y = Tensor::from(dev, {1, 2, 1, 1}, std::vector<float>{0.7f, -1.3f});
  Stream s(dev);
  kernels::max_pool2d(s, x, p, y, idx);
  kernels::max_pool2d_backward(s, w, idx, p, dmax);
  kernels::avg_pool2d_backward(s, w, p, true, davg);
  kernels::global_avg_pool_backward(s, dglob_y, dglob);
  s.run();
  test::expect_gradient_matches(
      [&](std::span<const float> xi) {
        return device_loss(dev, xs, ys, xi, wv, [&](Stream& st, const Tensor& a, const Tensor& b) {
          Tensor i = Tensor::empty(dev, ys, DType::i32);
          kernels::max_pool2d(st, a, p, b, i);
        });
      },
      xv, dmax.download(), "max_pool2d");
  test::expect_gradient_matches(
      [&](std::span<const float> xi) {
        return device_loss(dev, xs, ys, xi, wv, [&](Stream& st, const Tensor& a, const Tensor& b) {
          kernels::avg_pool2d(st, a, p, true, b);
        });
      },
      xv, davg.download(), "avg_pool2d");
  test::expect_gradient_matches(
      [&](std::span<const float> xi) {
        return device_loss(dev, xs, {1, 2, 1, 1}, xi, std::vector<float>{0.7f, -1.3f},
                           [&](Stream& st, const Tensor& a, const Tensor& b) {
                             kernels::global_avg_pool(st, a, b);
                           });
      },
      xv, dglob.download(), "global_avg_pool");
}

TEST(PoolKernels, NaNPropagatesThroughMax) {
  Device& dev = test::device();
  Tensor x = Tensor::from(dev, {1, 1, 2, 2}, std::vector<float>{1, NAN, 3, 2});
  Tensor y = Tensor::empty(dev, {1, 1, 1, 1}), idx = Tensor::empty(dev, {1, 1, 1, 1}, DType::i32);
  Stream s(dev);
  kernels::max_pool2d(s, x, kernels::pool_valid(2, 2, 2, 2), y, idx);
  s.run();
  EXPECT_TRUE(std::isnan(y.download()[0]));
  EXPECT_EQ(download_i32(idx)[0], 1);
}

TEST(PoolKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor x = Tensor::empty(dev, {1, 2, 8, 8});
  Tensor y = Tensor::empty(dev, {1, 2, 4, 4}), idx = Tensor::empty(dev, {1, 2, 4, 4}, DType::i32);
  const Pool2d p = kernels::pool_valid(2, 2, 2, 2);
  EXPECT_NO_THROW(kernels::max_pool2d(s, x, p, y, idx));
  Tensor wrong = Tensor::empty(dev, {1, 2, 3, 4});
  EXPECT_THROW(kernels::avg_pool2d(s, x, p, false, wrong), InvalidArgument);
  EXPECT_THROW(kernels::max_pool2d(s, x, p, y, y), InvalidArgument);  // f32 indices
  kernels::Conv2dParams same;
  same.pad = {1, 1, 1, 1};
  const kernels::Planes for_8x8 = kernels::Planes::make(
      s, x.shape(), kernels::Conv2dPlan(dev, x.shape(), {4, 2, 3, 3}, same).input_layout());
  try {  // a padded tensor of another shape
    kernels::max_pool2d_into_padded(s, x, p, for_8x8);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("[1, 2, 4, 4]"), std::string::npos) << e.what();
  }
  EXPECT_THROW(kernels::max_pool2d(s, x, Pool2d{2, 2, 2, 2, 2, 0, 0, 0}, y, idx), InvalidArgument);
  EXPECT_THROW(kernels::avg_pool2d(s, x, Pool2d{0, 2, 2, 2, 0, 0, 0, 0}, false, y),
               InvalidArgument);
  EXPECT_THROW(kernels::avg_pool2d(s, x, kernels::pool_valid(9, 9, 1, 1), false, y),
               InvalidArgument);
  EXPECT_THROW(kernels::global_avg_pool(s, x, y), InvalidArgument);
  Tensor flat = Tensor::empty(dev, {64});
  EXPECT_THROW(kernels::avg_pool2d(s, flat, p, false, y), InvalidArgument);
  try {
    Tensor empty = Tensor::empty(dev, {0, 2, 8, 8});
    kernels::avg_pool2d(s, empty, p, false, y);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos) << e.what();
  }
  s.run();
}

}  // namespace
}  // namespace vkjr2
